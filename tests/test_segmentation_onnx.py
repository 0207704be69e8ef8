"""Segmenter ONNX export and runtime (gaitnet.segmentation.onnx_runtime, gaitnet.io.onnx_session,
gaitnet.io.onnx_export, export/to_onnx.py segmenter): parity with PyTorch, refusal of a failing
export, metadata, one-line errors for wrong inputs and foreign files."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch
from onnx import TensorProto, helper

import gaitnet.io.onnx_export as onnx_export
from gaitnet.errors import InputError
from gaitnet.io.onnx_session import OnnxInputError
from gaitnet.segmentation.edge_refine import argmax_classes
from gaitnet.segmentation.onnx_runtime import (
    OnnxParityError,
    OnnxSegmenter,
    export_segmenter_onnx,
)
from gaitnet.segmentation.segmenter_net import SegmenterNet
from gaitnet.training.checkpoint import save_checkpoint

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "export" / "to_onnx.py"
H, W = 40, 56


def tiny(arch: str, input_scale: float = 1.0, seed: int = 0, **geometry) -> SegmenterNet:
    """A width-1/16 net with small random weights everywhere (score layers start at zero)."""
    net = SegmenterNet(arch, width=1 / 16, input_scale=input_scale, **geometry)
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(0.1 * torch.randn(p.shape, generator=gen))
    return net.eval()


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> tuple[SegmenterNet, Path, float]:
    net = tiny("fusion", input_scale=0.5)
    path = tmp_path_factory.mktemp("onnx") / "fusion.onnx"
    report = export_segmenter_onnx(net, path, height=H, width=W)
    return net, path, report.max_abs_diff


def test_parity_dynamic_batch_and_metadata(exported) -> None:
    net, path, diff = exported
    assert diff <= 1e-4
    seg = OnnxSegmenter(path, threads=2)
    assert (seg.arch, seg.channels, seg.height, seg.width) == ("fusion", 6, H, W)
    assert seg.classes == ("background", "foot", "leg")
    assert seg.metadata["gaitnet.input_scale"] == "0.5" and seg.input_scale == 0.5
    assert seg.metadata["gaitnet.padding"] == "published"
    assert seg.metadata["gaitnet.width"] == "0.0625"
    assert json.loads(seg.metadata["gaitnet.normalisation"])["rgb"]["mean"] == [0.485, 0.456, 0.406]
    x = np.random.default_rng(1).random((3, 6, H, W), dtype=np.float32)
    with torch.no_grad():
        expected = net(torch.from_numpy(x)).numpy()
    logits = seg(x)
    assert logits.shape == (3, 3, H, W) and logits.dtype == np.float32
    assert np.abs(expected).max() > 1e-2  # the nets are not trivially zero
    np.testing.assert_allclose(logits, expected, atol=1e-4)
    labels = seg.predict(x)
    assert labels.dtype == np.uint8 and labels.shape == (3, H, W)
    np.testing.assert_array_equal(labels, np.argmax(logits, axis=1))
    # float64 and integer inputs are fed as float32
    np.testing.assert_allclose(seg(x.astype(np.float64)), logits, atol=1e-6)


def test_single_stream_export(tmp_path: Path) -> None:
    """An HHA stream with the finest output stride, ``same`` padding and a logit bias: the
    graph adds the bias (parity with PyTorch) and the metadata record it."""
    net = tiny("hha", seed=2, padding="same", output_stride=2, logit_bias=[0.0, -0.5, 0.25])
    report = export_segmenter_onnx(net, tmp_path / "hha.onnx", height=33, width=47)
    assert report.max_abs_diff <= 1e-4
    seg = OnnxSegmenter(tmp_path / "hha.onnx")
    assert (seg.arch, seg.channels, seg.height, seg.width) == ("hha", 3, 33, 47)
    assert seg.metadata["gaitnet.output_stride"] == "2"
    assert seg.metadata["gaitnet.padding"] == "same"
    assert json.loads(seg.metadata["gaitnet.logit_bias"]) == [0.0, -0.5, 0.25]
    x = np.random.default_rng(3).random((1, 3, 33, 47), dtype=np.float32)
    unbiased = tiny("hha", seed=2, padding="same", output_stride=2)
    with torch.no_grad():
        plain = unbiased(torch.from_numpy(x)).numpy()
    shift = seg(x) - plain
    np.testing.assert_allclose(shift, np.broadcast_to([[[[0.0]], [[-0.5]], [[0.25]]]], shift.shape),
                               atol=1e-4)  # fmt: skip


class _Skewed:
    """An onnxruntime session whose outputs are off by 1e-3."""

    def __init__(self, session) -> None:
        self.session = session

    def run(self, names, feed):
        return [out + 1e-3 for out in self.session.run(names, feed)]


def test_export_refused_when_parity_fails(tmp_path: Path, monkeypatch) -> None:
    real = onnx_export.open_session
    monkeypatch.setattr(onnx_export, "open_session", lambda *a, **k: _Skewed(real(*a, **k)))
    net = tiny("rgb", seed=3)
    path = tmp_path / "rgb.onnx"
    path.write_bytes(b"previous model")
    with pytest.raises(OnnxParityError, match=r"max \|onnxruntime - torch\| = 0.001 exceeds"):
        export_segmenter_onnx(net, path, height=24, width=32)
    assert path.read_bytes() == b"previous model"  # left as it was, no temporary file left
    assert list(tmp_path.iterdir()) == [path]
    # the same skew passes a looser tolerance
    report = export_segmenter_onnx(net, path, height=24, width=32, atol=2e-3)
    assert 0.9e-3 < report.max_abs_diff <= 1.1e-3
    assert OnnxSegmenter(path).arch == "rgb"


def test_flip_average_is_the_mean_over_the_mirrored_frame(exported) -> None:
    _, path, _ = exported
    plain = OnnxSegmenter(path)
    flip = OnnxSegmenter(path, flip_average=True)
    x = np.random.default_rng(3).random((2, 6, H, W), dtype=np.float32)
    mirrored = plain(np.ascontiguousarray(x[..., ::-1]))[..., ::-1]
    np.testing.assert_allclose(flip(x), (plain(x) + mirrored) / 2, atol=1e-6)
    assert np.abs(flip(x) - plain(x)).max() > 1e-3  # the option acts
    # a frame that is its own mirror image gets logits that are their own mirror image
    symmetric = (x + x[..., ::-1]) / 2
    out = flip(symmetric)
    np.testing.assert_allclose(out, out[..., ::-1], atol=1e-6)
    # bad input is still the one-line error, naming the file
    with pytest.raises(OnnxInputError, match=re.escape(str(path))):
        flip(x[:, :3])


def _one_line(exc: pytest.ExceptionInfo, path: Path) -> None:
    text = str(exc.value)
    assert "\n" not in text and str(path) in text


@pytest.mark.parametrize(
    ("x", "match"),
    [
        (np.zeros((6, H, W), np.float32), r"expects shape \('batch', 6, 'H', 'W'\), given \(6, 40"),
        (np.zeros((1, 3, H, W), np.float32), "expects shape"),
        (np.zeros((0, 6, H, W), np.float32), "empty"),
        (np.zeros((1, 6, H, W), np.complex64), "dtype complex64"),
        (np.zeros((1, 6, H, W), bool), "dtype bool"),
        (np.full((1, 6, H, W), "a"), "dtype <U1"),
        (np.full((1, 6, H, W), 1e300), r"NaN/inf or values beyond float32's range"),
    ],
)
def test_wrong_inputs_are_one_line_errors(exported, x: np.ndarray, match: str) -> None:
    _, path, _ = exported
    seg = OnnxSegmenter(path)
    with pytest.raises(OnnxInputError, match=match) as err:
        seg(x)
    _one_line(err, path)


def test_nan_input_names_the_first_index(exported) -> None:
    _, path, _ = exported
    x = np.zeros((2, 6, H, W), np.float32)
    x[1, 4, 7, 9] = np.nan
    with pytest.raises(OnnxInputError, match=r"first at index \(1, 4, 7, 9\)"):
        OnnxSegmenter(path).predict(x)


def _foreign_onnx(path: Path) -> Path:
    """A valid ONNX file (Identity on (1, 6, 4, 4)) without gaitnet's metadata."""
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 6, 4, 4])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 6, 4, 4])
    graph = helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "g", [x], [y])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    model.ir_version = 9
    onnx.save(model, path)
    return path


def test_foreign_files_and_options(tmp_path: Path, exported) -> None:
    _, good, _ = exported
    cases = {
        "does not exist": tmp_path / "none.onnx",
        "is a folder": tmp_path,
        "cannot be loaded": tmp_path / "garbage.onnx",
        "is not a gaitnet segmenter": _foreign_onnx(tmp_path / "identity.onnx"),
    }
    (tmp_path / "garbage.onnx").write_bytes(b"\x00not onnx at all")
    for match, path in cases.items():
        with pytest.raises(OnnxInputError, match=match) as err:
            OnnxSegmenter(path)
        _one_line(err, path)
    for scale in ("0", "1.5", "half"):  # the HHA stride follows it: refused when meaningless
        model = onnx.load(good)
        for prop in model.metadata_props:
            if prop.key == "gaitnet.input_scale":
                prop.value = scale
        onnx.save(model, tmp_path / "scale.onnx")
        with pytest.raises(OnnxInputError, match="gaitnet.input_scale") as err:
            OnnxSegmenter(tmp_path / "scale.onnx")
        _one_line(err, tmp_path / "scale.onnx")
    with pytest.raises(OnnxInputError, match="not available"):
        OnnxSegmenter(good, providers=("NoSuchExecutionProvider",))
    with pytest.raises(OnnxInputError, match="threads"):
        OnnxSegmenter(good, threads=-1)
    assert issubclass(OnnxInputError, InputError)


def test_bad_export_arguments(tmp_path: Path) -> None:
    net = tiny("rgb")
    with pytest.raises(OnnxInputError, match="height"):
        export_segmenter_onnx(net, tmp_path / "x.onnx", height=0)
    with pytest.raises(OnnxInputError, match="2 class names for 3"):
        export_segmenter_onnx(net, tmp_path / "x.onnx", classes=("a", "b"))
    assert not (tmp_path / "x.onnx").exists()


def _checkpoint(
    folder: Path, net: SegmenterNet, model_cfg: dict | None = None, **extra: object
) -> Path:
    state = {
        **extra,
        "model": net.state_dict(),
        "optimizer": {},
        "scheduler": {},
        "epoch": 4,
        "best_metric": 0.5,
        "best_epoch": 4,
        "config": {"name": "tiny", "model": model_cfg or net.config()},
        "git_hash": "abc",
    }
    return save_checkpoint(state, folder / "best.pt")


def test_export_script(tmp_path: Path) -> None:
    net = tiny("rgb", input_scale=0.5, seed=4)  # one stream: half the export time
    ckpt = _checkpoint(tmp_path / "run", net, calibration={"logit_bias": [0.0, 0.0, 0.0]})
    # the scores of this checkpoint (train/segmenter.py --eval-only) win over the run's eval.json
    (ckpt.parent / "eval.json").write_text(json.dumps({"sets": {"end_of_training": {}}}))
    (ckpt.parent / "eval_best.json").write_text(json.dumps({"sets": {"own": {}}, "config": {}}))
    out = tmp_path / "models" / "seg.onnx"
    cmd = [sys.executable, str(SCRIPT), "segmenter", "--checkpoint", str(ckpt), "--out", str(out)]
    done = subprocess.run([*cmd, "--height", "36", "--width", "52"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    diff = float(re.search(r"max \|onnxruntime - torch\| = (\S+)", done.stdout).group(1))
    assert diff <= 1e-4
    sidecar = json.loads(out.with_suffix(".json").read_text())
    assert sidecar["arch"] == "rgb" and sidecar["input_scale"] == 0.5
    assert sidecar["input"]["shape"] == ["batch", 3, 36, 52]
    assert sidecar["classes"] == ["background", "foot", "leg"]
    assert sidecar["metrics"] == {"sets": {"own": {}}}
    assert sidecar["calibration"] == {"logit_bias": [0.0, 0.0, 0.0]}
    assert sidecar["logit_bias"] == [0.0, 0.0, 0.0] and sidecar["output_stride"] == 8
    assert sidecar["checkpoint"]["epoch"] == 4 and sidecar["parameters"] == sum(
        p.numel() for p in net.parameters()
    )
    x = np.random.default_rng(5).random((2, 3, 36, 52), dtype=np.float32)
    with torch.no_grad():
        expected = net(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(OnnxSegmenter(out)(x), expected, atol=1e-4)


def test_export_script_errors(tmp_path: Path, capsys) -> None:
    spec = importlib.util.spec_from_file_location("to_onnx", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    net = tiny("rgb")
    # a checkpoint whose config does not match its weights: one line, nothing written
    bad = _checkpoint(tmp_path / "bad", net, {**net.config(), "width": 0.125})
    out = tmp_path / "models" / "bad.onnx"
    assert script.main(["segmenter", "--checkpoint", str(bad), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {bad}: its model state does not fit config.model"), err
    assert err.count("\n") == 1 and not out.exists()
    # a predictor checkpoint (no config.model mapping of a segmenter)
    other = _checkpoint(tmp_path / "other", net, {"n_past": 10})
    assert script.main(["segmenter", "--checkpoint", str(other), "--out", str(out)]) == 1
    assert "config.model lacks key(s)" in capsys.readouterr().err


@pytest.mark.parametrize("classes", [2, 3, 5])
def test_argmax_classes_is_numpys_argmax_ties_included(classes: int) -> None:
    rng = np.random.default_rng(classes)
    logits = rng.integers(-2, 3, (2, classes, 7, 9)).astype(np.float32)  # many ties
    labels = argmax_classes(logits)
    assert labels.dtype == np.uint8 and labels.shape == (2, 7, 9)
    np.testing.assert_array_equal(labels, np.argmax(logits, axis=1))


def test_committed_model_is_what_its_sidecar_says() -> None:
    """The default segmenter of gaitnet segment / infer: loads, has the documented contract,
    and its sidecar (provenance, scores) describes these very bytes."""
    import hashlib

    from gaitnet.segmentation.segment_session import default_segmenter_path

    path = default_segmenter_path()
    seg = OnnxSegmenter(path)
    side = json.loads(path.with_suffix(".json").read_text())
    assert side["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert (seg.arch, seg.channels, seg.height, seg.width) == ("fusion", 6, 480, 640)
    assert (
        seg.input_scale == side["input_scale"]
        and seg.metadata["gaitnet.padding"] == side["padding"]
        and int(seg.metadata["gaitnet.output_stride"]) == side["output_stride"]
        and json.loads(seg.metadata["gaitnet.logit_bias"]) == side["logit_bias"]
    )
    assert seg.classes == tuple(side["classes"]) == ("background", "foot", "leg")
    labels = seg.predict(np.zeros((1, 6, 480, 640), np.float32))
    assert labels.shape == (1, 480, 640)


def test_sidecar_scores_are_the_checkpoints_own(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("to_onnx", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    (tmp_path / "eval.json").write_text(json.dumps({"sets": {"best": {}}, "config": {}}))
    assert script.read_eval(tmp_path / "best.pt") == {"sets": {"best": {}}}
    assert script.read_eval(tmp_path / "calibrated.pt") is None  # not best.pt's scores
    (tmp_path / "eval_calibrated.json").write_text(json.dumps({"sets": {"own": {}}}))
    assert script.read_eval(tmp_path / "calibrated.pt") == {"sets": {"own": {}}}
