"""The benchmark scripts keep gaitnet's error contract (gaitnet.cli.scripts.run_script): a bad
option or a missing input is one line on stderr, naming it, and exit status 1."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
SCRIPTS = sorted(p.name for p in (ROOT / "benchmarks").glob("*.py") if p.name != "vio_protocol.py")


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


def _one_line_error(proc: subprocess.CompletedProcess, *names: str) -> None:
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for name in names:
        assert name in lines[0]


def test_every_script_is_listed() -> None:
    assert len(SCRIPTS) >= 20 and "bench_infer.py" in SCRIPTS


@pytest.mark.parametrize("script", SCRIPTS)
def test_a_bad_option_is_one_line(script: str) -> None:
    proc = _run(f"benchmarks/{script}", "--no-such-option")
    _one_line_error(proc, script)


@pytest.mark.parametrize(
    "script",
    [
        "bench_swing_fill.py",
        "bench_infer.py",
        "bench_segmenter_labels.py",
        "bench_swing_errors.py",
        "bench_png.py",
        "bench_real_motion.py",
        "bench_profile.py",
    ],
)
def test_a_missing_input_is_one_line(tmp_path: Path, script: str) -> None:
    missing = str(tmp_path / "missing")
    _one_line_error(_run(f"benchmarks/{script}", missing), missing)
