"""Does the session show what a waist-worn camera sees? The checks before the filter runs.

A result is only as good as its input: a desk top taken for the floor, an IMU mounted upside
down or an IMU stream that misses half the walk give confident wrong numbers. Before the filter
starts, :func:`check_scene` looks at the IMU's time stamps and the first frames and lists what
is wrong, each as one short phrase:

- **IMU coverage.** The share of frames that fall inside the IMU stream (between its first and
  last sample, and not inside a gap longer than ``max_imu_gap_s``) must be at least
  ``min_imu_coverage``. Frames outside the stream's span are skipped by the filter (a warning
  says how many) when the rest is covered.
- **Pitch.** The optical axis points ``min_pitch_deg``–``max_pitch_deg`` below the horizon
  (the accelerometer's up): flatter, the feet leave the view (45°: no stride found on a
  simulated walk); steeper, the camera looks straight down at its own body and the feet's
  sides are no longer told apart (89°: left and right swapped on 2 of 4 simulated walks; 80–88°:
  right on 8 of 8).
- **Depth.** At least ``min_valid_depth`` of the pixels of the first frames have depth.
- **A floor along gravity.** Up is the accelerometer's mean specific force over the standing
  window (:func:`gaitnet.vio.initialise.standing_up`) rotated into the camera by ``T_CfromI``;
  the floor fit (:func:`gaitnet.geometry.floor_plane.fit_floor_depth`) must find a plane
  within ``floor.max_angle_from_prior_deg`` of it. When it finds none but the depth shows a
  large plane facing the camera elsewhere, the message gives that plane's angle from the
  accelerometer's up: an IMU upside down or a wrong ``T_CfromI`` (session.yaml) shows as about
  180° or 90°.
- **Plausible height.** The floor is ``min_height_m``–``max_height_m`` below the camera (a
  waist-worn camera of an adult).
- **The floor fills the view.** At least ``min_floor_fraction`` of the depth points lie on it
  (a waist camera pitched down sees mostly floor; a desk scene shows a table top among walls
  and objects), and at most ``max_below_floor_fraction`` lie more than ``below_floor_m``
  under it (nothing is below a floor; a table top has the room's floor beneath it).
- **Legs under the camera.** At least ``min_leg_fraction`` of the depth points stand
  ``leg_min_height_m`` above the floor up to 0.15 m below the camera, within ``leg_reach_m``
  of the camera's plumb line: a camera on a walker's waist sees their legs there (simulated
  walks pitched 70°: 1.1–2.4 % of the points; 65°: 1.7 %; 86°: 2.5 %; 60°: 0.2–0.3 %, all
  strides still found; 55°: none, the feet in view in 6 % of the frames and half the strides
  missed); a floor seen from a tripod, a hand or a table edge shows nothing there.

The checks run on the best of the first ``n_frames`` frames (the one whose floor has the most
inliers). The thresholds are far from what simulated waist-camera walks at the default pitch
(70°) show: height 0.97–1.16 m, floor 91–96 % of the points, none below it, legs 1.1–2.4 %
(docs/vio.md *Scene check*). The legs check is closest at flat pitches: 0.2–0.3 % at 60°
against its 0.1 %, and a camera pitched 55° or flatter is refused by it even though the pitch
check accepts 50°.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from gaitnet.checks import check_int_range, check_range
from gaitnet.geometry.floor_plane import (
    FloorParams,
    FloorPlane,
    fit_floor,
    floor_points,
)
from gaitnet.io.types import Frame, ImuSamples, SessionCalibration, SessionSource
from gaitnet.vio.errors import SceneError
from gaitnet.vio.initialise import InitParams, standing_up

__all__ = [
    "SceneParams",
    "Screening",
    "check_scene",
    "imu_coverage",
    "leg_fraction",
    "screen_session",
]

log = logging.getLogger(__name__)

#: Up directions tried, in the camera frame, when no floor lies along gravity (the plane the
#: depth shows, whatever the IMU says): 60° cones around the six axes cover every direction.
_AXES = np.concatenate([np.eye(3), -np.eye(3)])
_AXIS_CONE_DEG = 60.0
_BELOW_CAMERA_M = 0.15  # the leg volume's top, under the camera (its own strap and belly above)


@dataclass(frozen=True)
class SceneParams:
    """Thresholds of the scene check (module docstring); ``refuse: false`` (``--force``) runs
    anyway and marks the result unreliable."""

    refuse: bool = True
    n_frames: int = 3
    min_pitch_deg: float = 50.0
    max_pitch_deg: float = 86.0
    min_imu_coverage: float = 0.9
    max_imu_gap_s: float = 0.1
    min_valid_depth: float = 0.3
    min_height_m: float = 0.5
    max_height_m: float = 1.5
    min_floor_fraction: float = 0.4
    below_floor_m: float = 0.1
    max_below_floor_fraction: float = 0.05
    min_leg_fraction: float = 0.001
    leg_min_height_m: float = 0.05
    leg_reach_m: float = 0.5

    def __post_init__(self) -> None:
        check_int_range("scene.n_frames", self.n_frames, 1, 1000)
        check_range("scene.min_pitch_deg", self.min_pitch_deg, -90.0, 90.0)
        check_range("scene.max_pitch_deg", self.max_pitch_deg, self.min_pitch_deg, 90.0)
        check_range("scene.min_imu_coverage", self.min_imu_coverage, 0.0, 1.0)
        check_range("scene.max_imu_gap_s", self.max_imu_gap_s, 1e-3, 10.0)
        check_range("scene.min_valid_depth", self.min_valid_depth, 0.0, 1.0)
        check_range("scene.min_height_m", self.min_height_m, 0.0, 10.0)
        check_range("scene.max_height_m", self.max_height_m, self.min_height_m, 10.0)
        check_range("scene.min_floor_fraction", self.min_floor_fraction, 0.0, 1.0)
        check_range("scene.below_floor_m", self.below_floor_m, 0.0, 10.0)
        check_range("scene.max_below_floor_fraction", self.max_below_floor_fraction, 0.0, 1.0)
        check_range("scene.min_leg_fraction", self.min_leg_fraction, 0.0, 1.0)
        check_range("scene.leg_min_height_m", self.leg_min_height_m, 0.0, 10.0)
        check_range("scene.leg_reach_m", self.leg_reach_m, 0.0, 10.0)


def imu_coverage(imu_t_ns: np.ndarray, frame_t_ns: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Per frame, whether the IMU stream covers its time: inside the stream's span and not
    inside a gap between two samples longer than ``max_gap_s``."""
    t = np.asarray(frame_t_ns, dtype=np.int64)
    s = np.asarray(imu_t_ns, dtype=np.int64)
    if len(s) < 2:
        return np.zeros(len(t), dtype=bool)
    inside = (t >= s[0]) & (t <= s[-1])
    right = np.clip(np.searchsorted(s, t, side="left"), 1, len(s) - 1)
    gap = (s[right] - s[right - 1]) * 1e-9
    return inside & ((gap <= max_gap_s) | (s[right] == t))


def _facing_plane(points: np.ndarray, floor: FloorParams) -> FloorPlane | None:
    """The largest plane facing the camera (camera on its normal's side), whatever its
    direction: the best of :func:`fit_floor` over 60° cones around the six camera axes."""
    params = replace(floor, max_angle_from_prior_deg=_AXIS_CONE_DEG)
    planes = [fit_floor(points, axis, params) for axis in _AXES]
    planes = [p for p in planes if p is not None]
    return max(planes, key=lambda p: p.n_inliers) if planes else None


def _frame_problems(
    frame: Frame, K: np.ndarray, up_C: np.ndarray, params: SceneParams, floor: FloorParams
) -> tuple[int, list[str]]:
    """(floor inliers, problems) of one frame."""
    depth = frame.depth_m
    valid = float(np.mean(np.isfinite(depth) & (depth > 0)))
    if valid < params.min_valid_depth:
        return 0, [
            f"depth: {100 * valid:.0f} % of the pixels have depth (need "
            f"{100 * params.min_valid_depth:.0f} %)"
        ]
    points = floor_points(depth, K, floor.stride, floor.max_range_m)
    plane = fit_floor(points, up_C, floor)
    if plane is None:
        other = _facing_plane(points, floor)
        if other is not None and other.n_inliers >= params.min_floor_fraction * len(points):
            angle = np.degrees(np.arccos(np.clip(other.n_C @ up_C, -1.0, 1.0)))
            return 0, [
                f"no floor along gravity: the plane the depth shows is {angle:.0f}° from the "
                "accelerometer's up (an IMU upside down or a wrong T_CfromI in session.yaml?)"
            ]
        return 0, ["no floor plane below the camera along gravity"]
    problems = []
    if not params.min_height_m <= plane.h <= params.max_height_m:
        problems.append(
            f"the floor is {plane.h:.2f} m below the camera (a waist-worn camera: "
            f"{params.min_height_m:g}–{params.max_height_m:g} m)"
        )
    share = plane.n_inliers / max(len(points), 1)
    if share < params.min_floor_fraction:
        problems.append(
            f"the floor is {100 * share:.0f} % of the depth points (need "
            f"{100 * params.min_floor_fraction:.0f} %)"
        )
    height = plane.height(points)
    below = float(np.mean(height < -params.below_floor_m))
    if below > params.max_below_floor_fraction:
        problems.append(
            f"{100 * below:.0f} % of the depth points lie below the floor plane (a table top?)"
        )
    legs = leg_fraction(points, height, plane, params)
    if legs < params.min_leg_fraction:
        problems.append(
            f"no legs under the camera: {100 * legs:.2f} % of the depth points stand "
            f"{params.leg_min_height_m:g} m to 0.15 m below the camera above the floor within "
            f"{params.leg_reach_m:g} m of the camera's plumb line (need "
            f"{100 * params.min_leg_fraction:g} %: a waist-worn camera sees its wearer's legs)"
        )
    return plane.n_inliers, problems


def leg_fraction(
    points: np.ndarray, height: np.ndarray, plane: FloorPlane, params: SceneParams
) -> float:
    """Share of the depth ``points`` (camera frame) where a waist-worn camera sees its wearer's
    legs: ``leg_min_height_m`` above the floor (``height``: each point's) up to 0.15 m below
    the camera, and within ``leg_reach_m`` of the camera's plumb line (horizontally)."""
    if len(points) == 0:
        return 0.0
    n = plane.n_C
    horizontal = np.linalg.norm(points - np.outer(points @ n, n), axis=1)
    legs = (height > params.leg_min_height_m) & (height < plane.h - _BELOW_CAMERA_M)
    return float(np.mean(legs & (horizontal < params.leg_reach_m)))


def check_scene(
    frames: list[Frame],
    imu: ImuSamples,
    frame_times_ns: np.ndarray,
    calib: SessionCalibration,
    up_I: np.ndarray,
    params: SceneParams,
    floor: FloorParams,
) -> list[str]:
    """What the session lacks to be measured (module docstring), as short phrases; empty when
    it passes. ``frames``: the first frames; ``up_I``: the accelerometer's up (unit, IMU frame)
    over the standing window."""
    problems = []
    covered = imu_coverage(imu.t_ns, frame_times_ns, params.max_imu_gap_s)
    share = float(covered.mean()) if len(covered) else 0.0
    if share < params.min_imu_coverage:
        problems.append(
            f"the IMU covers {100 * share:.0f} % of the frames (IMU "
            f"{imu.t_ns[0] * 1e-9:.2f}–{imu.t_ns[-1] * 1e-9:.2f} s, frames "
            f"{frame_times_ns[0] * 1e-9:.2f}–{frame_times_ns[-1] * 1e-9:.2f} s)"
        )
    up_C = calib.T_CfromI[:3, :3] @ up_I
    pitch = float(np.degrees(np.arcsin(np.clip(-up_C[2], -1.0, 1.0))))
    if not params.min_pitch_deg <= pitch <= params.max_pitch_deg:
        problems.append(
            f"the camera looks {pitch:.0f}° below the horizon (the feet are measured at "
            f"{params.min_pitch_deg:g}–{params.max_pitch_deg:g}°: flatter they leave the view, "
            "steeper their sides are not told apart)"
        )
    results = [
        _frame_problems(f, calib.color.K, up_C, params, floor) for f in frames[: params.n_frames]
    ]
    best = max(results, key=lambda r: r[0]) if results else (0, ["no frames"])
    return problems + best[1]


@dataclass(frozen=True)
class Screening:
    """What :func:`screen_session` found: the first frames from the first one the IMU covers
    (for the initialisation), the problems (empty: the session passed) and the index of the
    last frame inside the IMU stream's span (later frames are skipped)."""

    first: list[Frame]
    problems: list[str]
    last_index: int


def screen_session(
    source: SessionSource,
    params: SceneParams,
    init: InitParams,
    floor: FloorParams,
    n_first: int,
) -> Screening:
    """Run :func:`check_scene` on ``source`` and its first ``n_first`` covered frames. Raises
    :class:`SceneError` (one line, every problem) when there are problems and
    ``params.refuse``; otherwise logs them as a warning. Logs how many frames lie outside the
    IMU stream's span."""
    times = np.asarray(source.frame_times_ns, dtype=np.int64)
    imu = source.imu
    covered = imu_coverage(imu.t_ns, times, params.max_imu_gap_s)
    start = int(np.argmax(covered)) if covered.any() else 0
    first = [source.frame(i) for i in range(start, min(len(source), start + max(n_first, 1)))]
    up_I = standing_up(imu, int(first[0].t_ns), init)
    problems = check_scene(first, imu, times, source.calibration, up_I, params, floor)
    if problems and params.refuse:
        raise SceneError(
            "this session does not show what a waist-worn camera sees: "
            + "; ".join(problems)
            + " (--force runs anyway and marks the result unreliable)"
        )
    if problems:
        log.warning("result marked unreliable: %s", "; ".join(problems))
    inside = np.flatnonzero(times <= imu.t_ns[-1])
    last = int(inside[-1]) if len(inside) else len(times) - 1
    outside = start + (len(times) - 1 - last)
    if outside and covered.any():
        log.warning(
            "%d of %d frames lie outside the IMU stream (%.2f–%.2f s) and are skipped",
            outside, len(times), imu.t_ns[0] * 1e-9, imu.t_ns[-1] * 1e-9,
        )  # fmt: skip
    return Screening(first, problems, last)
