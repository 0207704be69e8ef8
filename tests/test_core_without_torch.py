"""The core install has no PyTorch (pyproject: torch and torchvision are the ``train``
extra's): every module outside training imports without it, and a training script without it
says so in one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The modules that need PyTorch: training, the networks and their losses, torch datasets.
TRAINING_MODULES = {
    "gaitnet.geometry.torch_rotations",
    "gaitnet.motion.dct",
    "gaitnet.motion.evaluation",
    "gaitnet.motion.gcn",
    "gaitnet.motion.losses",
    "gaitnet.motion.motion_types",
    "gaitnet.motion.windows",
    "gaitnet.segmentation.dataset",
    "gaitnet.segmentation.fcn",
    "gaitnet.segmentation.focal_loss",
    "gaitnet.segmentation.segmenter_net",
    "gaitnet.segmentation.vgg16_weights",
    "gaitnet.training.checkpoint",
    "gaitnet.training.distributed",
    "gaitnet.training.onnx_weights",
    "gaitnet.training.predictor",
    "gaitnet.training.runs",
    "gaitnet.training.seeding",
    "gaitnet.training.segmenter",
    "gaitnet.training.segmenter_data",
}

BLOCK_TORCH = """
import sys
class _NoTorch:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "torchvision"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None
sys.meta_path.insert(0, _NoTorch())
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", BLOCK_TORCH + code], capture_output=True, text=True, cwd=ROOT
    )


def test_every_module_outside_training_imports_without_torch() -> None:
    """Exactly :data:`TRAINING_MODULES` fail to import with torch made unimportable (a new
    torch import in a core module fails this test, and so does a listed module that no
    longer needs torch)."""
    out = _run(
        "import importlib, pkgutil, gaitnet\n"
        "for m in pkgutil.walk_packages(gaitnet.__path__, 'gaitnet.'):\n"
        "    if m.name.endswith('__main__'):\n"
        "        continue\n"
        "    try:\n"
        "        importlib.import_module(m.name)\n"
        "    except ModuleNotFoundError as exc:\n"
        "        print(m.name, exc.name)\n"
    )
    assert out.returncode == 0, out.stderr
    failed = dict(line.split() for line in out.stdout.splitlines())
    assert set(failed) == TRAINING_MODULES
    assert set(failed.values()) == {"torch"}


def test_a_training_script_without_torch_says_so_in_one_line() -> None:
    out = _run(
        "import runpy\n"
        "sys.argv = ['train/predictor.py', '--help']\n"
        "runpy.run_path('train/predictor.py', run_name='__main__')\n"
    )
    assert out.returncode == 1
    assert out.stderr.strip() == "error: torch is not installed: pip install -e '.[train]'"


def test_the_exporter_without_torch_says_so_in_one_line() -> None:
    out = _run(
        "import runpy\n"
        "sys.argv = ['export/to_onnx.py', 'predictor', '--checkpoint', 'best.pt', '--out',"
        " 'x.onnx']\n"
        "runpy.run_path('export/to_onnx.py', run_name='__main__')\n"
    )
    assert out.returncode == 1
    assert out.stderr.strip() == "error: torch is not installed: pip install -e '.[train]'"
