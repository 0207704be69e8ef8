"""Stride-length errors: estimated strides matched to ground-truth strides in time.

A stride joins two consecutive stances of the same foot (docs/ecosystem.md). Both files are
CSV tables with a ``side`` column (``left``/``right``), ``stride_length_m`` and the times of the
two stances the stride joins, in seconds on the session clock:

- a result's ``strides.csv`` (``gaitnet vio``): ``start_s`` and ``end_s``, the times
  each of the two stances was confirmed (a few frames after the foot was first seen there);
- the simulator's ``groundtruth/strides.csv``: ``from_flat_start_s`` and ``to_flat_start_s``,
  the starts of the two foot-flat intervals (docs/groundtruth.md).

Matching (:func:`match_strides`): per side, each estimated stride is paired with the
ground-truth stride whose start and end times are both within ``tolerance_s`` of its own,
closest first (by the larger of the two time differences); each stride is used once. What is
left unmatched on either side is counted and reported, never silently dropped.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitnet.errors import GaitnetError

__all__ = ["SIDES", "StrideMatch", "StrideRows", "match_strides", "read_strides", "stride_metrics"]

SIDES = ("left", "right")
_TIME_COLUMNS = (("start_s", "end_s"), ("from_flat_start_s", "to_flat_start_s"))
DEFAULT_TOLERANCE_S = 0.25
"""Largest time difference between matched stances: a quarter of a typical 1 s stride, so a
stance cannot be mistaken for the neighbouring one of the same foot."""


@dataclass(frozen=True)
class StrideRows:
    """Strides of one file: ``side`` (n,) str, ``start_s``, ``end_s``, ``length_m`` (n,)."""

    side: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    length_m: np.ndarray

    def __len__(self) -> int:
        return int(self.side.shape[0])


def _number(path: Path, line: int, column: str, text: str, error: type[GaitnetError]) -> float:
    try:
        value = float(text)
    except ValueError:
        raise error(f"{path}: line {line}: {column} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise error(f"{path}: line {line}: {column} is not finite")
    return value


def read_strides(path: str | Path, error: type[GaitnetError]) -> StrideRows:
    """Read a strides table (module docstring), every value checked; ``error`` names ``path``."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: strides file not found")
    try:
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            header = reader.fieldnames or []
            names = next((c for c in _TIME_COLUMNS if set(c) <= set(header)), None)
            if names is None or not {"side", "stride_length_m"} <= set(header):
                raise error(
                    f"{path}: needs columns side, stride_length_m and start_s, end_s "
                    f"(or from_flat_start_s, to_flat_start_s); has {header}"
                )
            rows = list(reader)
    except UnicodeDecodeError:
        raise error(f"{path}: not UTF-8 text") from None
    except csv.Error as exc:
        raise error(f"{path}: not a CSV table ({exc})") from None
    side, start, end, length = [], [], [], []
    for line, row in enumerate(rows, start=2):
        if row.get("side") not in SIDES:
            raise error(f"{path}: line {line}: side must be left or right, got {row.get('side')!r}")
        side.append(row["side"])
        start.append(_number(path, line, names[0], row[names[0]] or "", error))
        end.append(_number(path, line, names[1], row[names[1]] or "", error))
        length.append(_number(path, line, "stride_length_m", row["stride_length_m"] or "", error))
        if end[-1] <= start[-1]:
            raise error(f"{path}: line {line}: the stride ends before it starts")
    return StrideRows(
        np.array(side, dtype=str), np.array(start), np.array(end), np.array(length, dtype=float)
    )


@dataclass(frozen=True)
class StrideMatch:
    """Matched pairs per side: indices into the estimate and the reference, and the counts
    of strides left unmatched in each."""

    pairs: dict[str, list[tuple[int, int]]]
    unmatched_estimate: dict[str, int]
    unmatched_reference: dict[str, int]


def match_strides(
    est: StrideRows, ref: StrideRows, tolerance_s: float = DEFAULT_TOLERANCE_S
) -> StrideMatch:
    """Pair estimated and reference strides of the same side by time (module docstring)."""
    pairs: dict[str, list[tuple[int, int]]] = {}
    left_est: dict[str, int] = {}
    left_ref: dict[str, int] = {}
    for side in SIDES:
        ie = np.flatnonzero(est.side == side)
        ir = np.flatnonzero(ref.side == side)
        cost = np.maximum(
            np.abs(est.start_s[ie, None] - ref.start_s[None, ir]),
            np.abs(est.end_s[ie, None] - ref.end_s[None, ir]),
        )
        found: list[tuple[int, int]] = []
        used_e: set[int] = set()
        used_r: set[int] = set()
        for flat in np.argsort(cost, axis=None, kind="stable"):
            a, b = np.unravel_index(flat, cost.shape)
            if cost[a, b] > tolerance_s:
                break
            if a in used_e or b in used_r:
                continue
            used_e.add(int(a))
            used_r.add(int(b))
            found.append((int(ie[a]), int(ir[b])))
        pairs[side] = sorted(found)
        left_est[side] = len(ie) - len(found)
        left_ref[side] = len(ir) - len(found)
    return StrideMatch(pairs, left_est, left_ref)


def stride_metrics(
    est: StrideRows, ref: StrideRows, tolerance_s: float = DEFAULT_TOLERANCE_S
) -> tuple[dict[str, object], dict[str, int]]:
    """The contract keys ``stride_rmse_m`` {left, right, all}, ``stride_max_err_m`` {left,
    right} and ``n_strides`` {left, right} (matched strides), plus counts of the unmatched
    ones. A side with no matched stride has no RMSE or maximum (the key is left out)."""
    match = match_strides(est, ref, tolerance_s)
    rmse: dict[str, float] = {}
    worst: dict[str, float] = {}
    every: list[float] = []
    for side in SIDES:
        err = [est.length_m[i] - ref.length_m[j] for i, j in match.pairs[side]]
        every += err
        if err:
            rmse[side] = float(np.sqrt(np.mean(np.square(err))))
            worst[side] = float(np.max(np.abs(err)))
    if every:
        rmse["all"] = float(np.sqrt(np.mean(np.square(every))))
    metrics: dict[str, object] = {
        "n_strides": {side: len(match.pairs[side]) for side in SIDES},
    }
    if rmse:
        metrics["stride_rmse_m"] = rmse
        metrics["stride_max_err_m"] = worst
    counts = {
        **{f"strides_unmatched_estimate_{s}": match.unmatched_estimate[s] for s in SIDES},
        **{f"strides_unmatched_groundtruth_{s}": match.unmatched_reference[s] for s in SIDES},
    }
    return metrics, counts
