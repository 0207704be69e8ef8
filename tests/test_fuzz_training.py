"""Fuzz the training entry script (train/predictor.py): options, configs, data files, checkpoints.

Every broken input must end with exit status 1, exactly one line on stderr, no traceback and
no checkpoint written (an existing one untouched); a valid run still trains. The script's
``cli()`` runs in-process (as ``python train/predictor.py`` does) with pytest's ``capsys``.
"""

from __future__ import annotations

import importlib.util
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from amassfactory import walking_like_clip, write_smplh_poses
from oneline import assert_one_line_exit

from gaitnet.motion.amass import DatasetSplit
from gaitnet.motion.prepared import prepare_walking_subset

ROOT = Path(__file__).parents[1]
# A warning would be a second line on a user's stderr: every one fails these tests.
pytestmark = [
    pytest.mark.filterwarnings("error::RuntimeWarning"),
    pytest.mark.filterwarnings("error::UserWarning"),
]


def _load_script():
    spec = importlib.util.spec_from_file_location(
        "train_predictor_fuzz", ROOT / "train/predictor.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


script = _load_script()


@pytest.fixture(scope="module")
def prepared(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("amass")
    rng = np.random.default_rng(0)
    for name, folder in (
        ("a", "FuzzTrain"),
        ("b", "FuzzTrain"),
        ("v", "FuzzVal"),
        ("t", "FuzzTest"),
    ):
        poses, trans = walking_like_clip(150, 60.0, rng)  # 2.5 s → 75 frames at 30 fps
        write_smplh_poses(root / folder / name / f"{name}_walk_poses.npz", poses, trans, 60.0)
    out = root.parent / "fuzz_walking.npz"
    prepare_walking_subset(root, out, split=DatasetSplit(val=("FuzzVal",), test=("FuzzTest",)))
    return out


def _config(folder: Path, prepared: Path, name: str = "fuzz") -> Path:
    cfg = {
        "name": name,
        "output_dir": str(folder / "runs"),
        "data": {"prepared": str(prepared), "train_stride": 4, "eval_stride": 8},
        "model": {"hidden": 8, "n_blocks": 1, "dropout": 0.1},
        "train": {
            "epochs": 1,
            "batch_size": 8,
            "num_threads": 1,
            "device": "cpu",
            "tensorboard": False,
        },  # fmt: skip
        "eval": {"stride": 8},
    }
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory, prepared) -> tuple[Path, Path]:
    """A valid one-epoch run (the valid input passes) whose last.pt the resume cases use."""
    folder = tmp_path_factory.mktemp("run")
    config = _config(folder, prepared)
    assert script.cli(["--config", str(config), "--no-final-eval"]) == 0
    return config, folder / "runs" / "fuzz"


def _snapshot(folder: Path) -> dict[str, bytes]:
    if not folder.is_dir():
        return {}
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.suffix == ".pt"}


def _assert_one_line_error(capsys, argv: list[str], run_dir: Path, before: dict) -> str:
    line = assert_one_line_exit(capsys, script.cli(argv))
    assert line.startswith("error: ") and "weights_only=False" not in line, (argv, line)
    assert _snapshot(run_dir) == before  # no checkpoint written, none changed
    if not before:
        assert not run_dir.exists() or not any(run_dir.glob("*.pt"))
    return line


# ---------------------------------------------------------------------------- options, configs

BAD_OPTIONS = [
    (["train.epoch=3"], "train.epoch"),  # unknown key
    (["train.batch_size=abc"], "train.batch_size"),  # wrong type
    (["train.batch_size=0"], "train.batch_size"),
    (["train.batch_size=-5"], "train.batch_size"),
    (["train.batch_size=100000"], "exceeds"),  # larger than the data set
    (["optim.lr=.nan"], "optim.lr"),
    (["optim.lr=1e400"], "optim.lr"),  # YAML reads inf
    (["optim.lr=0"], "optim.lr"),
    (["optim.lr_gamma=1.5"], "optim.lr_gamma"),
    (["optim.grad_clip_norm=-1"], "grad_clip_norm"),
    (["train.seed=-1"], "train.seed"),
    (["train.seed=99999999999999999999999"], "train.seed"),
    (["train.device=gpu"], "train.device"),
    (["train.device=cuda:99"], "cuda"),
    (["train.epochs=1000000000000"], "train.epochs"),
    (["train.num_threads=100000"], "train.num_threads"),
    (["model.dropout=1.5"], "dropout"),
    (["model.hidden=0"], "hidden"),
    (["model.hidden=100000000"], "hidden"),
    (["model.dct_n=50"], "dct_n"),
    (["model.n_nodes=20"], "n_nodes"),
    (["name=../escape"], "name"),
    (["loss.skeleton_height_m=0"], "skeleton_height_m"),
    (["loss.w_mpjpe=0", "loss.w_mae=0"], "both be zero"),
    (["data.num_workers=-1"], "num_workers"),
    (["data.train_stride=0"], "train_stride"),
    (["data.dataset_train_stride={FuzzTrain: 0}"], "dataset_train_stride.FuzzTrain"),
    (["data.dataset_train_stride=[1]"], "dataset_train_stride"),
    (["data.dataset_train_stride={NoSuchSet: 1}"], "sub-dataset 'nosuchset'"),
    (["eval.split=train2"], "eval.split"),
    (["data.split.val=[NoSuchSet]"], "no windows"),  # the validation split is empty
    (["no_equals_sign"], "key=value"),
    (["--bogus-option"], "bogus"),
    (["--checkpoint", "x.pt"], "--checkpoint"),
    (["--eval-only"], "--checkpoint or --onnx"),
]


@pytest.mark.parametrize(
    ("extra", "needle"), BAD_OPTIONS, ids=[" ".join(c[0]) for c in BAD_OPTIONS]
)
def test_bad_options_are_one_line(tmp_path, capsys, prepared, extra, needle) -> None:
    config = _config(tmp_path, prepared)
    err = _assert_one_line_error(capsys, ["--config", str(config), *extra], tmp_path / "runs", {})
    assert needle in err, err
    assert not (tmp_path / "runs").exists()  # nothing written for bad input


def _config_file_cases(folder: Path, prepared: Path) -> dict[str, Path]:
    good = _config(folder, prepared).read_text()
    cases = {
        "missing": folder / "none.yaml",
        "folder": folder,
        "not_yaml": folder / "bad.yaml",
        "non_utf8": folder / "latin.yaml",
        "top_level_list": folder / "list.yaml",
        "missing_name": folder / "noname.yaml",
        "nan_lr": folder / "nan.yaml",
        "nested_garbage": folder / "nested.yaml",
    }
    cases["not_yaml"].write_text("name: [unclosed\n")
    cases["non_utf8"].write_bytes(good.encode() + b"# caf\xe9\n")
    cases["top_level_list"].write_text("- 1\n- 2\n")
    cases["missing_name"].write_text("\n".join(ln for ln in good.splitlines() if "name:" not in ln))
    cases["nan_lr"].write_text(good + "optim:\n  lr: .nan\n")
    cases["nested_garbage"].write_text(good.replace("data:", "data:\n  split: 5\n  x:", 1))
    return cases


@pytest.mark.parametrize(
    "case",
    ["missing", "folder", "not_yaml", "non_utf8", "top_level_list", "missing_name", "nan_lr",
     "nested_garbage"],
)  # fmt: skip
def test_broken_config_files_are_one_line(tmp_path, capsys, prepared, case) -> None:
    config = _config_file_cases(tmp_path, prepared)[case]
    err = _assert_one_line_error(capsys, ["--config", str(config)], tmp_path / "runs", {})
    assert str(config) in err


# ---------------------------------------------------------------------------- data files


def _data_cases(folder: Path, prepared: Path) -> dict[str, Path]:
    good = prepared.read_bytes()
    with np.load(prepared) as data:
        arrays = {k: data[k] for k in data.files}
    cases: dict[str, Path] = {}

    def write(name: str, content: bytes) -> None:
        cases[name] = folder / f"{name}.npz"
        cases[name].write_bytes(content)

    def arrays_with(name: str, **changes) -> None:
        cases[name] = folder / f"{name}.npz"
        np.savez(cases[name], **{**arrays, **changes})

    cases["missing"] = folder / "missing.npz"
    cases["folder"] = folder
    write("empty", b"")
    write("garbage", b"this is not a zip archive at all")
    write("truncated", good[: len(good) // 2])
    rng = np.random.default_rng(7)  # flip bytes inside the compressed payload
    flipped = bytearray(good)
    for i in rng.integers(200, len(good) - 200, size=40):
        flipped[i] ^= 0xFF
    write("bitflips", bytes(flipped))
    cases["npy"] = folder / "plain.npy"
    np.save(cases["npy"], np.zeros(3))
    cases["npy_named_npz"] = folder / "array.npz"
    shutil.copy(cases["npy"], cases["npy_named_npz"])
    nan_root = arrays["root_orient"].copy()
    nan_root[5, 1] = np.nan
    arrays_with("nan_root", root_orient=nan_root)
    arrays_with("old_version", format_version=np.array(0))
    arrays_with("bad_offsets", clip_offset=arrays["clip_offset"][::-1].copy())
    arrays_with("unknown_split", clip_split=np.array(["train", "val", "oops", "test"]))
    arrays_with("float_names", clip_name=np.arange(4.0))
    arrays_with("nan_fps", fps=np.array(np.nan))
    arrays_with("wrong_joints", joint_aa=arrays["joint_aa"][:, :5])
    cases["pickled"] = folder / "pickled.npz"
    np.savez(cases["pickled"], **{**arrays, "clip_name": np.array([{"a": 1}] * 4, dtype=object)})
    cases["missing_key"] = folder / "nokey.npz"
    np.savez(cases["missing_key"], **{k: v for k, v in arrays.items() if k != "trans"})
    cases["zip_of_text"] = folder / "text.npz"
    with zipfile.ZipFile(cases["zip_of_text"], "w") as zf:
        zf.writestr("fps.npy", "not an npy header")
    return cases


DATA_CASES = ["missing", "folder", "empty", "garbage", "truncated", "bitflips", "npy",
              "npy_named_npz", "nan_root", "old_version", "bad_offsets", "unknown_split",
              "float_names", "nan_fps", "wrong_joints", "pickled", "missing_key",
              "zip_of_text"]  # fmt: skip


@pytest.fixture(scope="module")
def data_cases(tmp_path_factory, prepared) -> dict[str, Path]:
    return _data_cases(tmp_path_factory.mktemp("data"), prepared)


@pytest.mark.parametrize("case", DATA_CASES)
def test_missing_or_corrupt_data_is_one_line(tmp_path, capsys, prepared, data_cases, case) -> None:
    config = _config(tmp_path, prepared)
    argv = ["--config", str(config), f"data.prepared={data_cases[case]}"]
    err = _assert_one_line_error(capsys, argv, tmp_path / "runs", {})
    assert str(data_cases[case]) in err


# ---------------------------------------------------------------------------- checkpoints


class _Evil:
    def __reduce__(self):
        return (os.system, ("echo pwned > /dev/null",))


def _checkpoint_cases(folder: Path, last: Path) -> dict[str, Path]:
    good = last.read_bytes()
    state = torch.load(last, weights_only=True)
    cases: dict[str, Path] = {"missing": folder / "none.pt", "folder": folder}

    def write(name: str, content: bytes) -> None:
        cases[name] = folder / f"{name}.pt"
        cases[name].write_bytes(content)

    def save(name: str, obj) -> None:
        cases[name] = folder / f"{name}.pt"
        torch.save(obj, cases[name])

    write("empty", b"")
    write("garbage", b"\x80\x04garbage" * 10)
    write("truncated", good[: len(good) // 3])
    save("malicious", {**state, "extra": _Evil()})
    cases["plain_pickle"] = folder / "plain.pt"
    cases["plain_pickle"].write_bytes(pickle.dumps({"model": 1}))
    save("a_list", [1, 2, 3])
    save("lacks_keys", {"model": state["model"]})
    other = {**state, "config": {**state["config"], "model": {**state["config"]["model"],
                                                               "hidden": 16}}}  # fmt: skip
    save("other_architecture", other)  # weights of hidden 8, config says 16
    bad_cfg = {**state, "config": {**state["config"], "model": {"dropout": 2.0}}}
    save("invalid_architecture", bad_cfg)
    save("no_config", {**state, "config": "nope"})
    save("nan_best", {**state, "best_metric": float("nan")})
    save("bad_epoch", {**state, "epoch": "three"})
    save("bad_rng", {**state, "rng": [{"torch": torch.zeros(3)}]})
    save("foreign_optimizer", {**state, "optimizer": {"state": {}, "param_groups": [{}]}})
    return cases


CKPT_CASES = ["missing", "folder", "empty", "garbage", "truncated", "malicious", "plain_pickle",
              "a_list", "lacks_keys", "other_architecture", "invalid_architecture", "no_config",
              "nan_best", "bad_epoch", "bad_rng", "foreign_optimizer"]  # fmt: skip


@pytest.fixture(scope="module")
def checkpoint_cases(tmp_path_factory, finished_run) -> dict[str, Path]:
    _, run_dir = finished_run
    return _checkpoint_cases(tmp_path_factory.mktemp("ckpt"), run_dir / "last.pt")


@pytest.mark.parametrize("case", CKPT_CASES)
def test_bad_checkpoint_on_resume_is_one_line(capsys, finished_run, checkpoint_cases, case) -> None:
    config, run_dir = finished_run
    before = _snapshot(run_dir)
    argv = ["--config", str(config), "--resume", "--checkpoint", str(checkpoint_cases[case]),
            "train.epochs=2", "--no-final-eval"]  # fmt: skip
    err = _assert_one_line_error(capsys, argv, run_dir, before)
    assert str(checkpoint_cases[case]) in err
    if case == "malicious":
        assert "refused" in err and "system" in err


def test_resume_without_a_checkpoint_and_fresh_start_over_one(capsys, tmp_path, prepared,
                                                              finished_run) -> None:  # fmt: skip
    config = _config(tmp_path, prepared)
    err = _assert_one_line_error(
        capsys, ["--config", str(config), "--resume"], tmp_path / "runs", {}
    )
    assert "last.pt" in err
    config, run_dir = finished_run
    err = _assert_one_line_error(capsys, ["--config", str(config)], run_dir, _snapshot(run_dir))
    assert "--resume" in err


def test_the_valid_run_still_resumes(capsys, finished_run, tmp_path) -> None:
    config, run_dir = finished_run
    copy = tmp_path / "runs" / "fuzz"
    shutil.copytree(run_dir, copy)
    text = config.read_text().replace(str(run_dir.parent), str(tmp_path / "runs"))
    (tmp_path / "c.yaml").write_text(text)
    argv = ["--config", str(tmp_path / "c.yaml"), "--resume", "train.epochs=2", "--no-final-eval"]
    assert script.cli(argv) == 0
    assert torch.load(copy / "last.pt", weights_only=True)["epoch"] == 1
    assert "Traceback" not in capsys.readouterr().err
