"""The files of a ``gaitnet infer`` result folder (docs/pipeline.md, *Outputs*).

- ``joints.npz``: ``t_ns`` (n,), ``positions`` (n, 9, 3) world positions of SMPL joints
  ``smpl_indices`` [0, 1, 2, 4, 5, 7, 8, 10, 11] (``joint_names``; the layout of a simulated
  session's ``groundtruth/joints.npz``, which ``gaitnet evaluate`` reads), ``poses`` (n, 21)
  the corrected poses in the predictor's node layout, ``trans`` (n, 3) the SMPL translation,
  ``angles_deg`` (n, 6) sagittal joint angles (``angle_names``);
- ``joints.csv``: the same per frame as text (time, joint positions, angles);
- ``feet.csv``: ``t_ns``, ``marker_{left,right}_{x,y,z}`` the gap-free shoe-marker
  trajectories (world), ``measured_{left,right}`` 1 where the segmenter saw the foot (0: filled
  by prediction), ``contact_{left,right}`` the filter's stance flags;
- ``foot_left.tum``, ``foot_right.tum``: the marker trajectories as TUM (identity
  orientation), ``camera_frames.tum`` the smoothed camera, ``pelvis_frames.tum`` the corrected
  pelvis (SMPL joint 0 with the pelvis axes x forward, y left, z up);
- ``strides.csv``: the filter's strides (:data:`gaitnet.vio.gait.STRIDE_COLUMNS`);
- ``gait_strides.csv``: every stride's parameters (docs/report.md: lengths and times from the
  filter's strides, stance / swing / double support from the gait events of the foot
  trajectories);
- ``gait.c3d``: the joint centres and foot points [mm], the Foot Strike / Foot Off events
  and the subject's height, for the tools of a gait lab
  (:mod:`gaitnet.pipeline.c3d_export`);
- ``report.html``: the self-contained gait report (header, time-distance table per side with
  symmetry indices, per-stride table, figures), and the figures as PNG
  (``foot_trajectories.png``, ``top_view.png``, ``joint_angles.png``, ``gait_phases.png``);
- ``summary.json``: ``reliable`` (false with ``unreliable_reasons`` when a session that failed
  the scene check ran with ``--force``; the report's header says so too), session facts,
  models, skeleton, the world frame (``world_frame``: the
  filter's initialisation, ``apriltag`` or ``gravity_floor``, and its note), extrinsic, the
  gait summary, timings.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gaitnet.geometry import so3_exp
from gaitnet.io.csv_text import csv_text
from gaitnet.io.trajectory import tum_text
from gaitnet.motion.skeleton import JOINT_NAMES, SMPL_JOINT_INDICES
from gaitnet.pipeline.c3d_export import write_gait_c3d
from gaitnet.pipeline.gait_events import FootContact, detect_events
from gaitnet.pipeline.gait_parameters import (
    stride_parameters,
    stride_table_csv,
    summarise,
    table_cycles,
)
from gaitnet.pipeline.html_report import write_report
from gaitnet.pipeline.infer import InferResult
from gaitnet.pipeline.joint_angles import ANGLE_NAMES, sagittal_angles_deg
from gaitnet.pipeline.plots import (
    foot_trajectories_png,
    gait_phases_png,
    joint_angles_png,
    top_view_png,
    write_png,
)
from gaitnet.pipeline.pose_types import R_PfromSMPL
from gaitnet.vio.gait import STRIDE_COLUMNS
from gaitnet.vio.report import scale_source

__all__ = ["result_summary", "write_infer_files"]

SIDES = ("left", "right")


def _feet_csv(r: InferResult) -> str:
    cols = ["t_ns"] + [f"marker_{s}_{a}" for s in SIDES for a in "xyz"]
    cols += [f"measured_{s}" for s in SIDES] + [f"contact_{s}" for s in SIDES]
    rows = []
    for k in range(len(r.t_s)):
        row: list[object] = [int(r.t_ns[k])]
        row += [f"{v:.5f}" for v in r.feet_W[k].ravel()]
        row += [int(v) for v in r.foot_measured[k]] + [int(v) for v in r.contact[k]]
        rows.append(row)
    return csv_text(cols, rows)


def _joints_csv(r: InferResult, angles: np.ndarray) -> str:
    cols = ["t_s"] + [f"{name}_{a}" for name in JOINT_NAMES for a in "xyz"] + list(ANGLE_NAMES)
    rows = [
        [f"{r.t_s[k]:.6f}"]
        + [f"{v:.5f}" for v in r.joints_W[k].ravel()]
        + [f"{v:.2f}" for v in angles[k]]
        for k in range(len(r.t_s))
    ]
    return csv_text(cols, rows)


def _pelvis_poses(r: InferResult) -> np.ndarray:
    T = np.tile(np.eye(4), (len(r.t_s), 1, 1))
    T[:, :3, :3] = so3_exp(r.poses[:, :3]) @ R_PfromSMPL.T
    T[:, :3, 3] = r.joints_W[:, 0]
    return T


def _point_poses(p: np.ndarray) -> np.ndarray:
    T = np.tile(np.eye(4), (len(p), 1, 1))
    T[:, :3, 3] = p
    return T


def _world_frame_text(initialisation: str) -> str:
    """What the positions are measured from, for the report's header."""
    if initialisation == "apriltag":
        return "the start AprilTag sheet (positions and heading in the sheet's frame)"
    return "no AprilTag sheet seen: the camera's start position and heading (z up)"


def result_summary(r: InferResult, session_facts: dict[str, object]) -> dict[str, object]:
    """The facts ``summary.json`` holds (also the report's header)."""
    seen = r.foot_measured.mean(axis=0)
    return {
        "reliable": not r.unreliable,
        "unreliable_reasons": list(r.unreliable),
        "session": session_facts,
        "frames": int(len(r.t_s)),
        "duration_s": float(r.t_s[-1] - r.t_s[0]) if len(r.t_s) > 1 else 0.0,
        "models": {"segmenter": r.segmenter_path, "predictor": r.predictor_path},
        "subject_height_m": r.subject_height_m,
        "bone_lengths_m": {
            "thigh": [float(v) for v in r.skeleton.thigh_lengths],
            "shank": [float(v) for v in r.skeleton.shank_lengths],
        },
        "standing_frames": r.standing_frames,
        "world_frame": {
            "initialisation": r.vio.initialisation,
            "note": r.vio.initialisation_note,
        },
        "scale": scale_source(r.vio),
        "extrinsic": {
            "T_PfromC": r.extrinsic.T_PfromC.tolist(),
            "spread_pos_m": r.extrinsic.spread_pos_m,
            "spread_rot_rad": r.extrinsic.spread_rot_rad,
        },
        "feet_measured_fraction": {s: float(v) for s, v in zip(SIDES, seen, strict=True)},
        "feet_dropped": dict(r.feet_dropped),
        "seconds": r.timings_s,
    }


def write_infer_files(
    r: InferResult, stage: Path, session_facts: dict[str, object]
) -> dict[str, object]:
    """Write the files of the module docstring into the folder ``stage``; returns the gait
    summary (:func:`gaitnet.pipeline.gait_parameters.summarise`)."""
    angles = sagittal_angles_deg(r.poses[:, 3:].reshape(-1, 6, 3))
    with open(stage / "joints.npz", "wb") as f:
        np.savez(
            f,
            t_ns=r.t_ns,
            positions=r.joints_W,
            smpl_indices=np.array(SMPL_JOINT_INDICES),
            joint_names=np.array(JOINT_NAMES),
            poses=r.poses,
            trans=r.trans,
            angles_deg=angles,
            angle_names=np.array(ANGLE_NAMES),
        )
    (stage / "joints.csv").write_text(_joints_csv(r, angles))
    (stage / "feet.csv").write_text(_feet_csv(r))
    for i, side in enumerate(SIDES):
        (stage / f"foot_{side}.tum").write_text(
            tum_text(r.t_s, _point_poses(r.feet_W[:, i]), f"gaitnet infer: {side} shoe marker")
        )
    (stage / "camera_frames.tum").write_text(
        tum_text(r.vio.t_s, r.vio.T_WfromC, "gaitnet infer: colour camera, smoothed")
    )
    (stage / "pelvis_frames.tum").write_text(
        tum_text(r.t_s, _pelvis_poses(r), "gaitnet infer: pelvis (x forward, y left, z up)")
    )
    stride_rows = [[s.row()[c] for c in STRIDE_COLUMNS] for s in r.vio.strides]
    (stage / "strides.csv").write_text(csv_text(list(STRIDE_COLUMNS), stride_rows))
    feet = {s: r.feet_W[:, i] for i, s in enumerate(SIDES)}
    contacts = detect_events(r.t_s, feet, r.joints_W[:, :7])
    write_gait_c3d(stage / "gait.c3d", r.t_s, r.joints_W, r.feet_W, contacts, r.subject_height_m)
    summary = result_summary(r, session_facts)
    summary["gait"] = _write_report(r, stage, session_facts, angles, contacts)
    (stage / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    return summary["gait"]  # type: ignore[return-value]


def _write_report(
    r: InferResult,
    stage: Path,
    facts: dict[str, object],
    angles: np.ndarray,
    contacts: list[FootContact],
) -> dict[str, object]:
    """Per-stride parameters, figures and ``report.html`` from the gait events ``contacts``;
    the gait summary."""
    feet = {s: r.feet_W[:, i] for i, s in enumerate(SIDES)}
    measured = {s: r.foot_measured[:, i] for i, s in enumerate(SIDES)}
    rows = stride_parameters(r.vio.strides, contacts)
    gait = summarise(rows)
    (stage / "gait_strides.csv").write_text(stride_table_csv(rows))
    figures = [
        (
            "Foot trajectories (solid: foot seen by the camera, dashed: filled in)",
            foot_trajectories_png(r.t_s, feet, measured),
        ),
        ("Walk seen from above", top_view_png(feet, (), contacts, r.vio.T_WfromC[:, :2, 3])),
        (
            "Joint angles over the gait cycle (mean ± SD)",
            joint_angles_png(r.t_s, angles, contacts, table_cycles(rows)),
        ),
        (
            "Stance and swing over time",
            gait_phases_png(contacts, float(r.t_s[0]), float(r.t_s[-1])),
        ),
    ]
    names = ("foot_trajectories", "top_view", "joint_angles", "gait_phases")
    for name, (_, png) in zip(names, figures, strict=True):
        write_png(stage / f"{name}.png", png)
    header = {
        **(
            {"RELIABLE": "no (--force): " + "; ".join(r.vio.unreliable)} if r.vio.unreliable else {}
        ),
        "session": facts.get("path", ""),
        "device": facts.get("device", ""),
        "duration [s]": round(float(r.t_s[-1] - r.t_s[0]), 2),
        "frames": len(r.t_s),
        "body height [m]": round(r.subject_height_m, 2),
        "world frame": _world_frame_text(r.vio.initialisation),
        "scale from": scale_source(r.vio),
        "models": f"{Path(r.segmenter_path).name}, {Path(r.predictor_path).name}",
        "software": facts.get("software", ""),
    }
    notes = (
        "Stride and step lengths come from the filter's stance-foot landmarks (docs/vio.md); "
        "stance, swing and double support from gait events detected on the foot trajectories, "
        "which read stance about 3 points and double support about 6 points high on simulated "
        "walks (docs/report.md).",
        "Frames where the camera did not see a foot are filled by the motion predictor and the "
        "pose correction (dashed in the foot-trajectory figure).",
    )
    write_report(stage / "report.html", header, gait, rows, figures, notes=notes)
    return gait
