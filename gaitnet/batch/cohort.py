"""The cohort table (``cohort.csv``) and the failure list (``failures.csv``) of a batch
(docs/batch.md, *The cohort table*).

``cohort.csv`` has one row per session and side, read from each result folder's own
``summary.json`` (the gait summary ``gaitnet infer`` wrote: the mean over the side's steady
strides, :func:`gaitnet.pipeline.gait_parameters.summarise`), never computed again. Columns are
named with their units, as mobgap names its parameters; an empty cell is a parameter no steady
stride of that side has; ``n_strides_inferred`` counts the steady strides through a stance
laid from the step rhythm (``inferred`` in the session's ``gait_strides.csv``). Both files are
written atomically.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from gaitnet.batch.task import COMPLETE_FILE, SessionOutcome
from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.csv_text import csv_text

__all__ = [
    "COHORT_COLUMNS",
    "FAILURE_COLUMNS",
    "PARAMETERS",
    "CohortRow",
    "cohort_csv",
    "cohort_rows",
    "write_failures",
]

SIDES = ("left", "right")

#: cohort column → (key of the gait summary in ``summary.json``, display unit)
PARAMETERS: dict[str, tuple[str, str]] = {
    "stride_length_m": ("stride_length_m", "m"),
    "cadence_steps_per_min": ("cadence_spm", "steps/min"),
    "walking_speed_mps": ("walking_speed_mps", "m/s"),
    "stance_pct": ("stance_pct", "% of gait cycle"),
    "double_support_pct": ("double_support_pct", "% of gait cycle"),
}
COHORT_COLUMNS = (
    "session", "path", "side", "n_strides", "n_strides_inferred", *PARAMETERS, "reliable",
)  # fmt: skip
FAILURE_COLUMNS = ("session", "path", "error")


@dataclass(frozen=True)
class CohortRow:
    """One session's side: ``values`` maps each column of :data:`PARAMETERS` to the side's
    mean, or None."""

    session: str
    path: str
    side: str
    n_strides: int
    values: dict[str, float | None]
    reliable: bool
    n_inferred: int = 0

    def cells(self) -> list[str]:
        """The row as CSV cells (:data:`COHORT_COLUMNS`)."""
        numbers = ["" if v is None else f"{v:.6f}" for v in self.values.values()]
        return [
            self.session,
            self.path,
            self.side,
            str(self.n_strides),
            str(self.n_inferred),
            *numbers,
            "true" if self.reliable else "false",
        ]


def _read_summary(path: Path) -> dict:
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a gaitnet infer summary ({exc})") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("gait"), dict):
        raise InputError(f"{path}: not a gaitnet infer summary (no 'gait' object)")
    return summary


def _mean(stats: object, key: str) -> float | None:
    value = stats.get(key) if isinstance(stats, dict) else None
    mean = value.get("mean") if isinstance(value, dict) else None
    return float(mean) if isinstance(mean, (int, float)) else None


def cohort_rows(out: Path, names: Sequence[str]) -> list[CohortRow]:
    """The rows of the result folders ``out/<name>`` (each complete), in the order given."""
    rows = []
    for name in names:
        summary = _read_summary(Path(out) / name / COMPLETE_FILE)
        session = summary.get("session")
        path = str(session.get("path", "")) if isinstance(session, dict) else ""
        for side in SIDES:
            stats = summary["gait"].get(side, {})
            counts = [
                int(stats.get(key, 0)) if isinstance(stats, dict) else 0
                for key in ("n_strides", "n_inferred")
            ]
            values = {col: _mean(stats, key) for col, (key, _) in PARAMETERS.items()}
            reliable = summary.get("reliable") is True
            rows.append(CohortRow(name, path, side, counts[0], values, reliable, counts[1]))
    return rows


def cohort_csv(rows: Sequence[CohortRow]) -> str:
    """``cohort.csv``'s text."""
    return csv_text(COHORT_COLUMNS, [r.cells() for r in rows])


def write_failures(path: Path, failed: Sequence[SessionOutcome]) -> None:
    """Write ``failures.csv``: the sessions of this run that failed, with their one-line error
    (only the header when none did)."""
    rows = [[o.name, o.session, o.error or ""] for o in failed]
    atomic_write_text(path, csv_text(FAILURE_COLUMNS, rows))
