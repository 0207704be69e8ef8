"""Training library and train/predictor.py: outputs, resume, checkpoints, metrics, overfitting."""

from __future__ import annotations

import importlib.util
import json
import logging
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from scipy.spatial.transform import Rotation

from gaitnet.config import config_keys, load_config
from gaitnet.errors import GaitnetError, InputError
from gaitnet.motion.amass import DatasetSplit
from gaitnet.motion.prepared import prepare_walking_subset
from gaitnet.training.checkpoint import (
    CHECKPOINT_KEYS,
    CheckpointError,
    check_weights_only_safe,
    load_checkpoint,
    save_checkpoint,
)
from gaitnet.training.distributed import dist_info_from_env
from gaitnet.training.logs import RankZeroFilter
from gaitnet.training.metrics import MetricsLogger, NonFiniteMetricError, read_metrics
from gaitnet.training.predictor import PredictorTrainingConfig

ROOT = Path(__file__).parents[1]
# Upright SMPL body facing world +x (z up): R_root columns [0,1,0], [0,0,1], [1,0,0].
_UPRIGHT = Rotation.from_matrix(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))


def _load_script():
    spec = importlib.util.spec_from_file_location(
        "train_predictor", ROOT / "train" / "predictor.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


script = _load_script()


def _write_clip(path: Path, seed: int, fps: float = 60.0, seconds: float = 4.0) -> None:
    """A gait-like AMASS ``*_poses.npz``: sinusoidal hips/knees/ankles, yaw sway, forward walk."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fps)) / fps
    f = rng.uniform(0.8, 1.1)  # strides per second
    ph = 2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)
    poses = np.zeros((t.size, 52, 3))
    yaw = Rotation.from_rotvec(np.stack([0 * t, 0 * t, 0.08 * np.sin(ph)], axis=1))
    poses[:, 0] = (yaw * _UPRIGHT).as_rotvec()
    for side, sign in ((0, 1.0), (1, -1.0)):
        p = ph + side * np.pi
        poses[:, 1 + side, 0] = -0.35 * np.sin(p)  # hip flexion is a negative x rotation
        poses[:, 4 + side, 0] = 0.5 * (1 + np.sin(p + 1.2))  # knee flexion positive x
        poses[:, 7 + side, 0] = 0.15 * np.sin(p - 0.5)
        poses[:, 1 + side, 2] = sign * 0.05 * np.cos(p)
    trans = np.stack([1.2 * t, 0.02 * np.sin(ph), 0.9 + 0.02 * np.cos(2 * ph)], axis=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(
        path,
        poses=poses.reshape(t.size, 156),
        trans=trans,
        betas=np.zeros(16),
        dmpls=np.zeros((t.size, 8)),
        gender=np.array("neutral"),
        mocap_framerate=np.array(fps),
    )


@pytest.fixture(scope="module")
def prepared(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("amass")
    for i in range(3):
        _write_clip(root / "TinyTrain" / f"s{i}" / f"c{i}_walk_poses.npz", seed=i)
    _write_clip(root / "TinyVal" / "v" / "v_walk_poses.npz", seed=10)
    _write_clip(root / "TinyTest" / "t" / "t_walk_poses.npz", seed=11, fps=100.0)
    out = root.parent / "tiny_walking.npz"
    # The prepared file stores every clip as training; the config's data.split decides.
    prepare_walking_subset(root, out, split=DatasetSplit(val=(), test=()))
    return out


def _config(tmp: Path, prepared: Path, name: str = "tiny", **extra) -> Path:
    cfg = {
        "name": name,
        "output_dir": str(tmp / "runs"),
        "data": {
            "prepared": str(prepared),
            "split": {"val": ["TinyVal"], "test": ["TinyTest"]},
            "train_stride": 3,
            "eval_stride": 5,
        },
        "model": {"hidden": 16, "n_blocks": 1, "dropout": 0.2},
        "train": {"epochs": 2, "batch_size": 8, "num_threads": 1, "device": "cpu", **extra},
        "eval": {"stride": 4},
    }
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _run(*argv: str) -> int:
    return script.main(script.get_args_parser().parse_args(list(argv)))


@pytest.fixture(scope="module")
def two_epochs(tmp_path_factory, prepared) -> Path:
    tmp = tmp_path_factory.mktemp("run2")
    assert _run("--config", str(_config(tmp, prepared))) == 0
    return tmp / "runs" / "tiny"


def test_two_epoch_run_writes_everything(two_epochs: Path) -> None:
    for name in ("metrics.csv", "last.pt", "best.pt", "config.yaml", "eval.json", "train.log"):
        assert (two_epochs / name).is_file(), name
    assert list((two_epochs / "tb").iterdir())
    rows = read_metrics(two_epochs / "metrics.csv")
    assert [r["epoch"] for r in rows] == ["0", "1"]
    assert {"train/loss", "val/mpjpe_m", "lr"} <= set(rows[0])
    cfg = load_config(PredictorTrainingConfig, two_epochs / "config.yaml")
    assert cfg.model.hidden == 16 and cfg.data.split.test == ("TinyTest",)
    for ckpt in ("last.pt", "best.pt"):
        state = torch.load(two_epochs / ckpt, weights_only=True)
        assert set(CHECKPOINT_KEYS) <= set(state)
    assert torch.load(two_epochs / "last.pt", weights_only=True)["epoch"] == 1
    result = json.loads((two_epochs / "eval.json").read_text())
    assert result["split"] == "test"
    assert set(result["methods"]) == {"gcn", "zero_velocity", "constant_velocity"}
    assert all(len(m["mpjpe_m"]) == 10 for m in result["methods"].values())


def test_resume_continues_with_identical_state(tmp_path: Path, prepared, two_epochs) -> None:
    config = _config(tmp_path, prepared)
    assert _run("--config", str(config), "train.epochs=1") == 0
    run = tmp_path / "runs" / "tiny"
    first = torch.load(run / "last.pt", weights_only=True)
    assert first["epoch"] == 0
    with pytest.raises(GaitnetError, match="--resume"):
        _run("--config", str(config))  # never silently overwrite finished work
    # Architecture keys come from the checkpoint even if the config says otherwise.
    assert _run("--config", str(config), "--resume", "train.epochs=2", "model.hidden=32") == 0
    resumed = torch.load(run / "last.pt", weights_only=True)
    straight = torch.load(two_epochs / "last.pt", weights_only=True)
    assert resumed["epoch"] == 1
    for key, value in straight["model"].items():
        torch.testing.assert_close(resumed["model"][key], value, rtol=0, atol=0)
    assert resumed["scheduler"] == straight["scheduler"]
    opt_a, opt_b = resumed["optimizer"], straight["optimizer"]
    assert opt_a["param_groups"] == opt_b["param_groups"]
    for pid, st in opt_b["state"].items():
        for k, v in st.items():
            torch.testing.assert_close(opt_a["state"][pid][k], v, rtol=0, atol=0)
    assert [r["epoch"] for r in read_metrics(run / "metrics.csv")] == ["0", "1"]


def test_loss_decreases_when_overfitting_a_tiny_set(prepared) -> None:
    cfg = load_config(
        PredictorTrainingConfig,
        None,
        [f"data.prepared={prepared}", "name=o", "model.hidden=32", "model.n_blocks=1",
         "model.dropout=0.0", "optim.lr=0.003", "data.split.val=[TinyVal]",
         "data.split.test=[TinyTest]"],
    )  # fmt: skip
    from torch.utils.data import DataLoader

    from gaitnet.motion.gcn import DCTGCN
    from gaitnet.training.predictor import build_windows

    torch.manual_seed(0)
    ds = build_windows(cfg, "train", 10)
    loader = DataLoader(ds, batch_size=16, shuffle=False, drop_last=True)
    model = DCTGCN(cfg.model)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.optim.lr)
    losses = [
        script.train_one_epoch(model, opt, loader, cfg, e, "cpu", False)["train/loss"]
        for e in range(25)
    ]
    assert losses[-1] < 0.5 * losses[0], losses


def test_eval_only_from_checkpoint(tmp_path: Path, prepared, two_epochs: Path) -> None:
    out = tmp_path / "e.json"
    config = _config(tmp_path, prepared)
    assert _run("--config", str(config), "--eval-only", "--checkpoint",
                str(two_epochs / "best.pt"), "--out", str(out), "eval.split=val") == 0  # fmt: skip
    result = json.loads(out.read_text())
    assert result["split"] == "val" and len(result["methods"]["gcn"]["mpjpe_m"]) == 10
    with pytest.raises(CheckpointError, match="does not exist"):
        _run("--config", str(config), "--eval-only", "--checkpoint", str(tmp_path / "no.pt"))


def test_cli_reports_config_errors(tmp_path: Path, prepared) -> None:
    config = _config(tmp_path, prepared)
    done = subprocess.run(
        [sys.executable, str(ROOT / "train" / "predictor.py"), "--config", str(config),
         "train.epoch=3"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 1
    assert done.stderr.startswith("error: ") and "train.epoch" in done.stderr


def test_checkpoint_helpers(tmp_path: Path) -> None:
    state = {k: 0 for k in ("model", "optimizer", "scheduler", "epoch", "best_metric")}
    state.update(best_epoch=0, config={"a": [1, 2.0, None]}, git_hash="x", t=torch.ones(2))
    save_checkpoint(state, tmp_path / "c.pt")
    assert load_checkpoint(tmp_path / "c.pt")["config"] == {"a": [1, 2.0, None]}
    with pytest.raises(TypeError, match=r"checkpoint\['bad'\]"):
        check_weights_only_safe({"bad": Path("x")})
    with pytest.raises(TypeError):
        save_checkpoint({**state, "bad": object()}, tmp_path / "d.pt")
    assert not (tmp_path / "d.pt").exists()
    torch.save({"model": 1}, tmp_path / "e.pt")
    with pytest.raises(CheckpointError, match="lacks key"):
        load_checkpoint(tmp_path / "e.pt")


def test_metrics_csv_is_append_safe_on_resume(tmp_path: Path) -> None:
    m = MetricsLogger(tmp_path, ["train/loss"], tensorboard=False)
    for e in range(3):
        m.log(e, {"train/loss": 1.0 / (e + 1)})
    m.close()
    # Interrupted after epoch 2's row but before its checkpoint: resume at epoch 2.
    m = MetricsLogger(tmp_path, ["train/loss"], start_epoch=2, tensorboard=False)
    assert [r["epoch"] for r in read_metrics(tmp_path / "metrics.csv")] == ["0", "1"]
    m.log(2, {"train/loss": 0.3})
    assert [r["epoch"] for r in read_metrics(tmp_path / "metrics.csv")] == ["0", "1", "2"]
    with pytest.raises(KeyError):
        m.log(3, {"nope": 1.0})


def test_torchrun_environment_and_rank_filter(monkeypatch) -> None:
    for k in ("RANK", "WORLD_SIZE", "LOCAL_RANK"):
        monkeypatch.delenv(k, raising=False)
    info = dist_info_from_env()
    assert (info.rank, info.world_size, info.distributed, info.is_main) == (0, 1, False, True)
    monkeypatch.setenv("RANK", "1")
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("LOCAL_RANK", "1")
    info = dist_info_from_env()
    assert (info.rank, info.world_size, info.local_rank, info.distributed) == (1, 2, 1, True)
    monkeypatch.setenv("RANK", "2")
    with pytest.raises(InputError, match="inconsistent"):
        dist_info_from_env()
    rec = logging.LogRecord("x", logging.INFO, "", 0, "m", (), None)
    warn = logging.LogRecord("x", logging.WARNING, "", 0, "m", (), None)
    assert RankZeroFilter(0).filter(rec) and not RankZeroFilter(1).filter(rec)
    assert RankZeroFilter(1).filter(warn)


def test_every_predictor_config_key_is_documented() -> None:
    text = (ROOT / "docs" / "predictor.md").read_text()
    missing = [k for k in config_keys(PredictorTrainingConfig) if f"`{k}`" not in text]
    assert not missing, f"undocumented keys in docs/predictor.md: {missing}"
    for cfg in sorted((ROOT / "configs" / "predictor").glob("*.yaml")):
        assert cfg.read_text().startswith("#"), f"{cfg.name} needs a header comment"
        load_config(PredictorTrainingConfig, cfg)


def _draws(loader_gen: torch.Generator) -> list:
    """One number from every generator a training run uses."""
    import random

    out = [random.random(), random.gauss(0, 1), float(np.random.rand()), float(np.random.randn()),
           float(torch.rand(1)), float(torch.rand(1, generator=loader_gen))]  # fmt: skip
    if torch.cuda.is_available():
        for device in range(torch.cuda.device_count()):
            out.append(float(torch.rand(1, device=f"cuda:{device}")))
    return out


def test_every_generator_state_is_saved_and_restored(tmp_path: Path, caplog) -> None:
    """rng_state -> checkpoint file (weights_only) -> restore_rng_state gives the same draws
    from python, numpy, torch CPU, every CUDA device (where there is one) and the loader."""
    from gaitnet.training.seeding import RNG_KEYS, restore_rng_state, rng_state, seed_everything

    seed_everything(5)
    gen = torch.Generator().manual_seed(9)
    _draws(gen)  # move every stream off its seed (and leave a cached gaussian in python/numpy)
    state = rng_state(gen)
    assert set(state) == set(RNG_KEYS)
    assert len(state["cuda"]) == (torch.cuda.device_count() if torch.cuda.is_available() else 0)
    ckpt = {k: 0 for k in CHECKPOINT_KEYS} | {"config": {}, "rng": [state]}
    save_checkpoint(ckpt, tmp_path / "rng.pt")
    expected = _draws(gen)
    seed_everything(123)  # scramble every stream
    gen.manual_seed(321)
    scrambled = _draws(gen)
    restore_rng_state(load_checkpoint(tmp_path / "rng.pt")["rng"][0], gen)
    assert _draws(gen) == expected
    # each stream on its own: every one of them differed after scrambling
    assert all(a != b for a, b in zip(expected, scrambled, strict=True))
    with pytest.raises(ValueError, match="rng state"):
        restore_rng_state({**state, "numpy": {"keys": torch.zeros(3)}}, gen)
    # A checkpoint from a machine with one more GPU: the devices both have are restored and a
    # warning names the difference (a CPU machine restores none).
    n_here = torch.cuda.device_count() if torch.cuda.is_available() else 0
    extra = {**state, "cuda": [*state["cuda"], torch.get_rng_state()]}
    with caplog.at_level(logging.WARNING, logger="gaitnet.training.seeding"):
        restore_rng_state(extra, gen)
    assert f"{n_here + 1} device(s), this machine {n_here}" in caplog.text
    assert _draws(gen) == expected
    with pytest.raises(ValueError, match="keys"):
        restore_rng_state({"torch": state["torch"]}, gen)


_KILLED_SAVE = """
import os, signal, sys, torch
from gaitnet.io.atomic import atomic_save

def save(tmp):
    torch.save({"w": torch.zeros(250_000)}, tmp)  # a checkpoint-sized temp file, then a kill
    os.kill(os.getpid(), signal.SIGKILL)

atomic_save(sys.argv[1], save)
"""


def test_checkpoint_temp_of_a_killed_save_is_removed_by_the_next_save(tmp_path: Path) -> None:
    target = tmp_path / "last.pt"
    done = subprocess.run([sys.executable, "-c", _KILLED_SAVE, str(target)], capture_output=True)
    assert done.returncode == -9  # SIGKILL mid-save
    leftovers = [p for p in tmp_path.iterdir() if p.name.startswith(".last.pt.tmp-")]
    assert len(leftovers) == 1 and leftovers[0].stat().st_size > 900_000
    assert not target.exists()  # never a half-written checkpoint under the real name
    state = {k: 0 for k in CHECKPOINT_KEYS} | {"config": {}}
    save_checkpoint(state, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["last.pt"]
    assert load_checkpoint(target)["epoch"] == 0


def test_checkpoint_errors_are_one_line(tmp_path: Path) -> None:
    import os

    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    torch.save({k: 0 for k in CHECKPOINT_KEYS} | {"config": {}, "x": Evil()}, tmp_path / "e.pt")
    with pytest.raises(CheckpointError) as info:
        load_checkpoint(tmp_path / "e.pt")
    message = str(info.value)
    assert "\n" not in message and "system" in message and "refused" in message
    assert "weights_only=False" not in message and "set to `False`" not in message
    good = tmp_path / "g.pt"
    save_checkpoint({k: 0 for k in CHECKPOINT_KEYS} | {"config": {}}, good)
    (tmp_path / "t.pt").write_bytes(good.read_bytes()[:100])
    (tmp_path / "z.pt").write_bytes(b"")
    for name in ("t.pt", "z.pt"):
        with pytest.raises(CheckpointError, match="cannot be read") as info:
            load_checkpoint(tmp_path / name)
        assert "\n" not in str(info.value)
    with pytest.raises(CheckpointError, match="is a folder"):
        load_checkpoint(tmp_path)
    with pytest.raises(ValueError, match="non-finite"):
        save_checkpoint({k: 0 for k in CHECKPOINT_KEYS} | {"config": {}, "val": math.nan},
                        tmp_path / "nan.pt")  # fmt: skip
    assert not (tmp_path / "nan.pt").exists()


def test_metrics_without_tensorboard_and_never_nan(tmp_path: Path, monkeypatch, caplog) -> None:
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)  # as if not installed
    with caplog.at_level(logging.WARNING, logger="gaitnet.training.metrics"):
        m = MetricsLogger(tmp_path, ["train/loss"], tensorboard=True)
    assert [r.getMessage() for r in caplog.records if "tensorboard" in r.getMessage()] != []
    assert len(caplog.records) == 1
    m.log(0, {"train/loss": 0.5})
    with pytest.raises(NonFiniteMetricError, match="train/loss is nan"):
        m.log(1, {"train/loss": math.nan})
    m.close()
    assert [r["epoch"] for r in read_metrics(tmp_path / "metrics.csv")] == ["0"]
    assert not (tmp_path / "tb").exists()


def test_per_clip_skeletons_and_augmented_clips(prepared) -> None:
    from dataclasses import replace

    from gaitnet.motion.prepared import load_prepared
    from gaitnet.motion.skeleton import builtin_skeleton
    from gaitnet.training.predictor import AugmentConfig, LossConfig, augmented, clip_skeletons

    data = load_prepared(prepared)
    own = builtin_skeleton(1.5).rest_joints
    rest = np.zeros((data.n_clips, 9, 3), np.float32)
    rest[0] = own
    has = np.arange(data.n_clips) == 0
    data = replace(data, clip_rest_joints=rest, clip_has_rest_joints=has)
    common = builtin_skeleton(1.75).rest_joints
    skel = clip_skeletons(data, LossConfig())
    np.testing.assert_allclose(skel[0], own, atol=1e-6)  # the clip's own skeleton
    np.testing.assert_allclose(skel[1:], np.broadcast_to(common, skel[1:].shape))
    flat = clip_skeletons(data, LossConfig(per_clip_skeleton=False, skeleton_height_m=1.6))
    np.testing.assert_allclose(flat, np.broadcast_to(builtin_skeleton(1.6).rest_joints, flat.shape))
    n_train = int(np.sum(data.clip_split == "train"))
    more = augmented(data, AugmentConfig(mirror=True, time_scales=(0.5,)))
    assert int(np.sum(more.clip_split == "train")) == 4 * n_train  # +mirror, ×0.5 of both
    assert int(np.sum(more.clip_split != "train")) == int(np.sum(data.clip_split != "train"))
    assert augmented(data, AugmentConfig()) is data


def test_input_noise_reaches_the_input_only(prepared) -> None:
    from torch.utils.data import DataLoader

    from gaitnet.motion.gcn import DCTGCN
    from gaitnet.training.predictor import build_windows

    cfg = load_config(
        PredictorTrainingConfig,
        None,
        [f"data.prepared={prepared}", "name=n", "model.hidden=8", "model.n_blocks=1",
         "augment.input_noise_rad=0.1", "data.split.val=[TinyVal]", "data.split.test=[TinyTest]"],
    )  # fmt: skip
    ds = build_windows(cfg, "train", 10)
    loader = DataLoader(ds, batch_size=8, shuffle=False, drop_last=True)
    seen: list[torch.Tensor] = []

    class Recorder(DCTGCN):
        def forward(self, past: torch.Tensor) -> torch.Tensor:
            seen.append(past.detach().clone())
            out = torch.cat([past, past[:, -1:].expand(-1, 10, -1)], dim=1)
            return out + 0.0 * self.gc1.weight.sum()  # zero-residual: the input comes out

    model = Recorder(cfg.model)
    opt = torch.optim.SGD(model.parameters(), lr=0.0)
    stats = script.train_one_epoch(model, opt, loader, cfg, 0, "cpu", False)
    clean = torch.cat([p[:, :10] for p, _ in loader])
    noise = torch.cat(seen) - clean
    assert 0.09 < float(noise.std()) < 0.11 and abs(float(noise.mean())) < 0.01
    # the loss compares with the clean targets: the noisy past frames count as errors
    assert stats["train/mae_rad"] > 0.05


def test_augmented_last_pose_run(tmp_path: Path, prepared) -> None:
    config = _config(tmp_path, prepared, name="aug")
    assert _run("--config", str(config), "train.epochs=1", "augment.mirror=true",
                "augment.time_scales=[0.8]", "model.residual=last_pose") == 0  # fmt: skip
    log = (tmp_path / "runs" / "aug" / "train.log").read_text()
    # 3 clips of 120 frames: 34 windows each (stride 3); mirrored: the same; ×0.8 (150
    # frames): 44 each, for the originals and the mirror images → 3·34 + 3·34 + 6·44
    assert "windows: 468 train" in log
    state = torch.load(tmp_path / "runs" / "aug" / "best.pt", weights_only=True)
    assert state["config"]["model"]["residual"] == "last_pose"
    assert state["model"]["gc1.weight"].shape[0] == 21  # dct_n + the last pose


def test_init_fine_tunes_from_checkpoint_weights(tmp_path: Path, prepared, two_epochs) -> None:
    """--init: a fresh run (epoch 0, new optimizer) from the checkpoint's weights and
    architecture; here with the window-normalised loss and a negligible learning rate, so the
    weights stay those of the checkpoint."""
    config = _config(tmp_path, prepared, name="ft")
    init = two_epochs / "best.pt"
    assert _run("--config", str(config), "--init", str(init), "train.epochs=1",
                "model.hidden=32", "optim.lr=1e-12",
                "loss.window_normalisation=baseline") == 0  # fmt: skip
    run = tmp_path / "runs" / "ft"
    state = torch.load(run / "last.pt", weights_only=True)
    start = torch.load(init, weights_only=True)
    assert state["epoch"] == 0 and state["config"]["model"]["hidden"] == 16
    assert state["config"]["loss"]["window_normalisation"] == "baseline"
    for key in ("gc1.weight", "gc7.weight", "gcbs.0.gc1.att"):
        torch.testing.assert_close(state["model"][key], start["model"][key], rtol=0, atol=1e-9)
    assert "initialised from the weights of" in (run / "train.log").read_text()
    with pytest.raises(InputError, match="--init"):
        _run("--config", str(config), "--init", str(init), "--resume")
