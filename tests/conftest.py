"""Shared fixtures: tiny sessions written through the project's own writer."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from sessionfactory import make_tiny_session  # noqa: E402


@pytest.fixture
def tiny_session(tmp_path: Path) -> Path:
    return make_tiny_session(tmp_path / "session")


@pytest.fixture(scope="session")
def tiny_sim_session(tmp_path_factory) -> Path:
    """A small simulated session (160×120, 6 Hz) shared by the tests that need one."""
    from gaitnet.config import load_config
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    config = Path(__file__).parents[1] / "configs" / "sim" / "tiny.yaml"
    cfg = load_config(SimConfig, config, ["camera.fps=6", "output.preview_frames=2"])
    out = tmp_path_factory.mktemp("sim") / "tiny"
    simulate_session(cfg, 3, out)
    return out


@pytest.fixture(scope="session")
def tiny_model(tmp_path_factory, tiny_sim_session: Path) -> Path:
    """A random fusion segmenter for the tiny session's frame size (score layers drawn at
    random so that every class appears; the published zero init would give background only)."""
    import torch

    from gaitnet.io import open_session
    from gaitnet.segmentation.onnx_runtime import export_segmenter_onnx
    from gaitnet.segmentation.segmenter_net import build_segmenter

    calib = open_session(tiny_sim_session).calibration
    torch.manual_seed(0)
    model = build_segmenter("fusion", width=1 / 16, input_scale=1.0).eval()
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "score" in name:
                p.normal_(0.0, 0.5)
    path = tmp_path_factory.mktemp("seg") / "tiny.onnx"
    export_segmenter_onnx(model, path, height=calib.color.height, width=calib.color.width)
    return path
