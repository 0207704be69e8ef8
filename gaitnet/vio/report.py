"""Writing a ``gaitnet vio`` result folder (docs/vio.md, *Outputs*).

Files, all written into a staging folder that appears at the output path only when complete
(:func:`gaitnet.io.atomic.staged_folder`):

- ``camera_frames.tum``: the smoothed colour-camera trajectory (the filter's when the smoother
  is off), TUM, world-from-camera — the file ``gaitnet evaluate`` reads for ``body_ate_m``;
- ``filter_frames.tum``: the filter's colour-camera trajectory; ``imu_only_frames.tum``: the
  IMU-only dead-reckoning baseline;
- ``stance_feet.csv``: one row per stance-foot landmark;
- ``strides.csv``: one row per stride (:data:`gaitnet.vio.gait.STRIDE_COLUMNS`);
- ``summary.json``: ``reliable`` (false with ``unreliable_reasons`` when a session that failed
  the scene check ran with ``--force``), gait summary per side, walking speed, distance,
  measurements used and skipped with reasons, initialisation, timings;
- ``trajectory.png``: top view of the trajectory and the stance feet (left red, right green,
  the usual gait-lab colours; docs/ecosystem.md);
- ``vio_config.yaml``: the resolved config.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from gaitnet.io.atomic import staged_folder
from gaitnet.io.trajectory import tum_text
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.gait import STRIDE_COLUMNS, summarise
from gaitnet.vio.result import VioResult

__all__ = ["STANCE_COLUMNS", "summary", "write_result"]

STANCE_COLUMNS = (
    "landmark",
    "side",
    "first_s",
    "last_s",
    "x_m",
    "y_m",
    "z_m",
    "std_x_m",
    "std_y_m",
    "n_observations",
)
SIDE_COLOURS = {"left": "#d62728", "right": "#2ca02c"}


def _finite_or_none(value: object) -> object:
    """JSON has no NaN: non-finite floats become null (recursively)."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


#: ``summary.json`` ``scale``: what the lengths' metric scale rests on.
SCALE_FROM_SHEETS = "AprilTag sheets"
SCALE_FROM_DEPTH = (
    "depth alone: no AprilTag sheet was decoded, so lengths carry the depth camera's scale "
    "error (strides 2 % long or short on simulated D455 sessions; lay the AprilTag sheets at "
    "the start and the end of the walk)"
)


def scale_source(result: VioResult) -> str:
    """What the result's metric scale rests on: the sheets when a tag pose initialised or
    updated the filter, else the depth alone (:data:`SCALE_FROM_DEPTH`)."""
    if result.initialisation == "apriltag" or result.used.get("tag", 0) > 0:
        return SCALE_FROM_SHEETS
    return SCALE_FROM_DEPTH


def summary(result: VioResult) -> dict[str, object]:
    """The ``summary.json`` object of a result."""
    p = result.T_WfromC[:, :3, 3]
    steps = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)
    duration = float(result.t_s[-1] - result.t_s[0]) if len(result.t_s) > 1 else 0.0
    gait = summarise(result.strides)
    speeds = [s.speed_mps for s in result.strides if s.steady]
    return _finite_or_none(
        {
            "reliable": not result.unreliable,
            "unreliable_reasons": list(result.unreliable),
            "frames": int(len(result.t_s)),
            "duration_s": duration,
            "distance_m": float(steps.sum()),
            "walking_speed_mps": float(np.mean(speeds)) if speeds else None,
            "n_stance_feet": {
                side: sum(1 for s in result.stance_feet if s.side == side)
                for side in ("left", "right")
            },
            "gait": gait,
            "initialisation": result.initialisation,
            "initialisation_note": result.initialisation_note,
            "scale": scale_source(result),
            "smoothed": result.T_WfromC_smoothed is not None,
            "smoother": result.smoother,
            "gait_filter": summarise(result.strides_filter),
            "measurements_used": dict(sorted(result.used.items())),
            "measurements_skipped": {
                kind: dict(sorted(c.items())) for kind, c in sorted(result.skipped.items())
            },
            "timings_s": result.timings_s,
        }
    )  # type: ignore[return-value]


def _csv_text(columns: tuple[str, ...], rows: list[dict[str, object]]) -> str:
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue()


def _stance_rows(result: VioResult) -> list[dict[str, object]]:
    return [
        {
            "landmark": s.landmark_id,
            "side": s.side,
            "first_s": f"{s.t_first_s:.6f}",
            "last_s": f"{s.t_last_s:.6f}",
            "x_m": f"{s.xy[0]:.6f}",
            "y_m": f"{s.xy[1]:.6f}",
            "z_m": "0.000000",
            "std_x_m": f"{s.std_xy[0]:.6f}",
            "std_y_m": f"{s.std_xy[1]:.6f}",
            "n_observations": s.n_observations,
        }
        for s in sorted(result.stance_feet, key=lambda s: s.t_first_s)
    ]


def plot_trajectory(result: VioResult, path: Path) -> None:
    """Top view (thesis Figs. 5.5/5.6): camera trajectory (smoothed, filter, IMU-only) and
    stance feet with their stride links, left red and right green."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5), dpi=110)
    imu_only = result.T_WfromC_imu_only[:, :3, 3]
    ax.plot(imu_only[:, 0], imu_only[:, 1], color="0.7", lw=1, ls=":", label="IMU only")
    flt = result.T_WfromC_filter[:, :3, 3]
    ax.plot(flt[:, 0], flt[:, 1], color="0.45", lw=1, ls="--", label="filter")
    if result.T_WfromC_smoothed is not None:
        sm = result.T_WfromC_smoothed[:, :3, 3]
        ax.plot(sm[:, 0], sm[:, 1], color="k", lw=1.5, label="smoother")
    for side, colour in SIDE_COLOURS.items():
        feet = sorted((s for s in result.stance_feet if s.side == side), key=lambda s: s.t_first_s)
        if feet:
            xy = np.array([s.xy for s in feet])
            ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=0.8, alpha=0.5)
            ax.scatter(
                xy[:, 0], xy[:, 1], color=colour, s=28, zorder=3, label=f"{side} stance feet"
            )
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("camera trajectory and stance feet (top view)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_result(
    result: VioResult, out_dir: str | Path, config_text: str, overwrite: bool = False
) -> Path:
    """Write every output file of ``result`` (module docstring) to ``out_dir`` atomically.
    A non-finite pose or stance position is a :class:`FilterDivergedError` and nothing is
    written: an output never holds a NaN."""
    arrays = [result.T_WfromC, result.T_WfromC_filter, result.T_WfromC_imu_only]
    arrays += [s.xy for s in result.stance_feet]
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise FilterDivergedError("the trajectory or a stance foot is not finite; nothing written")
    with staged_folder(out_dir, overwrite) as stage:
        t = result.t_s
        (stage / "camera_frames.tum").write_text(
            tum_text(t, result.T_WfromC, "camera (colour) poses, world from camera")
        )
        (stage / "filter_frames.tum").write_text(
            tum_text(t, result.T_WfromC_filter, "filter camera poses, world from camera")
        )
        (stage / "imu_only_frames.tum").write_text(
            tum_text(t, result.T_WfromC_imu_only, "IMU-only dead reckoning, world from camera")
        )
        (stage / "stance_feet.csv").write_text(_csv_text(STANCE_COLUMNS, _stance_rows(result)))
        (stage / "strides.csv").write_text(
            _csv_text(STRIDE_COLUMNS, [s.row() for s in result.strides])
        )
        (stage / "summary.json").write_text(json.dumps(summary(result), indent=2) + "\n")
        (stage / "vio_config.yaml").write_text(config_text)
        plot_trajectory(result, stage / "trajectory.png")
    return Path(out_dir)
