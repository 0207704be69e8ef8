"""``gait.c3d``: a ``gaitnet infer`` result in the file format gait labs read (Vicon Nexus,
Visual3D, pyCGM2, Mokka, OpenSim), written with ezc3d (docs/report.md, *gait.c3d*).

- Points, in millimetres in the result's world frame (x forward at the start, y left, z up):
  the seven lower-body joint centres (:data:`JOINT_LABELS`, Plug-in Gait's names for the
  hip, knee and ankle joint centres) and the two gap-free foot points (:data:`FOOT_LABELS`:
  the shoe markers of ``feet.csv``, measured or filled). ``POINT:RATE`` is the frame rate
  (1 / the median frame interval); frame ``k`` of the result goes to the frame of the uniform
  grid nearest its time, and a grid frame no result frame reaches (a dropped camera frame)
  is marked invalid (residual −1), as C3D readers expect.
- Events as Vicon Nexus writes them: ``Foot Strike`` and ``Foot Off`` (icons 1 and 2) with
  the contexts ``Left`` and ``Right``, from the gait events of the foot trajectories
  (:func:`gaitnet.pipeline.gait_events.detect_events`; an event that was not detected is not
  written). ``EVENT:TIMES`` holds minutes and seconds; the time of C3D frame ``f`` (1-based,
  ``TRIAL:ACTUAL_START_FIELD`` 1) is ``f / rate``.
- The subject: ``SUBJECTS:NAMES`` and ``PROCESSING:Height`` [mm], where Nexus keeps the
  subject's measurements.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import ezc3d
import numpy as np

from gaitnet.pipeline.gait_events import FootContact

__all__ = ["FOOT_LABELS", "JOINT_LABELS", "c3d_frame_grid", "write_gait_c3d"]

JOINT_LABELS: tuple[tuple[str, str], ...] = (
    ("PELVIS", "pelvis centre (SMPL joint 0)"),
    ("LHJC", "left hip joint centre"),
    ("RHJC", "right hip joint centre"),
    ("LKJC", "left knee joint centre"),
    ("RKJC", "right knee joint centre"),
    ("LAJC", "left ankle joint centre"),
    ("RAJC", "right ankle joint centre"),
)
FOOT_LABELS: tuple[tuple[str, str], ...] = (
    ("LFOOT", "left shoe marker, measured or filled (feet.csv)"),
    ("RFOOT", "right shoe marker, measured or filled (feet.csv)"),
)
EVENTS = {
    "initial_contact_s": ("Foot Strike", 1, "The instant the heel strikes the ground"),
    "toe_off_s": ("Foot Off", 2, "The instant the toe leaves the ground"),
}
CONTEXTS = {"left": "Left", "right": "Right"}


def c3d_frame_grid(t_s: np.ndarray) -> tuple[float, np.ndarray, int]:
    """The C3D frame rate [Hz] (1 / the median frame interval), each frame's slot on the
    uniform grid from the first frame (nearest), and the number of grid frames."""
    t = np.asarray(t_s, dtype=np.float64)
    rate = 1.0 / float(np.median(np.diff(t)))
    slots = np.rint((t - t[0]) * rate).astype(np.int64)
    return rate, slots, int(slots[-1]) + 1


def write_gait_c3d(
    path: Path,
    t_s: np.ndarray,
    joints_W: np.ndarray,
    feet_W: np.ndarray,
    contacts: Sequence[FootContact],
    subject_height_m: float,
    subject: str = "subject",
) -> None:
    """Write ``gait.c3d`` (module docstring): ``t_s`` (n,) frame times [s] (strictly
    increasing), ``joints_W`` (n, ≥7, 3) the joints of ``joints.npz`` (the first seven are
    written), ``feet_W`` (n, 2, 3) the foot points [m], ``contacts`` the gait events."""
    rate, slots, n_grid = c3d_frame_grid(t_s)
    xyz = np.concatenate([joints_W[:, : len(JOINT_LABELS)], feet_W], axis=1) * 1000.0
    labels = [name for name, _ in JOINT_LABELS + FOOT_LABELS]
    points = np.zeros((4, len(labels), n_grid))
    residuals = np.full((1, len(labels), n_grid), -1.0)
    # two result frames on one slot (a frame interval far below the median): the later wins
    points[:3, :, slots] = np.transpose(xyz, (2, 1, 0))
    points[3, :, slots] = 1.0
    residuals[0, :, slots] = 0.0  # grid frames no result frame reaches stay (0, 0, 0), −1
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = np.array([rate])
    c3d["parameters"]["POINT"]["LABELS"]["value"] = labels
    c3d["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = [
        text for _, text in JOINT_LABELS + FOOT_LABELS
    ]
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    c3d["data"]["points"] = points
    c3d["data"]["meta_points"]["residuals"] = residuals
    c3d.add_parameter("TRIAL", "ACTUAL_START_FIELD", [1, 0])
    c3d.add_parameter("TRIAL", "ACTUAL_END_FIELD", [n_grid, 0])
    c3d.add_parameter("SUBJECTS", "USED", 1)
    c3d.add_parameter("SUBJECTS", "NAMES", [subject])
    c3d.add_parameter("PROCESSING", "Height", float(subject_height_m * 1000.0))
    t0 = float(t_s[0])
    for contact in sorted(contacts, key=lambda c: c.still_start_s):
        for field, (label, icon, description) in EVENTS.items():
            t = getattr(contact, field)
            if t is None:
                continue
            seconds = (t - t0) + 1.0 / rate  # C3D frame 1 is the first frame
            c3d.add_event(
                [int(seconds // 60), float(seconds % 60)],
                context=CONTEXTS[contact.side],
                label=label,
                description=description,
                subject=subject,
                icon_id=icon,
            )
    c3d.write(str(path))
