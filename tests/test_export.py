"""export/to_onnx.py: subprocess smoke tests of the predictor export (parity, sidecar, errors)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from gaitnet.config import config_to_dict, load_config
from gaitnet.motion.gcn import DCTGCN
from gaitnet.motion.onnx_runtime import OnnxPredictor
from gaitnet.training.checkpoint import save_checkpoint
from gaitnet.training.predictor import PredictorTrainingConfig

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "export" / "to_onnx.py"


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> tuple[Path, DCTGCN]:
    run = tmp_path_factory.mktemp("run")
    cfg = load_config(
        PredictorTrainingConfig,
        None,
        ["name=tiny", "model.hidden=16", "model.n_blocks=1", "model.dct_n=15"],
    )
    torch.manual_seed(0)
    model = DCTGCN(cfg.model).eval()
    state = {
        "model": model.state_dict(),
        "optimizer": {},
        "scheduler": {},
        "epoch": 3,
        "best_metric": 0.0123,
        "best_epoch": 3,
        "config": config_to_dict(cfg),
        "git_hash": "abc",
        "fps": 30.0,
    }
    path = save_checkpoint(state, run / "best.pt")
    (run / "eval.json").write_text(json.dumps({"split": "test", "methods": {}, "config": {}}))
    return path, model


def test_export_predictor_parity_and_sidecar(tmp_path: Path, checkpoint) -> None:
    path, model = checkpoint
    out = tmp_path / "models" / "tiny.onnx"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "predictor", "--checkpoint", str(path), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    diff = float(re.search(r"max \|onnxruntime - torch\| = (\S+)", done.stdout).group(1))
    assert diff <= 1e-4
    sidecar = json.loads(out.with_suffix(".json").read_text())
    assert (sidecar["n_past"], sidecar["n_future"], sidecar["dct_n"]) == (10, 10, 15)
    assert sidecar["node_layout"]["smpl_joints"] == [0, 1, 2, 4, 5, 7, 8]
    assert sidecar["input"]["name"] == "past_poses" and sidecar["metrics"]["split"] == "test"
    assert sidecar["parity_max_abs_diff"] <= 1e-4 and sidecar["checkpoint"]["epoch"] == 3
    x = np.random.default_rng(0).normal(scale=0.3, size=(3, 10, 21)).astype(np.float32)
    with torch.no_grad():
        expected = model(torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(OnnxPredictor(out)(x), expected, atol=1e-4)


def test_export_errors_are_one_line(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "predictor", "--checkpoint", str(tmp_path / "no.pt"),
         "--out", str(tmp_path / "x.onnx")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 1
    assert done.stderr.startswith("error: checkpoint") and "does not exist" in done.stderr
    assert not (tmp_path / "x.onnx").exists()
    done = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True)
    assert done.returncode == 1 and "KIND" in done.stderr  # a subcommand is required
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
