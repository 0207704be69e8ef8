"""Step 2 of gaitnet infer (gaitnet.pipeline.foot_points): the HHA handed to the segmenter is
encoded at the resolution the model's streams see, with the floor and gravity of the camera
pose."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gaitnet.io.types import Frame
from gaitnet.pipeline.config import InferConfig
from gaitnet.pipeline.foot_points import floor_in_camera, measure_feet
from gaitnet.segmentation.hha import hha_encode
from gaitnet.segmentation.onnx_runtime import network_input

H, W, F = 96, 128, 100.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])


class RecordingSegmenter:
    """Labels everything background and keeps the input it was given."""

    arch = "hha"
    path = "recording"

    def __init__(self, input_scale: float) -> None:
        self.input_scale = input_scale
        self.inputs: list[np.ndarray] = []

    def labels(self, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
        self.inputs.append(network_input(self.arch, rgb, hha))
        return np.zeros(rgb.shape[:2], np.uint8)


def floor_frame() -> tuple[Frame, np.ndarray]:
    """A camera 1 m above the floor, pitched 60° down, seeing only the floor (ray-cast)."""
    t = np.radians(60.0)
    R = np.stack(
        [[0.0, -1.0, 0.0], [-np.sin(t), 0.0, -np.cos(t)], [np.cos(t), 0.0, -np.sin(t)]], axis=1
    )
    T = np.eye(4)
    T[:3, :3], T[2, 3] = R, 1.0
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], axis=-1) @ R.T
    depth = np.where(rays[..., 2] < -0.05, -1.0 / rays[..., 2], 0.0)
    depth = np.where(depth < 6.0, depth, 0.0).astype(np.float32)
    rgb = np.full((H, W, 3), 128, np.uint8)
    return Frame(index=0, t_ns=0, rgb=rgb, depth_m=depth), T


@pytest.mark.parametrize(("scale", "stride"), [(1.0, 1), (0.5, 2)])
def test_hha_is_encoded_at_the_models_resolution(scale: float, stride: int) -> None:
    frame, T = floor_frame()
    cfg = InferConfig()
    seg = RecordingSegmenter(scale)
    feet = measure_feet(frame, K, T, seg, "mid", cfg.hha, cfg.feet)  # type: ignore[arg-type]
    assert np.isnan(feet.foot_W).all() and feet.n_blobs == 0  # nothing labelled foot
    (x,) = seg.inputs
    plane = floor_in_camera(T)
    expected = hha_encode(frame.depth_m, K, -plane.n_C, cfg.hha, plane=plane, stride=stride)
    assert x.shape == (1, 3, H, W)
    np.testing.assert_array_equal(
        np.round(x[0] * 255.0).astype(np.uint8), expected.transpose(2, 0, 1)
    )
    blocks = x[0, :, ::2, ::2]
    assert np.array_equal(x[0, :, 1::2, 1::2], blocks) == (stride == 2)


def test_running_the_pipeline_does_not_import_pytorch() -> None:
    """The ONNX runtimes and the pipeline load without PyTorch (about 2 s of start-up);
    only the exports import it."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import gaitnet.pipeline.infer, gaitnet.pipeline.outputs, gaitnet.cli.commands\n"
        "import gaitnet.segmentation.onnx_runtime, gaitnet.motion.onnx_runtime\n"
        "print(sorted(m for m in ('torch', 'torchvision') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


class FloorAsFootSegmenter(RecordingSegmenter):
    """Labels a floor patch (what a segmenter's rim does) and a leg patch."""

    def labels(self, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
        labels = np.zeros(rgb.shape[:2], np.uint8)
        labels[40:70, 40:60] = 1
        labels[10:20, 90:110] = 2
        return labels


def test_kept_label_map_drops_floor_labelled_foot() -> None:
    """The label map handed on (``gaitnet infer --save-labels``) is the post-processed one: a
    foot label lying on the floor is no foot, the leg label stays."""
    frame, T = floor_frame()
    cfg = InferConfig()
    feet = measure_feet(frame, K, T, FloorAsFootSegmenter(0.5), "mid", cfg.hha, cfg.feet)  # type: ignore[arg-type]
    assert feet.n_blobs == 0 and np.isnan(feet.foot_W).all()
    assert not (feet.labels == 1).any()
    assert (feet.labels == 2).sum() == 10 * 20


class FarAndNearFootSegmenter(RecordingSegmenter):
    """Two foot blobs on the body's left: a large one far ahead, a small one near."""

    FAR = np.s_[4:24, 22:30]
    NEAR = np.s_[70:82, 34:44]

    def labels(self, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
        labels = np.zeros(rgb.shape[:2], np.uint8)
        labels[self.FAR] = 1
        labels[self.NEAR] = 1
        return labels


def test_a_foot_beyond_reach_is_no_foot() -> None:
    """With ``feet.max_distance_m`` the far blob (a box on the floor ahead) is dropped before
    the sides are assigned, so the near one is the left foot on its own; without the limit the
    far one, more to the left, takes the left side."""
    frame, T = floor_frame()
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], axis=-1)
    raised = (0.05 - 1.0) / (rays @ T[:3, :3].T)[..., 2]  # a surface 5 cm above the floor
    depth = frame.depth_m.copy()
    for region in (FarAndNearFootSegmenter.FAR, FarAndNearFootSegmenter.NEAR):
        depth[region] = raised[region]
    frame = Frame(index=0, t_ns=0, rgb=frame.rgb, depth_m=depth)
    cfg = InferConfig()
    seg = FarAndNearFootSegmenter(0.5)

    def feet_with(max_distance_m: float) -> np.ndarray:
        params = replace(cfg.feet, max_distance_m=max_distance_m)
        return measure_feet(frame, K, T, seg, "mid", cfg.hha, params).foot_W  # type: ignore[arg-type]

    limited, unlimited = feet_with(cfg.feet.max_distance_m), feet_with(float("inf"))
    reach = [np.hypot(*(p - T[:3, 3])[:2]) for p in (unlimited[0], limited[0])]
    assert reach[0] > cfg.feet.max_distance_m > reach[1]
    assert np.isnan(limited[1]).all()  # the near foot alone, sided left
    np.testing.assert_allclose(unlimited[1], limited[0])  # it was "right" beside the box
