"""train/segmenter.py and gaitnet.training.segmenter: outputs, kill-and-resume, DDP, config keys.

Every run here trains a width-1/16 net on 64×48 simulated frames for a few batches.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import yaml
from scriptload import load_script

from gaitnet.config import config_keys, load_config
from gaitnet.errors import ConfigError, GaitnetError, InputError
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.focal_loss import FocalLoss
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import simulate_dataset
from gaitnet.training.checkpoint import load_checkpoint
from gaitnet.training.metrics import read_metrics
from gaitnet.training.runs import SkipSampler
from gaitnet.training.segmenter import (
    SegmenterTrainingConfig,
    build_loss,
    build_model,
    build_optimizer,
    build_scheduler,
    scores_of,
)
from gaitnet.training.segmenter_data import build_dataset, build_training_set, resolve_set

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "train" / "segmenter.py"


script = load_script(SCRIPT)
calibrate = load_script(ROOT / "train" / "calibrate_segmenter.py")


@pytest.fixture(scope="module")
def frames(tmp_path_factory) -> Path:
    """8 simulated 64×48 frames; train.txt 6 of them, val.txt 2, test.txt 2 (overlapping)."""
    root = tmp_path_factory.mktemp("seg") / "frames"
    cfg = load_config(
        SimConfig,
        ROOT / "configs" / "sim" / "tiny.yaml",
        ["camera.width=64", "camera.height=48", "camera.fx=38.6", "camera.fy=38.6",
         "camera.cx=31.5", "camera.cy=23.5", "output.preview_frames=0"],
    )  # fmt: skip
    simulate_dataset(cfg, 8, 5, root)
    ids = [f"{i:06d}" for i in range(8)]
    (root / "train.txt").write_text("\n".join(ids[:6]) + "\n")
    (root / "val.txt").write_text("\n".join(ids[6:]) + "\n")
    (root / "test.txt").write_text("\n".join(ids[5:7]) + "\n")
    return root


def _config(tmp: Path, frames: Path, name: str = "tiny", **sections) -> Path:
    cfg = {
        "name": name,
        "output_dir": str(tmp / "runs"),
        "data": {"train": str(frames / "train.txt"), "val": str(frames / "val.txt"),
                 "augment": None},
        "model": {"arch": "fusion", "width": 0.0625, "input_scale": 1.0},
        "optim": {"name": "adam", "lr": 1e-3, "weight_decay": 0.0},
        "train": {"epochs": 2, "batch_size": 2, "eval_batch_size": 2, "num_threads": 1,
                  "device": "cpu", "tensorboard": False},
        "eval": {"sets": [str(frames / "test.txt"), str(frames)]},
    }  # fmt: skip
    for key, value in sections.items():
        cfg[key] = {**cfg.get(key, {}), **value} if isinstance(value, dict) else value
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _run(*argv: str) -> int:
    return script.main(script.get_args_parser().parse_args(list(argv)))


@pytest.fixture(scope="module")
def straight(tmp_path_factory, frames) -> Path:
    """An uninterrupted 2-epoch run, 3 batches per epoch, checkpoints every batch."""
    tmp = tmp_path_factory.mktemp("straight")
    assert _run("--config", str(_config(tmp, frames, train={"checkpoint_every": 1}))) == 0
    return tmp / "runs" / "tiny"


def test_run_writes_metrics_checkpoints_and_eval(straight: Path) -> None:
    for name in ("metrics.csv", "last.pt", "best.pt", "config.yaml", "eval.json", "train.log"):
        assert (straight / name).is_file(), name
    rows = read_metrics(straight / "metrics.csv")
    assert [r["epoch"] for r in rows] == ["0", "1"]
    assert all(0 <= float(r["val/miou"]) <= 1 for r in rows)
    report = json.loads((straight / "eval.json").read_text())
    assert sorted(report["sets"]) == ["frames", "test"]  # names: split-file stem, folder name
    whole = report["sets"]["frames"]
    assert whole["frames"] == 8 and report["sets"]["test"]["frames"] == 2
    conf = np.array(whole["confusion"])
    assert conf.shape == (3, 3) and conf.sum() == 8 * 64 * 48  # every pixel labelled
    assert whole["pixel_acc"] == pytest.approx(np.trace(conf) / conf.sum())
    last = load_checkpoint(straight / "last.pt")
    assert last["epoch"] == 1 and last["step_in_epoch"] == 0
    assert last["scheduler"]["last_epoch"] == 6  # stepped once per batch: 2 epochs × 3


_KILL_AFTER_SAVES = """
import os, signal, sys
sys.path.insert(0, {train!r})
import importlib.util
spec = importlib.util.spec_from_file_location("seg", {script!r})
seg = importlib.util.module_from_spec(spec); spec.loader.exec_module(seg)
real, count = seg.save_checkpoint, [0]
def save(state, path):
    real(state, path)
    count[0] += 1
    if count[0] == {n}:
        os.kill(os.getpid(), signal.SIGKILL)
seg.save_checkpoint = save
sys.exit(seg.cli(["--config", {config!r}]))
"""


@pytest.mark.parametrize("saves", [2, 5])  # killed mid-epoch 0; mid-epoch 1
def test_killed_run_resumes_to_the_same_weights(tmp_path, frames, straight, saves) -> None:
    config = _config(tmp_path, frames, train={"checkpoint_every": 1})
    code = _KILL_AFTER_SAVES.format(train=str(ROOT / "train"), script=str(SCRIPT), n=saves,
                                    config=str(config))  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == -9, done.stderr[-2000:]
    run = tmp_path / "runs" / "tiny"
    killed = load_checkpoint(run / "last.pt")
    assert killed["step_in_epoch"] > 0  # it died in the middle of an epoch
    with pytest.raises(GaitnetError, match="--resume"):
        _run("--config", str(config))  # never silently overwrite started work
    assert _run("--config", str(config), "--resume") == 0
    resumed, ref = load_checkpoint(run / "last.pt"), load_checkpoint(straight / "last.pt")
    for key, value in ref["model"].items():
        torch.testing.assert_close(resumed["model"][key], value, rtol=0, atol=0)
    for pid, st in ref["optimizer"]["state"].items():
        for k, v in st.items():
            torch.testing.assert_close(resumed["optimizer"]["state"][pid][k], v, rtol=0, atol=0)
    assert resumed["scheduler"] == ref["scheduler"]
    a, b = read_metrics(run / "metrics.csv"), read_metrics(straight / "metrics.csv")
    drop = ("time/epoch_s",)
    assert [{k: v for k, v in r.items() if k not in drop} for r in a] == [
        {k: v for k, v in r.items() if k not in drop} for r in b
    ]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_torchrun_two_processes(tmp_path, frames) -> None:
    config = _config(tmp_path, frames, name="ddp", train={"epochs": 1})
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2",
           "--master_port", str(_free_port()), str(SCRIPT), "--config", str(config),
           "--no-final-eval"]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    ckpt = load_checkpoint(tmp_path / "runs" / "ddp" / "last.pt")
    assert len(ckpt["rng"]) == 2  # each rank's generator states
    # 6 training frames, global batch 2 = 1 per rank: 3 steps, every frame once.
    assert ckpt["scheduler"]["last_epoch"] == 3
    assert [r["epoch"] for r in read_metrics(tmp_path / "runs" / "ddp" / "metrics.csv")] == ["0"]


@pytest.mark.parametrize(
    ("override", "named"),
    [
        ("optim.lrr=0.1", "optim.lrr"),
        ("model.arch=depth", "model.arch"),
        ("loss.alpha=[1,1]", "loss.alpha"),
        ("train.device=cuda:7", "train.device"),
        ("data.train=/nonexistent/train.txt", "/nonexistent/train.txt"),
    ],
)
def test_bad_config_is_one_line_naming_the_key(tmp_path, frames, capsys, override, named):
    config = _config(tmp_path, frames)
    assert script.cli(["--config", str(config), override]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and named in lines[0], lines
    assert not (tmp_path / "runs").exists()  # nothing written


def test_bad_key_from_the_command_line(tmp_path, frames) -> None:
    config = _config(tmp_path, frames)
    argv = [sys.executable, str(SCRIPT), "--config", str(config), "train.epoch=3"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "'train.epoch'" in lines[0], lines


# --------------------------------------------------------------- every key acts


def _cfg(*overrides: str) -> SegmenterTrainingConfig:
    return load_config(SegmenterTrainingConfig, None, ["name=x", *overrides])


def test_model_keys_build_that_model() -> None:
    net = build_model(_cfg("model.arch=hha", "model.width=0.0625", "model.input_scale=0.5",
                           "model.num_classes=4").model)  # fmt: skip
    assert (net.arch, net.width, net.input_scale, net.num_classes) == ("hha", 0.0625, 0.5, 4)
    assert net.padding == "published" and net.hha.features[0].padding == (100, 100)
    same = build_model(_cfg("model.width=0.0625", "model.padding=same").model)
    assert same.padding == "same" and same.rgb.features[0].padding == (1, 1)
    with pytest.raises(ConfigError, match="model.padding"):
        _cfg("model.padding=valid")
    with pytest.raises(ConfigError, match="model.vgg16_weights"):
        _cfg("model.width=0.5", "model.vgg16_weights=/nonexistent.pth")
    with pytest.raises(InputError, match="nonexistent"):  # width 1: the file is read
        build_model(_cfg("model.vgg16_weights=/nonexistent.pth").model)


def test_output_stride_key_builds_finer_nets() -> None:
    net = build_model(_cfg("model.width=0.0625", "model.output_stride=4").model)
    assert net.output_stride == 4 and net.rgb.score_pool2.out_channels == 3
    assert build_model(_cfg("model.width=0.0625").model).output_stride == 8
    with pytest.raises(ConfigError, match="model.output_stride"):
        _cfg("model.output_stride=16")


def test_logit_bias_key_reaches_the_net() -> None:
    net = build_model(_cfg("model.width=0.0625", "model.logit_bias=[0, -0.5, 0.25]").model)
    assert net.logit_bias == (0.0, -0.5, 0.25)
    assert build_model(_cfg("model.width=0.0625").model).logit_bias == (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match="model.logit_bias must be null or a list of 3"):
        _cfg("model.logit_bias=[0, 1]")


def test_calibration_writes_the_bias_that_maximises_val_miou(tmp_path, straight: Path) -> None:
    """train/calibrate_segmenter.py on a checkpoint whose bias is far off (and whose config
    names a start checkpoint that no longer exists: only the architecture is rebuilt): the
    written checkpoint has the same weights, the old bias plus the fitted one, a higher
    validation mIoU, and that mIoU is what --eval-only scores independently."""
    source = load_checkpoint(straight / "best.pt")
    off = dict(source, config={**source["config"], "model": {
        **source["config"]["model"], "logit_bias": [0.0, 3.0, 3.0],
        "init_checkpoint": str(tmp_path / "gone.pt")}})  # fmt: skip
    skewed = tmp_path / "skewed.pt"
    torch.save(off, skewed)
    out = tmp_path / "calibrated.pt"
    config = str(straight / "config.yaml")
    argv = ["--config", config, "--checkpoint", str(skewed), "--out", str(out)]
    assert calibrate.main(calibrate.get_args_parser().parse_args(argv)) == 0
    ckpt = load_checkpoint(out)
    info = ckpt["calibration"]
    assert ckpt["config"]["model"]["logit_bias"] == info["logit_bias"]
    np.testing.assert_allclose(info["logit_bias"], np.add([0.0, 3.0, 3.0], info["fitted_bias"]))
    assert min(info["fitted_bias"]) < 0 and info["miou_after"] > info["miou_before"]
    assert info["frames"] == 2
    for key, value in source["model"].items():
        assert torch.equal(ckpt["model"][key], value)
    scores = tmp_path / "scores.json"
    val = str(Path(ckpt["config"]["data"]["val"]))
    assert _run("--config", config, "--eval-only", "--checkpoint", str(out), "--out",
                str(scores), f"eval.sets=[{val}]") == 0  # fmt: skip
    assert json.loads(scores.read_text())["sets"]["val"]["miou"] == pytest.approx(
        info["miou_after"], abs=1e-9
    )
    best = straight / "best.pt"
    with pytest.raises(InputError, match="would overwrite"):
        calibrate.main(calibrate.get_args_parser().parse_args(
            ["--config", config, "--checkpoint", str(best), "--out", str(best)]))  # fmt: skip


def test_calibration_bad_input_is_one_line(tmp_path, straight: Path, capsys) -> None:
    config = str(straight / "config.yaml")
    missing = ["--config", config, "--checkpoint", str(tmp_path / "none.pt")]
    assert calibrate.cli(missing) == 1
    assert calibrate.cli(["--config", config]) == 1  # no --checkpoint
    assert calibrate.cli([*missing[:2], "--checkpoint", str(straight / "best.pt"),
                          "--set", str(tmp_path / "nowhere.txt"),
                          "--out", str(tmp_path / "c.pt")]) == 1  # fmt: skip
    lines = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 3 and "Traceback" not in "\n".join(lines)
    assert "none.pt" in errors[0] and "--checkpoint" in errors[1] and "nowhere.txt" in errors[2]
    assert not (tmp_path / "c.pt").exists()


def test_init_checkpoint_starts_from_a_trained_net(straight: Path, tmp_path) -> None:
    """``model.init_checkpoint`` copies the trained layers (the same net: the same logits), a
    finer ``output_stride`` keeps its new score layers at zero; mismatches are named."""
    best = straight / "best.pt"
    ckpt = load_checkpoint(best)
    model = ckpt["config"]["model"]
    keys = [f"model.{k}={v}" for k, v in model.items() if k in ("arch", "width", "input_scale")]
    trained = build_model(_cfg(*keys).model)
    trained.load_state_dict(ckpt["model"])
    same = build_model(_cfg(*keys, f"model.init_checkpoint={best}").model).eval()
    x = torch.rand(1, 6, 48, 64)
    with torch.no_grad():
        assert torch.equal(same(x), trained.eval()(x))
    finer = build_model(_cfg(*keys, "model.output_stride=2", f"model.init_checkpoint={best}").model)
    state = finer.state_dict()
    for key, value in ckpt["model"].items():
        if key in state:
            assert torch.equal(state[key], value), key
    assert not finer.rgb.score_pool1.weight.any() and not finer.hha.score_pool2.weight.any()
    assert torch.count_nonzero(finer.rgb.score_pool3.weight) > 0  # copied, trained
    with pytest.raises(ConfigError, match=r"model.init_checkpoint .*model.width is 0.0625"):
        build_model(_cfg("model.width=0.125", f"model.init_checkpoint={best}").model)
    with pytest.raises(ConfigError, match="exclude each other"):
        _cfg(f"model.init_checkpoint={best}", "model.vgg16_weights=/x.pth")
    with pytest.raises(GaitnetError, match="does not exist"):
        build_model(_cfg(*keys, f"model.init_checkpoint={tmp_path / 'none.pt'}").model)


def test_loss_keys_give_that_focal_loss() -> None:
    torch.manual_seed(0)
    logits, target = torch.randn(2, 3, 5, 4), torch.randint(0, 3, (2, 5, 4))
    target[0, 0, 0] = 7
    loss = build_loss(_cfg("loss.alpha=[0.2,1.0,0.6]", "loss.gamma=1.5",
                           "loss.ignore_index=7").loss)  # fmt: skip
    ref = FocalLoss(alpha=[0.2, 1.0, 0.6], gamma=1.5, ignore_index=7)
    assert float(loss(logits, target)) == pytest.approx(float(ref(logits, target)))
    ce = build_loss(_cfg("loss.gamma=0", "loss.ignore_index=7").loss)
    expected = torch.nn.functional.cross_entropy(logits, target, ignore_index=7)
    assert float(ce(logits, target)) == pytest.approx(float(expected), rel=1e-6)


def test_optim_keys_and_schedules() -> None:
    p = [torch.nn.Parameter(torch.zeros(2))]
    sgd = build_optimizer(p, _cfg("optim.lr=0.1", "optim.momentum=0.8",
                                  "optim.weight_decay=0.01").optim)  # fmt: skip
    assert isinstance(sgd, torch.optim.SGD)
    g = sgd.param_groups[0]
    assert (g["lr"], g["momentum"], g["weight_decay"]) == (0.1, 0.8, 0.01)
    adam = build_optimizer(p, _cfg("optim.name=adam", "optim.momentum=0.5").optim)
    assert isinstance(adam, torch.optim.Adam) and adam.param_groups[0]["betas"] == (0.5, 0.999)

    def lrs(*overrides: str, epochs: int = 2, steps: int = 5) -> list[float]:
        cfg = _cfg("optim.lr=1.0", *overrides).optim
        opt = build_optimizer([torch.nn.Parameter(torch.zeros(1))], cfg)
        sched = build_scheduler(opt, cfg, epochs, steps)
        out = []
        for _ in range(epochs * steps):
            out.append(opt.param_groups[0]["lr"])
            opt.step()
            sched.step()
        return out

    poly = lrs("optim.schedule=poly", "optim.poly_power=2")
    np.testing.assert_allclose(poly, [(1 - i / 10) ** 2 for i in range(10)], rtol=1e-9)
    step = lrs("optim.schedule=step", "optim.step_epochs=1", "optim.step_gamma=0.5")
    assert step == [1.0] * 5 + [0.5] * 5
    assert lrs("optim.schedule=constant") == [1.0] * 10


def test_data_keys_and_sets(frames: Path) -> None:
    root, ids = resolve_set(frames / "val.txt")
    assert root == frames and ids == ["000006", "000007"]
    assert resolve_set(frames) == (frames, None)
    with pytest.raises(InputError, match="missing.txt"):
        resolve_set(frames / "missing.txt")
    cfg = _cfg(f"data.train={frames / 'train.txt'}")
    assert len(build_dataset(cfg.data.train, cfg, augment=True)) == 6
    assert build_dataset(cfg.data.train, cfg, augment=True).augment == cfg.data.augment
    assert build_dataset(cfg.data.train, cfg, augment=False).augment is None
    no_aug = _cfg("data.augment=null")
    assert build_dataset(cfg.data.train, no_aug, augment=True).augment is None
    assert build_dataset(frames, _cfg("data.cache_hha=false"), False).cache_hha is False


def test_extra_training_sets_join_the_first(frames: Path, monkeypatch) -> None:
    import gaitnet.training.segmenter_data as seg

    one = _cfg(f"data.train={frames / 'train.txt'}")
    assert isinstance(build_training_set(one, seed=5), SegmentationFolder)
    two = _cfg(f"data.train={frames / 'train.txt'}", f"data.train_extra=[{frames / 'val.txt'}]")
    joined = build_training_set(two, seed=5)
    assert len(joined) == 6 + 2
    first, extra = joined.datasets
    assert (first.seed, extra.seed) == (5, 6)  # each set its own augmentation draws
    assert extra.augment == two.data.augment and extra.ids == ["000006", "000007"]
    joined.set_epoch(3)
    assert first.epoch == extra.epoch == 3
    # frames of another size cannot share a batch unless a fixed crop makes them one size
    sizes = iter([(48, 64), (60, 80)])

    def sized(path, cfg, augment, seed=0):
        h, w = next(sizes)
        return SimpleNamespace(intrinsics=SimpleNamespace(height=h, width=w))

    monkeypatch.setattr(seg, "build_dataset", sized)
    uncropped = _cfg("data.augment.crop_height=0", f"data.train_extra=[{frames / 'val.txt'}]")
    with pytest.raises(InputError, match="data.augment.crop_height"):
        build_training_set(uncropped)


def test_train_keys_act(tmp_path, frames) -> None:
    config = _config(tmp_path, frames, name="keys", train={
        "epochs": 1, "max_steps_per_epoch": 2, "num_threads": 1, "tensorboard": True,
        "seed": 3})  # fmt: skip
    assert _run("--config", str(config), "--no-final-eval") == 0
    run = tmp_path / "runs" / "keys"
    ckpt = load_checkpoint(run / "last.pt")
    assert ckpt["scheduler"]["last_epoch"] == 2  # train.max_steps_per_epoch
    assert (run / "tb").is_dir() and not (run / "eval.json").exists()
    assert torch.get_num_threads() == 1
    other = _config(tmp_path, frames, name="keys2", train={
        "epochs": 1, "max_steps_per_epoch": 2, "seed": 4})  # fmt: skip
    assert _run("--config", str(other), "--no-final-eval") == 0
    ckpt2 = load_checkpoint(tmp_path / "runs" / "keys2" / "last.pt")
    assert not (tmp_path / "runs" / "keys2" / "tb").exists()  # train.tensorboard false
    key = next(iter(ckpt["model"]))
    assert not torch.equal(ckpt["model"][key], ckpt2["model"][key])  # train.seed


def test_eval_only_matches_the_final_evaluation(tmp_path, straight: Path) -> None:
    out = tmp_path / "again.json"
    config = straight / "config.yaml"
    assert _run("--config", str(config), "--eval-only", "--checkpoint",
                str(straight / "best.pt"), "--out", str(out), "eval.batch_size=3") == 0  # fmt: skip
    again, first = json.loads(out.read_text()), json.loads((straight / "eval.json").read_text())
    for name, scores in first["sets"].items():
        assert again["sets"][name]["confusion"] == scores["confusion"]


def test_scores_of_a_known_confusion() -> None:
    conf = np.array([[8, 2, 0], [1, 3, 0], [0, 0, 0]])  # leg absent: not in the mean
    s = scores_of(conf)
    assert s["pixel_acc"] == pytest.approx(11 / 14)
    ious = [8 / 11, 3 / 6]
    assert s["miou"] == pytest.approx(np.mean(ious))
    assert s["confusion"] == conf.tolist()


def test_skip_sampler_drops_only_the_next_epochs_head() -> None:
    s = SkipSampler(list(range(6)))
    s.skip_next(4)
    assert list(s) == [4, 5] and list(s) == list(range(6))


def test_every_segmenter_config_key_is_documented() -> None:
    sys.path.insert(0, str(ROOT / "tests"))
    from test_docs import config_rows, documented_rows

    expected = config_rows(SegmenterTrainingConfig)
    documented = documented_rows("## Segmenter training")
    assert sorted(documented) == sorted(expected)
    for key, (tp, default) in expected.items():
        assert documented[key][:2] == (tp, default), key
        assert documented[key][2], key
    assert config_keys(SegmenterTrainingConfig)


def test_loader_keys_reach_the_loaders(tmp_path, frames, monkeypatch) -> None:
    made = []

    class Recording(torch.utils.data.DataLoader):
        def __init__(self, dataset, batch_size=1, **kwargs):
            made.append((len(dataset), batch_size, kwargs.get("num_workers", 0)))
            super().__init__(dataset, batch_size, **{**kwargs, "num_workers": 0})

    monkeypatch.setattr(script, "DataLoader", Recording)
    config = _config(tmp_path, frames, name="loaders", data={"num_workers": 2},
                     train={"epochs": 1, "max_steps_per_epoch": 1, "batch_size": 3,
                            "eval_batch_size": 1},
                     eval={"batch_size": 5, "sets": [str(frames / "test.txt")]})  # fmt: skip
    assert _run("--config", str(config)) == 0
    # train (6 frames, batch 3), val (2 frames, eval_batch_size 1), final eval (batch 5)
    assert made == [(6, 3, 2), (2, 1, 2), (2, 5, 2)]


def test_architecture_comes_from_the_checkpoint(tmp_path) -> None:
    """with_checkpoint_model (gaitnet.training.checkpoint): the model keys of the checkpoint's
    config replace the config's; a checkpoint without usable ones is a one-line error."""
    from gaitnet.config import config_to_dict
    from gaitnet.training.checkpoint import CheckpointError
    from gaitnet.training.segmenter import with_checkpoint_model

    cfg = _cfg("model.width=0.0625")
    theirs = {**config_to_dict(cfg.model), "output_stride": 4, "width": 0.125}
    out = with_checkpoint_model(cfg, {"config": {"model": theirs}}, tmp_path / "a.pt")
    assert (out.model.output_stride, out.model.width, out.name) == (4, 0.125, cfg.name)
    for bad in ({}, {"config": {"model": {"arch": "sonar"}}}):
        with pytest.raises(CheckpointError, match=r"a.pt: no usable segmenter architecture"):
            with_checkpoint_model(cfg, bad, tmp_path / "a.pt")
