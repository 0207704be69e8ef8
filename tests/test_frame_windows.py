"""A segmenter exported for one frame size on frames of another (gaitnet.segmentation.frame_windows
through OnnxSegmenter): the windows cover the frame, the weights join them, and a per-pixel
network gives exactly its output on the scaled frame, scaled back."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
import torch
from onnx import TensorProto, helper, numpy_helper

from gaitnet.segmentation.frame_windows import MIN_OVERLAP, window_starts, window_weights
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter, export_segmenter_onnx
from gaitnet.segmentation.segmenter_net import SegmenterNet

H, W = 40, 56


@pytest.mark.parametrize(("width", "window"), [(56, 56), (30, 56), (75, 56), (160, 56), (853, 640)])
def test_windows_cover_the_width_and_their_weights_sum_to_one(width: int, window: int) -> None:
    starts = window_starts(width, window)
    assert starts[0] == 0 and starts == sorted(starts)
    if width <= window:
        assert starts == [0]
    else:
        assert starts[-1] + window == width
        overlap = min(MIN_OVERLAP, window // 2)
        ends = [a + window for a in starts]
        assert all(ends[i] - starts[i + 1] >= overlap for i in range(len(starts) - 1))
        fewer = np.linspace(0, width - window, len(starts) - 1)  # one window less overlaps less
        assert len(starts) == 2 or min(window - np.diff(fewer)) < overlap
    span = max(width, window)
    weights = window_weights(starts, window, span)
    np.testing.assert_allclose(weights.sum(axis=0), 1.0, atol=1e-6)
    for i, a in enumerate(starts):
        outside = np.ones(span, bool)
        outside[a : a + window] = False
        assert (weights[i, outside] == 0).all()
    if len(starts) > 1:  # at the second window's seam the first window weighs most
        seam = starts[1]
        assert weights[0, seam] > weights[1, seam] > 0


def _pixelwise_segmenter(tmp_path: Path, like: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """A gaitnet segmenter for (batch, 6, H, W) frames whose logits are a 1 × 1 convolution of
    the input, with the metadata of the exported model ``like``."""
    rng = np.random.default_rng(3)
    weight = rng.normal(size=(3, 6, 1, 1)).astype(np.float32)
    bias = rng.normal(size=3).astype(np.float32)
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w", "b"], ["logits"])],
        "pixelwise",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, ["batch", 6, H, W])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", 3, H, W])],
        [numpy_helper.from_array(weight, "w"), numpy_helper.from_array(bias, "b")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    model.ir_version = onnx.load(like).ir_version
    for prop in onnx.load(like).metadata_props:
        model.metadata_props.add(key=prop.key, value=prop.value)
    path = tmp_path / "pixelwise.onnx"
    onnx.save(model, path)
    return path, weight[:, :, 0, 0], bias


@pytest.fixture(scope="module")
def fusion(tmp_path_factory) -> Path:
    net = SegmenterNet("fusion", width=1 / 16, input_scale=0.5)
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(0.1 * torch.randn(p.shape, generator=gen))
    path = tmp_path_factory.mktemp("windows") / "fusion.onnx"
    export_segmenter_onnx(net.eval(), path, height=H, width=W)
    return path


@pytest.mark.parametrize("size", [(30, 90), (60, 210), (40, 30), (20, 20)])
def test_a_pixelwise_network_gives_its_output_on_the_scaled_frame(
    tmp_path: Path, fusion: Path, size: tuple[int, int]
) -> None:
    path, weight, bias = _pixelwise_segmenter(tmp_path, fusion)
    seg = OnnxSegmenter(path)
    h, w = size
    x = np.random.default_rng(5).random((2, 6, h, w), dtype=np.float32)
    got = seg(x)
    assert got.shape == (2, 3, h, w)
    scaled_w = round(w * H / h)
    expected = np.empty_like(got)
    for b in range(2):  # independently: OpenCV's resize of the planes, the convolution, back
        up = cv2.INTER_AREA if (h >= H and scaled_w <= w) else cv2.INTER_LINEAR
        planes = np.stack([cv2.resize(p, (scaled_w, H), interpolation=up) for p in x[b]])
        logits = np.einsum("kc,chw->khw", weight, planes) + bias[:, None, None]
        down = cv2.INTER_AREA if (h <= H and w <= scaled_w) else cv2.INTER_LINEAR
        expected[b] = np.stack([cv2.resize(p, (w, h), interpolation=down) for p in logits])
    np.testing.assert_allclose(got, expected, atol=2e-5)


def test_a_frame_of_the_models_size_is_not_windowed(fusion: Path) -> None:
    seg = OnnxSegmenter(fusion)
    x = np.random.default_rng(1).random((1, 6, H, W), dtype=np.float32)
    np.testing.assert_array_equal(seg(x), seg._run(x))
    wide = np.concatenate([x, x[..., : W // 2]], axis=3)  # 84 columns: two windows
    labels = seg.predict(wide)
    assert labels.shape == (1, H, W + W // 2) and labels.max() < 3
    np.testing.assert_array_equal(seg(wide)[..., :8], seg(x)[..., :8])  # far from the seam
