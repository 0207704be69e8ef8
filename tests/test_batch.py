"""``gaitnet batch`` (gaitnet.batch): sessions are found and named from their paths, bad input is
one line, two good sessions and a broken one give the good ones' cohort rows (their own
summary.json values) and name the broken one with exit 1, a rerun skips what is complete, an
interrupt keeps what is finished and removes what is not, a dead worker fails only its session,
and ``--ray local`` writes the same cohort as local workers."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from oneline import assert_one_line_exit

import gaitnet.batch.local as local
import gaitnet.batch.run as batch_run_module
from gaitnet.batch.cohort import PARAMETERS, cohort_csv, cohort_rows
from gaitnet.batch.cohort_html import render_cohort
from gaitnet.batch.local import DIED, run_local
from gaitnet.batch.sessions import find_sessions
from gaitnet.batch.task import SessionTask, thread_settings
from gaitnet.cli import main
from gaitnet.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
#: what the sessions run with: the two keys make them quicker, and show that overrides act
OVERRIDES = ["pipeline.segmented_stances=false", "vio.smoother.enabled=false"]
#: the files of a ``gaitnet infer`` folder (gaitnet/pipeline/outputs.py, infer_folder.py)
INFER_FILES = {
    "joints.npz", "joints.csv", "feet.csv", "foot_left.tum", "foot_right.tum",
    "camera_frames.tum", "pelvis_frames.tum", "strides.csv", "gait_strides.csv", "gait.c3d",
    "report.html", "foot_trajectories.png", "top_view.png", "joint_angles.png",
    "gait_phases.png", "summary.json", "infer_config.yaml",
}  # fmt: skip


def _main(args: list[str]) -> tuple[int, str, str]:
    """``gaitnet ARGS`` in this process: (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(args)
    return code, out.getvalue(), err.getvalue()


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _fake_session(folder: Path) -> Path:
    """A folder that discovery takes for a session (it opens nothing)."""
    folder.mkdir(parents=True)
    (folder / "session.yaml").write_text("format_version: 1\n")
    return folder


@pytest.fixture(scope="module")
def cohort_root(tmp_path_factory, tiny_sim_session: Path) -> Path:
    """Two good sessions (the tiny simulated one twice) and a broken .bag, in subject folders."""
    root = tmp_path_factory.mktemp("cohort")
    for subject in ("s01", "s02"):
        shutil.copytree(tiny_sim_session, root / subject / "walk1")
    (root / "s03").mkdir()
    (root / "s03" / "broken.bag").write_bytes(b"not a bag")
    return root


@pytest.fixture(scope="module")
def batch(tmp_path_factory, cohort_root: Path) -> SimpleNamespace:
    """One local batch over :func:`cohort_root` with 2 workers on (what it takes for) 2 CPUs."""
    out = tmp_path_factory.mktemp("batch") / "out"
    pools: list[int] = []
    real = local.ProcessPoolExecutor

    def spy(max_workers: int, mp_context):
        pools.append(max_workers)
        return real(max_workers=max_workers, mp_context=mp_context)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(batch_run_module, "usable_cores", lambda: 2)
        mp.setattr(local, "ProcessPoolExecutor", spy)
        code, stdout, stderr = _main(
            ["batch", str(cohort_root), "--out", str(out), "--workers", "2", *OVERRIDES]
        )
    return SimpleNamespace(out=out, code=code, stdout=stdout, stderr=stderr, pools=pools)


def test_good_sessions_are_written_and_the_broken_one_is_named(
    batch: SimpleNamespace, cohort_root: Path
) -> None:
    assert batch.code == 1, batch.stderr
    errors = [line for line in batch.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1 and errors[0].startswith("gaitnet batch: error: 1 of 3 session(s)")
    assert "s03__broken" in errors[0] and "failures.csv" in errors[0]
    failures = _csv(batch.out / "failures.csv")
    assert [f["session"] for f in failures] == ["s03__broken"]
    assert failures[0]["path"] == str(cohort_root / "s03" / "broken.bag")
    assert "broken.bag" in failures[0]["error"] and "\n" not in failures[0]["error"]
    entries = sorted(p.name for p in batch.out.iterdir())
    assert entries == ["cohort.csv", "cohort.html", "failures.csv", "s01__walk1", "s02__walk1"]
    for name in ("s01__walk1", "s02__walk1"):  # the files of gaitnet infer, nothing half-written
        assert {p.name for p in (batch.out / name).iterdir()} == INFER_FILES
    assert "2 written, 0 skipped (complete already), 1 failed" in batch.stdout


def test_cohort_rows_are_each_sessions_own_summary(
    batch: SimpleNamespace, cohort_root: Path
) -> None:
    rows = _csv(batch.out / "cohort.csv")
    assert [(r["session"], r["side"]) for r in rows] == [
        ("s01__walk1", "left"), ("s01__walk1", "right"),
        ("s02__walk1", "left"), ("s02__walk1", "right"),
    ]  # fmt: skip
    for row in rows:
        summary = json.loads((batch.out / row["session"] / "summary.json").read_text())
        subject = row["session"].split("__")[0]
        assert row["path"] == summary["session"]["path"] == str(cohort_root / subject / "walk1")
        stats = summary["gait"][row["side"]]
        assert int(row["n_strides"]) == stats["n_strides"]
        assert int(row["n_strides_inferred"]) == stats["n_inferred"]
        assert row["reliable"] == str(summary["reliable"]).lower()
        for column, (key, _) in PARAMETERS.items():
            expected = f"{stats[key]['mean']:.6f}" if key in stats else ""
            assert row[column] == expected, column
    page = (batch.out / "cohort.html").read_text()
    assert "s01__walk1" in page and "s02__walk1" in page and "s03__broken" in page
    assert "http" not in page and "<script" not in page


def test_workers_threads_and_overrides_act(batch: SimpleNamespace) -> None:
    """--workers 2 is a pool of 2 processes; on 2 CPUs each session gets 1 thread
    (thread_settings), and the KEY=VALUE overrides are in each session's infer config."""
    assert batch.pools == [2]
    assert thread_settings(2, 2) == (1, 1)
    for name in ("s01__walk1", "s02__walk1"):
        cfg = yaml.safe_load((batch.out / name / "infer_config.yaml").read_text())
        assert (cfg["pipeline"]["workers"], cfg["models"]["threads"]) == (1, 1)
        assert cfg["pipeline"]["segmented_stances"] is False
        assert cfg["vio"]["smoother"]["enabled"] is False
    assert "2 worker processes, each session with 1 segmentation thread(s)" in batch.stdout


def test_a_rerun_skips_the_finished_sessions(
    batch: SimpleNamespace, cohort_root: Path, monkeypatch
) -> None:
    ran: list[list[str]] = []
    real = local.run_local

    def spy(tasks, workers, on_done=None):
        ran.append([t.name for t in tasks])
        return real(tasks, workers, on_done)

    monkeypatch.setattr(local, "run_local", spy)
    before = {n: (batch.out / n / "summary.json").stat().st_mtime_ns for n in ("s01__walk1",)}
    cohort = (batch.out / "cohort.csv").read_bytes()
    code, stdout, _ = _main(["batch", str(cohort_root), "--out", str(batch.out), *OVERRIDES])
    assert code == 1  # the broken session fails again
    assert ran == [["s03__broken"]]
    assert "0 written, 2 skipped (complete already), 1 failed" in stdout
    assert before == {n: (batch.out / n / "summary.json").stat().st_mtime_ns for n in before}
    assert (batch.out / "cohort.csv").read_bytes() == cohort


def test_ray_local_writes_the_same_cohort(
    batch: SimpleNamespace, cohort_root: Path, tmp_path: Path, monkeypatch
) -> None:
    pytest.importorskip("ray")
    monkeypatch.setattr(batch_run_module, "usable_cores", lambda: 2)  # a Ray instance of 2 CPUs
    out = tmp_path / "ray"
    args = ["batch", str(cohort_root), "--out", str(out), "--workers", "2", "--ray", "local"]
    code, stdout, stderr = _main([*args, *OVERRIDES])
    assert code == 1, stderr
    assert "2 Ray tasks (local)" in stdout
    for name in ("cohort.csv", "failures.csv"):
        assert (out / name).read_bytes() == (batch.out / name).read_bytes(), name
    for name in ("s01__walk1", "s02__walk1"):
        config = "infer_config.yaml"
        assert (out / name / config).read_bytes() == (batch.out / name / config).read_bytes()


def test_an_interrupt_keeps_finished_sessions_and_removes_the_partial_one(
    batch: SimpleNamespace, cohort_root: Path, tmp_path: Path
) -> None:
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) while the second
    session runs: exit 130 and one line; the first stays as it was, the second leaves nothing."""
    out = tmp_path / "out"
    shutil.copytree(batch.out, out)
    shutil.rmtree(out / "s02__walk1")
    kept = (out / "s01__walk1" / "summary.json").stat().st_mtime_ns
    args = ["batch", str(cohort_root), "--out", str(out), "--workers", "1", *OVERRIDES]
    proc = subprocess.Popen(
        [sys.executable, "-m", "gaitnet.cli", *args],
        cwd=ROOT,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        while proc.poll() is None and not any(".partial-" in p.name for p in out.iterdir()):
            time.sleep(0.05)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert stderr.replace("\r", "\n").splitlines()[-1] == "gaitnet batch: interrupted"
    assert sorted(p.name for p in out.iterdir()) == [
        "cohort.csv", "cohort.html", "failures.csv", "s01__walk1"
    ]  # fmt: skip
    assert (out / "s01__walk1" / "summary.json").stat().st_mtime_ns == kept


def test_a_dead_worker_fails_only_its_session(tmp_path: Path, monkeypatch) -> None:
    """The sessions running beside a worker that dies run again, one by one; the one whose
    worker dies alone is the failure."""
    import batchworkers

    monkeypatch.setattr(local, "run_session", batchworkers.crash_or_pass)
    names = ["crash", "ok1", "ok2", "ok3"]
    tasks = [SessionTask(n, n, str(tmp_path / n), None, "test") for n in names]  # type: ignore[arg-type]
    seen: list[str] = []
    outcomes = run_local(tasks, 2, lambda o: seen.append(o.name))
    assert sorted(o.name for o in outcomes) == sorted(seen) == names
    assert {o.name: o.error for o in outcomes} == {
        "crash": DIED, "ok1": None, "ok2": None, "ok3": None
    }  # fmt: skip


def test_sessions_are_found_and_named_from_their_paths(tmp_path: Path) -> None:
    root = tmp_path / "study"
    walk1 = _fake_session(root / "s01" / "visit1" / "walk1")
    _fake_session(walk1 / "inside")  # not searched: inside a session
    (root / "s01" / "visit2").mkdir(parents=True)
    (root / "s01" / "visit2" / "walk.bag").write_bytes(b"")
    (root / "s02").mkdir()
    (root / "s02" / "WALK.BAG").write_bytes(b"")
    (root / "s02" / "notes.txt").write_text("not a session")
    (root / "s02" / "loop").symlink_to(root)  # searched once
    _fake_session(root / ".trash" / "old")  # hidden
    _fake_session(root / "results" / "old")  # the output folder
    found = find_sessions([root], root / "results")
    assert [(s.name, s.path) for s in found] == [
        ("s01__visit1__walk1", walk1.absolute()),
        ("s01__visit2__walk", (root / "s01" / "visit2" / "walk.bag").absolute()),
        ("s02__WALK", (root / "s02" / "WALK.BAG").absolute()),
    ]
    direct = find_sessions([root / "s01" / "visit2" / "walk.bag", walk1], tmp_path / "out")
    assert [s.name for s in direct] == ["walk", "walk1"]
    assert len(find_sessions([root, walk1], root / "results")) == 3  # the same session once


@pytest.mark.parametrize(
    "case, fragments",
    [
        ("empty", ["empty", "no session found"]),
        ("missing", ["missing", "no such session folder"]),
        ("inside", ["lies inside the session", "walk1"]),
        ("same-name", ["a/walk1", "b/walk1", "would both be written to"]),
        ("text-file", ["notes.txt", "not a session folder"]),
        ("workers", ["--workers must be within 1–1024, got 0"]),
        ("key", ["pipeline.nokey"]),
    ],
)
def test_bad_input_is_one_line(tmp_path: Path, case: str, fragments: list[str], capsys) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.txt").write_text("")
    a, b = _fake_session(tmp_path / "a" / "walk1"), _fake_session(tmp_path / "b" / "walk1")
    out = tmp_path / "out"
    args = {
        "empty": [str(tmp_path / "empty")],
        "missing": [str(tmp_path / "missing")],
        "inside": [str(a), "--out", str(a / "results")],
        "same-name": [str(a), str(b)],
        "text-file": [str(tmp_path / "notes.txt")],
        "workers": [str(a), "--workers", "0"],
        "key": [str(a), "pipeline.nokey=1"],
    }[case]
    if "--out" not in args:
        args += ["--out", str(out)]
    assert_one_line_exit(capsys, main(["batch", *args]), "gaitnet batch: error:", *fragments)
    assert not out.exists() and not (a / "results").exists()


def test_an_unreachable_ray_address_is_one_line_at_once(tmp_path: Path, capsys) -> None:
    with socket.socket() as s:  # a port nothing listens at once it is closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    session = _fake_session(tmp_path / "walk1")
    args = ["batch", str(session), "--out", str(tmp_path / "out"), "--ray", f"127.0.0.1:{port}"]
    assert_one_line_exit(capsys, main(args), f"--ray 127.0.0.1:{port}: no Ray cluster answers")
    assert_one_line_exit(capsys, main([*args[:-1], "nohost"]), "expected HOST:PORT")
    assert not (tmp_path / "out").exists()


def test_ray_missing_is_one_line(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails
    session = _fake_session(tmp_path / "walk1")
    args = ["batch", str(session), "--out", str(tmp_path / "out"), "--ray", "local"]
    assert_one_line_exit(capsys, main(args), "ray is not installed", "pip install -e '.[cluster]'")


def test_thread_settings_keep_workers_times_threads_within_the_cores() -> None:
    assert thread_settings(2, 1) == (2, 1)  # gaitnet infer's own: 2 segmentation threads
    assert thread_settings(2, 2) == (1, 1)
    assert thread_settings(16, 4) == (2, 2)
    assert thread_settings(16, 1) == (2, 8)
    assert thread_settings(8, 3) == (2, 1)
    assert thread_settings(1, 4) == (1, 1)  # more workers than cores: one thread each


def test_cohort_table_from_known_summaries(tmp_path: Path) -> None:
    gait = {
        "left": {
            "n_strides": 3,
            "n_inferred": 1,
            "stride_length_m": {"mean": 1.25, "sd": 0.1, "n": 3},
            "cadence_spm": {"mean": 110.0, "sd": 1.0, "n": 3},
            "stance_pct": {"mean": 61.5, "sd": 1.0, "n": 2},
        },
        "right": {"n_strides": 0},
    }
    for name, reliable in (("a", True), ("b", False)):
        (tmp_path / name).mkdir()
        summary = {"reliable": reliable, "session": {"path": f"/data/{name}"}, "gait": gait}
        (tmp_path / name / "summary.json").write_text(json.dumps(summary))
    rows = cohort_rows(tmp_path, ["b", "a"])
    assert cohort_csv(rows).splitlines() == [
        "session,path,side,n_strides,n_strides_inferred,stride_length_m,cadence_steps_per_min,"
        "walking_speed_mps,stance_pct,double_support_pct,reliable",
        "b,/data/b,left,3,1,1.250000,110.000000,,61.500000,,false",
        "b,/data/b,right,0,0,,,,,,false",
        "a,/data/a,left,3,1,1.250000,110.000000,,61.500000,,true",
        "a,/data/a,right,0,0,,,,,,true",
    ]
    page = render_cohort(rows, [])
    assert page.count("data:image/png;base64,") == 3  # the parameters with a value
    (tmp_path / "a" / "summary.json").write_text("{")
    with pytest.raises(InputError, match="not a gaitnet infer summary"):
        cohort_rows(tmp_path, ["a"])
