"""Stride matching and the stride keys of ``gaitnet evaluate`` (gaitnet/evaluation/strides.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.evaluation.strides import match_strides, read_strides, stride_metrics

GT_HEADER = "side,stride,from_flat_start_s,to_flat_start_s,heel_strike_s,stride_length_m\n"
EST_HEADER = "side,start_s,end_s,stride_length_m,stride_time_s\n"


def _reference(n: int = 5) -> list[tuple[str, float, float, float]]:
    rows = []
    for k in range(n):
        rows.append(("left", 1.0 + k, 2.0 + k, 1.2 + 0.01 * k))
        rows.append(("right", 1.5 + k, 2.5 + k, 1.25 - 0.01 * k))
    return rows


def _write_gt(path: Path, rows) -> Path:
    lines = [
        f"{s},{i},{a:.6f},{b:.6f},{b - 0.08:.6f},{L:.6f}\n" for i, (s, a, b, L) in enumerate(rows)
    ]
    path.write_text(GT_HEADER + "".join(lines))
    return path


def _write_est(path: Path, rows) -> Path:
    path.write_text(EST_HEADER + "".join(f"{s},{a},{b},{L},{b - a}\n" for s, a, b, L in rows))
    return path


def test_rmse_and_max_error_equal_an_independent_computation(tmp_path: Path) -> None:
    ref = _reference()
    rng = np.random.default_rng(3)
    err = rng.normal(0, 0.02, len(ref))
    shift = rng.uniform(-0.1, 0.1, (len(ref), 2))  # stance seen a little after/before the flat
    est = [
        (s, a + da, b + db, L + e)
        for (s, a, b, L), e, (da, db) in zip(ref, err, shift, strict=True)
    ]
    metrics, counts = stride_metrics(
        read_strides(_write_est(tmp_path / "e.csv", est), InputError),
        read_strides(_write_gt(tmp_path / "g.csv", ref), SessionError),
    )
    left = err[0::2]
    right = err[1::2]
    assert metrics["n_strides"] == {"left": 5, "right": 5}
    assert metrics["stride_rmse_m"]["left"] == pytest.approx(np.sqrt(np.mean(left**2)), abs=1e-6)
    assert metrics["stride_rmse_m"]["right"] == pytest.approx(np.sqrt(np.mean(right**2)), abs=1e-6)
    assert metrics["stride_rmse_m"]["all"] == pytest.approx(np.sqrt(np.mean(err**2)), abs=1e-6)
    assert metrics["stride_max_err_m"]["left"] == pytest.approx(np.max(np.abs(left)), abs=1e-6)
    assert all(v == 0 for v in counts.values())


def test_missed_and_extra_strides_are_counted_not_dropped(tmp_path: Path) -> None:
    ref = _reference()
    est = [r for r in ref if not (r[0] == "left" and r[1] == 3.0)]  # one left stride missed
    est.append(("right", 20.0, 21.0, 1.0))  # one invented
    est.append(("left", 1.0, 2.0, 9.0))  # a duplicate of a matched one: only one may match
    metrics, counts = stride_metrics(
        read_strides(_write_est(tmp_path / "e.csv", est), InputError),
        read_strides(_write_gt(tmp_path / "g.csv", ref), SessionError),
    )
    assert metrics["n_strides"] == {"left": 4, "right": 5}
    assert counts["strides_unmatched_groundtruth_left"] == 1
    assert counts["strides_unmatched_estimate_left"] == 1
    assert counts["strides_unmatched_estimate_right"] == 1
    assert metrics["stride_max_err_m"]["left"] < 1e-9  # the exact copy matched, not the 9 m one


def test_sides_never_match_each_other_and_tolerance_acts(tmp_path: Path) -> None:
    ref = [("left", 1.0, 2.0, 1.2)]
    est_rows = read_strides(_write_est(tmp_path / "e.csv", [("right", 1.0, 2.0, 1.2)]), InputError)
    ref_rows = read_strides(_write_gt(tmp_path / "g.csv", ref), SessionError)
    assert match_strides(est_rows, ref_rows).pairs == {"left": [], "right": []}
    late = read_strides(_write_est(tmp_path / "l.csv", [("left", 1.2, 2.2, 1.2)]), InputError)
    assert match_strides(late, ref_rows, tolerance_s=0.25).pairs["left"] == [(0, 0)]
    assert match_strides(late, ref_rows, tolerance_s=0.1).pairs["left"] == []


@pytest.mark.parametrize(
    "body, message",
    [
        ("side,start_s\nleft,1\n", "needs columns"),
        (EST_HEADER + "middle,1,2,1.2,1\n", "side must be left or right"),
        (EST_HEADER + "left,1,2,nan,1\n", "not finite"),
        (EST_HEADER + "left,1,2,abc,1\n", "not a number"),
        (EST_HEADER + "left,2,1,1.2,1\n", "ends before it starts"),
    ],
)
def test_broken_strides_files_are_one_line_errors(tmp_path: Path, body: str, message: str) -> None:
    path = tmp_path / "strides.csv"
    path.write_text(body)
    with pytest.raises(InputError, match=message) as info:
        read_strides(path, InputError)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_evaluate_reports_the_contract_stride_keys(tmp_path: Path) -> None:
    session = tmp_path / "session"
    (session / "groundtruth").mkdir(parents=True)
    ref = _reference(3)
    _write_gt(session / "groundtruth" / "strides.csv", ref)
    result = tmp_path / "result"
    result.mkdir()
    _write_est(result / "strides.csv", [(s, a, b, L + 0.01) for s, a, b, L in ref])
    report = json.loads(evaluate_result(result, session).to_json())
    assert report["stride_rmse_m"] == pytest.approx({"left": 0.01, "right": 0.01, "all": 0.01})
    assert report["n_strides"] == {"left": 3, "right": 3}
    (session / "groundtruth" / "strides.csv").unlink()
    with pytest.raises(SessionError, match="strides file not found"):
        evaluate_result(result, session)


def test_evaluate_prints_how_many_true_strides_the_rmse_covers(tmp_path: Path, capsys) -> None:
    """One right stride missed and one found that matches none: the printed summary says
    "right 2 of 3" next to the RMSE over the two."""
    from gaitnet.cli import main

    session = tmp_path / "session"
    (session / "groundtruth").mkdir(parents=True)
    ref = _reference(3)
    _write_gt(session / "groundtruth" / "strides.csv", ref)
    est = [r for r in ref if not (r[0] == "right" and r is ref[-1])]
    est.append(("right", 50.0, 51.0, 1.3))  # a stride at times the walk has none
    result = tmp_path / "result"
    result.mkdir()
    _write_est(result / "strides.csv", est)
    assert main(["evaluate", str(result), "--session", str(session)]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("n_strides"))
    left = sum(r[0] == "left" for r in ref)
    assert f"left {left} of {left}" in line and "right 2 of 3" in line
    assert "found but unmatched: left 0, right 1" in line
