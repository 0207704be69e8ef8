"""Every command survives bad arguments: exit 1, exactly one line on stderr, no traceback.

Runs ``gaitnet.cli.main`` in-process on every subcommand (and on ``gaitnet`` with no or an
unknown command) with missing, unknown and malformed options, out-of-range numbers, paths
that do not exist, files where folders are expected and the reverse. None of these cases
renders a frame: each is refused before any simulation starts. Also: an unexpected exception
is a bug (exit 2 with the traceback), an OSError on a user path is exit 1, Ctrl-C is 130 and
SIGTERM 143.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from oneline import assert_one_line_exit

from gaitnet import cli
from gaitnet.cli import main

# Placeholders: {session} a valid tiny session folder, {file} a regular file, {dir} an empty
# folder, {nonempty} a non-empty folder, {missing} a path that does not exist, {tmp} a fresh
# folder to write into, {badyaml} a config that is not YAML, {result} a result folder whose
# joints.npz is corrupt, {badshape} one whose joints.npz has the wrong shape, {badtum} one with
# a broken camera_frames.tum, {gtsession} a session folder with an (empty) groundtruth/.
OUT = "{tmp}/out"
CASES: list[tuple[str, list[str], str]] = [
    # (id, argv, a substring of the one error line)
    ("no-command", [], "gaitnet: error: the following arguments are required: COMMAND"),
    ("unknown-command", ["nope"], "invalid choice: 'nope'"),
    ("unknown-top-option", ["--bogus", "check", "{session}"], "unrecognized arguments: --bogus"),
    ("verbose-only", ["-v"], "required: COMMAND"),
    # check
    ("check-missing-arg", ["check"], "gaitnet check: error: the following arguments"),
    ("check-missing-path", ["check", "{missing}"], "{missing}"),
    ("check-missing-bag", ["check", "{missing}.bag"], "bag file not found"),
    ("check-file", ["check", "{file}"], "not a session folder or a .bag file"),
    ("check-empty-dir", ["check", "{dir}"], "session.yaml"),
    ("check-unknown-option", ["check", "{session}", "--bogus"], "unrecognized arguments"),
    ("check-extra-arg", ["check", "{session}", "extra"], "unrecognized arguments: extra"),
    ("check-flag-value", ["check", "{session}", "--decode=yes"], "ignored explicit argument"),
    # tags
    ("tags-missing-out", ["tags"], "required: --out"),
    ("tags-suffix", ["tags", "--out", "{tmp}/sheet.gif"], "written as .png or .pdf"),
    ("tags-out-dir", ["tags", "--out", "{dir}"], "is a folder"),
    ("tags-rows-zero", ["tags", "--out", "{tmp}/s.png", "--rows", "0"], "rows must be"),
    ("tags-size-nan", ["tags", "--out", "{tmp}/s.png", "--tag-size-mm", "nan"], "finite"),
    ("tags-too-big", ["tags", "--out", "{tmp}/s.png", "--paper", "a4"], "do not fit on A4"),
    ("tags-paper", ["tags", "--out", "{tmp}/s.png", "--paper", "a0"], "invalid choice"),
    ("tags-ids", ["tags", "--out", "{tmp}/s.png", "--first-id", "580"], "ids 0–586 only"),
    ("tags-dpi", ["tags", "--out", "{tmp}/s.png", "--dpi", "5"], "dpi 5"),
    # convert
    ("convert-missing-args", ["convert"], "gaitnet convert: error: the following arguments"),
    ("convert-missing-output", ["convert", "{session}"], "required: OUTPUT"),
    ("convert-missing-input", ["convert", "{missing}", OUT], "{missing}"),
    ("convert-input-file", ["convert", "{file}", OUT], "not a session folder"),
    ("convert-output-file", ["convert", "{session}", "{file}"], "exists and is not a folder"),
    ("convert-output-nonempty", ["convert", "{session}", "{nonempty}"], "not empty"),
    ("convert-output-below-file", ["convert", "{session}", "{file}/sub"], "{file}"),
    ("convert-output-empty", ["convert", "{session}", ""], "empty path"),
    ("convert-unknown-option", ["convert", "{session}", OUT, "--force"], "unrecognized"),
    ("convert-board-missing", ["convert", "{session}", OUT, "--board", "{missing}"], "not found"),
    ("convert-board-dir", ["convert", "{session}", OUT, "--board", "{dir}"], "is not a file"),
    ("convert-board-bad", ["convert", "{session}", OUT, "--board", "{badyaml}"], "not valid YAML"),
    # simulate
    ("simulate-missing-out", ["simulate"], "required: --out"),
    (
        "simulate-seed-negative",
        ["simulate", "--out", OUT, "--seed", "-1"],
        "seed must be within 0–4294967295",
    ),
    (
        "simulate-seed-2**32",
        ["simulate", "--out", OUT, "--seed", str(2**32)],
        "seed must be within",
    ),
    ("simulate-seed-text", ["simulate", "--out", OUT, "--seed", "abc"], "expected an integer"),
    ("simulate-seed-float", ["simulate", "--out", OUT, "--seed", "1.5"], "argument --seed"),
    ("simulate-seed-empty", ["simulate", "--out", OUT, "--seed", ""], "argument --seed"),
    ("simulate-seed-no-value", ["simulate", "--out", OUT, "--seed"], "expected one argument"),
    ("simulate-out-file", ["simulate", "--out", "{file}"], "exists and is not a folder"),
    ("simulate-out-empty", ["simulate", "--out", ""], "empty path"),
    ("simulate-out-nonempty", ["simulate", "--out", "{nonempty}"], "not empty"),
    ("simulate-config-missing", ["simulate", "--out", OUT, "--config", "{missing}"], "not found"),
    ("simulate-config-dir", ["simulate", "--out", OUT, "--config", "{dir}"], "is a folder"),
    ("simulate-config-bad", ["simulate", "--out", OUT, "--config", "{badyaml}"], "not valid YAML"),
    ("simulate-override-empty-key", ["simulate", "--out", OUT, "=5"], "override '=5'"),
    ("simulate-override-dots", ["simulate", "--out", OUT, "a..b=1"], "not a dotted key"),
    ("simulate-override-no-eq", ["simulate", "--out", OUT, "gait.speed_mps"], "key=value"),
    ("simulate-override-type", ["simulate", "--out", OUT, "gait.speed_mps=fast"], "expects"),
    ("simulate-override-nan", ["simulate", "--out", OUT, "camera.fps=.nan"], "finite"),
    ("simulate-override-range", ["simulate", "--out", OUT, "mount.pitch_deg=120"], "pitch_deg"),
    ("simulate-override-unknown", ["simulate", "--out", OUT, "gait.sped=1"], "unknown key"),
    ("simulate-unknown-option", ["simulate", "--out", OUT, "--bogus"], "unrecognized"),
    # simulate-dataset
    ("dataset-missing-n", ["simulate-dataset", "--out", OUT], "required: --n"),
    ("dataset-missing-out", ["simulate-dataset", "--n", "1"], "required: --out"),
    (
        "dataset-n-zero",
        ["simulate-dataset", "--n", "0", "--out", OUT],
        "--n (number of frames) must be within 1–1000000",
    ),
    ("dataset-n-negative", ["simulate-dataset", "--n", "-3", "--out", OUT], "--n (number"),
    ("dataset-n-text", ["simulate-dataset", "--n", "ten", "--out", OUT], "expected an integer"),
    ("dataset-n-float", ["simulate-dataset", "--n", "2.5", "--out", OUT], "argument --n"),
    (
        "dataset-seed-negative",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--seed", "-1"],
        "--seed must be within",
    ),
    (
        "dataset-pitch-order",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-min", "80", "--pitch-max", "60"],
        "--pitch-min/--pitch-max must satisfy 10 ≤ min ≤ max ≤ 89°",
    ),
    (
        "dataset-pitch-nan",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-min", "nan"],
        "argument --pitch-min",
    ),
    (
        "dataset-pitch-inf",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-max", "inf"],
        "argument --pitch-max",
    ),
    (
        "dataset-pitch-low",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-min", "5", "--pitch-max", "60"],
        "10 ≤ min",
    ),
    (
        "dataset-pitch-high",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-min", "60", "--pitch-max", "95"],
        "max ≤ 89°",
    ),
    (
        "dataset-pitch-text",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-max", "x"],
        "expected a number",
    ),
    (
        "dataset-pitch-alone",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--pitch-min", "60"],
        "together",
    ),
    ("dataset-out-file", ["simulate-dataset", "--n", "1", "--out", "{file}"], "not a folder"),
    (
        "dataset-config-bad",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--config", "{badyaml}"],
        "not valid YAML",
    ),
    ("dataset-override-bad", ["simulate-dataset", "--n", "1", "--out", OUT, "=5"], "empty key"),
    (
        "dataset-unknown-option",
        ["simulate-dataset", "--n", "1", "--out", OUT, "--labelme=1"],
        "ignored explicit argument",
    ),
    # evaluate
    ("vio-missing-args", ["vio"], "gaitnet vio: error: the following arguments"),
    ("vio-missing-out", ["vio", "{session}"], "required: --out"),
    ("vio-session-missing", ["vio", "{missing}", "--out", "{tmp}/out"], "{missing}"),
    ("vio-out-is-file", ["vio", "{session}", "--out", "{file}"], "{file}"),
    ("vio-bad-key", ["vio", "{session}", "--out", "{tmp}/out", "filter.nope=1"], "filter.nope"),
    (
        "vio-bad-value",
        ["vio", "{session}", "--out", "{tmp}/out", "filter.foot_std_m=-1"],
        "foot_std_m",
    ),
    (
        "vio-value-too-large",  # finite, but its square overflowed inside the filter
        ["vio", "{session}", "--out", "{tmp}/out", "imu.scale=1e308"],
        "scale must be a number of magnitude at most 1e30",
    ),
    ("segment-missing-args", ["segment"], "gaitnet segment: error: the following arguments"),
    ("segment-missing-out", ["segment", "{session}"], "required: --out"),
    ("segment-session-missing", ["segment", "{missing}", "--out", "{tmp}/out"], "{missing}"),
    ("segment-out-is-file", ["segment", "{session}", "--out", "{file}"], "{file}"),
    (
        "segment-model-missing",
        ["segment", "{session}", "--out", "{tmp}/out", "--model", "{missing}"],
        "{missing}",
    ),
    (
        "segment-model-not-onnx",
        ["segment", "{session}", "--out", "{tmp}/out", "--model", "{file}"],
        "{file}",
    ),
    (
        "segment-bad-threads",
        ["segment", "{session}", "--out", "{tmp}/out", "--threads", "2.5"],
        "expected an integer",
    ),
    ("infer-missing-args", ["infer"], "gaitnet infer: error: the following arguments"),
    ("infer-missing-out", ["infer", "{session}"], "required: --out"),
    ("infer-session-missing", ["infer", "{missing}", "--out", "{tmp}/out"], "{missing}"),
    ("infer-out-is-file", ["infer", "{session}", "--out", "{file}"], "{file}"),
    (
        "infer-bad-key",
        ["infer", "{session}", "--out", "{tmp}/out", "pipeline.nope=1"],
        "pipeline.nope",
    ),
    (
        "infer-bad-value",
        ["infer", "{session}", "--out", "{tmp}/out", "pipeline.standing_s=-1"],
        "standing_s",
    ),
    (
        "infer-segmenter-not-onnx",
        ["infer", "{session}", "--out", "{tmp}/out", "--segmenter", "{file}"],
        "{file}",
    ),
    ("batch-missing-args", ["batch"], "gaitnet batch: error: the following arguments"),
    ("batch-missing-out", ["batch", "{session}"], "required: --out"),
    ("batch-no-session", ["batch", "{dir}", "--out", "{tmp}/out"], "no session found"),
    (
        "batch-workers-0",
        ["batch", "{session}", "--out", "{tmp}/out", "--workers", "0"],
        "--workers must be within 1–1024",
    ),
    (
        "batch-bad-key",
        ["batch", "{session}", "--out", "{tmp}/out", "pipeline.nope=1"],
        "pipeline.nope",
    ),
    ("evaluate-missing-args", ["evaluate"], "gaitnet evaluate: error: the following arguments"),
    ("evaluate-missing-session", ["evaluate", "{dir}"], "required: --session"),
    ("evaluate-result-missing", ["evaluate", "{missing}", "--session", "{session}"], "{missing}"),
    ("evaluate-result-file", ["evaluate", "{file}", "--session", "{session}"], "{file}"),
    ("evaluate-session-missing", ["evaluate", "{dir}", "--session", "{missing}"], "{missing}"),
    ("evaluate-session-file", ["evaluate", "{dir}", "--session", "{file}"], "{file}"),
    ("evaluate-no-groundtruth", ["evaluate", "{dir}", "--session", "{session}"], "no ground truth"),
    (
        "evaluate-json-dir",
        ["evaluate", "{dir}", "--session", "{session}", "--json", "{dir}"],
        "is a folder",
    ),
    (
        "evaluate-json-no-parent",
        ["evaluate", "{dir}", "--session", "{session}", "--json", "{missing}/m.json"],
        "does not exist",
    ),
    (
        "evaluate-json-below-file",
        ["evaluate", "{dir}", "--session", "{session}", "--json", "{file}/m.json"],
        "does not exist",
    ),
    (
        "evaluate-json-empty",
        ["evaluate", "{dir}", "--session", "{session}", "--json", ""],
        "empty path",
    ),
    ("evaluate-corrupt-joints", ["evaluate", "{result}", "--session", "{gtsession}"], "joints.npz"),
    ("evaluate-joints-shape", ["evaluate", "{badshape}", "--session", "{gtsession}"], "joints.npz"),
    (
        "evaluate-broken-tum",
        ["evaluate", "{badtum}", "--session", "{gtsession}"],
        "camera_frames.tum",
    ),
    (
        "evaluate-unknown-option",
        ["evaluate", "{dir}", "--session", "{session}", "--csv", "x"],
        "unrecognized",
    ),
]


@pytest.fixture(scope="module")
def places(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    from sessionfactory import make_tiny_session

    root = tmp_path_factory.mktemp("fuzz_cli")
    (root / "file.txt").write_text("not a session\n")
    (root / "empty").mkdir()
    (root / "nonempty").mkdir()
    (root / "nonempty" / "keep.txt").write_text("x\n")
    (root / "bad.yaml").write_text("gait: [speed\n")
    result = root / "result"
    result.mkdir()
    (result / "joints.npz").write_bytes(b"PK\x03\x04 not really a zip")
    badshape = root / "badshape"
    badshape.mkdir()
    np.savez(badshape / "joints.npz", t_ns=np.arange(3), positions=np.zeros((3, 3)))
    badtum = root / "badtum"
    badtum.mkdir()
    (badtum / "camera_frames.tum").write_text("0 1 2 3\nnot numbers\n")
    gtsession = root / "gtsession"
    (gtsession / "groundtruth").mkdir(parents=True)
    return {
        "session": str(make_tiny_session(root / "session")),
        "file": str(root / "file.txt"),
        "dir": str(root / "empty"),
        "nonempty": str(root / "nonempty"),
        "missing": str(root / "missing"),
        "badyaml": str(root / "bad.yaml"),
        "result": str(result),
        "badshape": str(badshape),
        "badtum": str(badtum),
        "gtsession": str(gtsession),
    }


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        rc = main(argv)
    except SystemExit as exc:  # main must not exit; record it so the assertion says so
        rc = -1000 if exc.code is None else exc.code  # type: ignore[assignment]
    out, err = capsys.readouterr()
    return int(rc), out, err


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_arguments_exit_1_with_one_line(
    argv: list[str],
    expected: str,
    places: dict[str, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    fill = {**places, "tmp": str(tmp_path)}
    argv = [a.format(**fill) for a in argv]
    started = time.perf_counter()
    rc, out, err = run_main(argv, capsys)
    line = assert_one_line_exit(err, rc, ": error: ", expected.format(**fill))
    assert line.startswith("gaitnet"), line
    assert out == ""
    assert not (tmp_path / "out").exists() and not any(tmp_path.iterdir())  # nothing written
    assert time.perf_counter() - started < 10, "refused too late (did it start simulating?)"


def test_every_subcommand_is_fuzzed() -> None:
    sub = next(a for a in cli.build_parser()._actions if a.dest == "command")
    fuzzed = {c[1][0] for c in CASES if c[1] and not c[1][0].startswith("-")}
    assert set(sub.choices) <= fuzzed, set(sub.choices) - fuzzed


def test_help_and_version_exit_0(capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["--help"], ["--version"], ["simulate", "--help"]):
        rc, out, err = run_main(argv, capsys)
        assert rc == 0 and out and not err, argv


def test_unexpected_exception_is_a_bug_exit_2_with_traceback(
    monkeypatch: pytest.MonkeyPatch, places: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    def boom(args: object) -> int:
        raise RuntimeError("boom")

    monkeypatch.setattr(cli, "_cmd_check", boom)
    rc, _, err = run_main(["check", places["session"]], capsys)
    assert rc == 2
    assert "Traceback" in err and "RuntimeError: boom" in err
    last = err.splitlines()[-1]
    assert last.startswith("gaitnet check: internal error") and "bug in gaitnet" in last


@pytest.mark.parametrize(
    "error",
    [
        PermissionError(13, "Permission denied", "/data/walk.bag"),
        IsADirectoryError(21, "Is a directory", "/data/out.json"),
        OSError(28, "No space left on device", "/data/out/color/1.png"),
        FileNotFoundError(2, "No such file or directory", "/data/a", "/data/b"),
    ],
    ids=["permission", "is-a-directory", "disk-full", "rename"],
)
def test_os_error_on_a_user_path_is_exit_1_one_line(
    error: OSError,
    monkeypatch: pytest.MonkeyPatch,
    places: dict[str, str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    def fail(args: object) -> int:
        raise error

    monkeypatch.setattr(cli, "_cmd_check", fail)
    rc, _, err = run_main(["check", places["session"]], capsys)
    line = assert_one_line_exit(err, rc, error.strerror)
    assert line.startswith(f"gaitnet check: error: {error.filename}") and "Errno" not in line


def test_interrupts(
    monkeypatch: pytest.MonkeyPatch, places: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C → 130; SIGTERM arrives as KeyboardInterrupt (cleanup runs) → 143; the previous
    SIGTERM handler is restored afterwards."""
    before = signal.getsignal(signal.SIGTERM)
    cleaned: list[str] = []

    def ctrl_c(args: object) -> int:
        raise KeyboardInterrupt

    def killed(args: object) -> int:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the handler interrupts this
            return 0
        except KeyboardInterrupt:
            cleaned.append("staging removed")
            raise

    monkeypatch.setattr(cli, "_cmd_check", ctrl_c)
    rc, _, err = run_main(["check", places["session"]], capsys)
    assert rc == 130 and err.strip() == "gaitnet check: interrupted"
    monkeypatch.setattr(cli, "_cmd_check", killed)
    started = time.perf_counter()
    rc, _, err = run_main(["check", places["session"]], capsys)
    assert rc == 143 and err.strip() == "gaitnet check: terminated"
    assert cleaned == ["staging removed"] and time.perf_counter() - started < 4
    assert signal.getsignal(signal.SIGTERM) is before
