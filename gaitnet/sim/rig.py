"""The sensor rig: a D455-like camera on the front of the pelvis and its IMU.

Frames: pelvis P (origin at the SMPL pelvis joint, x forward, y left, z up), camera C (OpenCV:
x right, y down, z forward), IMU I (rigidly attached to the camera, ``T_CfromI``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gaitnet.checks import check_each, check_int_range, check_range
from gaitnet.geometry import make_T, so3_exp
from gaitnet.io.types import CameraIntrinsics

# Camera looking along the pelvis x axis, level: camera x = −pelvis y, y = −pelvis z, z = pelvis x.
R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
PITCH_RANGE_DEG = (10.0, 89.0)  # valid mount.pitch_deg values
FOV_RANGE_DEG = (10.0, 150.0)  # valid horizontal and vertical fields of view


DEFAULT_EXPOSURE_RANGE_S = (0.001, 0.030)  # the D455 colour sensor's usable exposures at 30 Hz
EXPOSURE_STEP_S = 1e-4  # its exposure step


@dataclass(frozen=True)
class CameraConfig:
    """Colour camera (depth is aligned to it). Defaults: a D455 at 640×480, 30 Hz.

    Valid values: ``width`` 16–2048 and ``height`` 16–2048 px; ``fx``, ``fy`` such that the
    horizontal and vertical fields of view lie within 10–150°; the principal point inside the
    image; ``fps`` 1–120 Hz.

    Exposure (motion blur, :mod:`gaitnet.sim.render_motion`): the auto-exposure reaches the
    brightness it wants (its exposure factor ``E``, :mod:`gaitnet.sim.session`) with an
    exposure time ``E · exposure_time_ref_s`` (:meth:`exposure_time_s`) clipped to
    ``exposure_time_range_s`` (the rest is analog gain), so dim scenes get long exposures and
    long smears. ``exposure_time_ref_s`` (0.5–30 ms): the time for the reference brightness
    ``E = 1`` (the default lighting: ~10 ms, an indoor D455 colour exposure);
    ``exposure_time_range_s`` [shortest, longest] within 0.1 ms (the D455 colour sensor's
    step) and the frame period; the default range's longest exposure becomes the frame period
    (to the 0.1 ms step below it) where that is shorter, as on the camera (60 Hz: 16.6 ms);
    ``motion_blur`` false renders the mid-exposure instant only.
    Sources: docs/references.md, *Simulator realism: rendering*.
    """

    width: int = 640
    height: int = 480
    fx: float = 386.0
    fy: float = 386.0
    cx: float = 319.5
    cy: float = 239.5
    fps: float = 30.0
    motion_blur: bool = True
    exposure_time_ref_s: float = 0.010
    exposure_time_range_s: tuple[float, float] = DEFAULT_EXPOSURE_RANGE_S

    def __post_init__(self) -> None:
        check_int_range("width", self.width, 16, 2048)
        check_int_range("height", self.height, 16, 2048)
        for name, focal, size in (("fx", self.fx, self.width), ("fy", self.fy, self.height)):
            # field of view 2·atan(size / 2f) within FOV_RANGE_DEG
            lo, hi = (size / (2 * np.tan(np.deg2rad(a) / 2)) for a in FOV_RANGE_DEG[::-1])
            check_range(name, focal, round(float(lo), 3), round(float(hi), 3), " px (FOV 10–150°)")
        check_range("cx", self.cx, 0.0, float(self.width), " px")
        check_range("cy", self.cy, 0.0, float(self.height), " px")
        check_range("fps", self.fps, 1.0, 120.0, " Hz")
        check_range("exposure_time_ref_s", self.exposure_time_ref_s, 0.0005, 0.03, " s")
        period = 1.0 / self.fps
        if tuple(self.exposure_time_range_s) == DEFAULT_EXPOSURE_RANGE_S and period < 0.030:
            longest = max(np.floor(period / EXPOSURE_STEP_S) * EXPOSURE_STEP_S, 0.001)
            object.__setattr__(self, "exposure_time_range_s", (0.001, round(float(longest), 6)))
        check_each("exposure_time_range_s", self.exposure_time_range_s, 1e-4, 1.0 / self.fps, " s")
        if len(self.exposure_time_range_s) != 2 or (
            self.exposure_time_range_s[0] > self.exposure_time_range_s[1]
        ):
            raise ValueError(
                f"exposure_time_range_s must be [shortest, longest], got "
                f"{list(self.exposure_time_range_s)}"
            )

    def exposure_time_s(self, exposure: float) -> float:
        """Exposure time [s] that the auto-exposure uses for the exposure factor ``exposure``
        (0 when ``motion_blur`` is off: the frame is one instant)."""
        if not self.motion_blur:
            return 0.0
        lo, hi = self.exposure_time_range_s
        return float(np.clip(exposure * self.exposure_time_ref_s, lo, hi))

    def intrinsics(self) -> CameraIntrinsics:
        return CameraIntrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy)


@dataclass(frozen=True)
class MountConfig:
    """Where the camera sits on the pelvis and how the IMU sits in the camera.

    ``pitch_deg``: downward pitch of the optical axis from horizontal (thesis: about 30–75°),
    10–89°; a pair ``[lo, hi]`` draws it uniformly from that range, once per session in
    ``gaitnet simulate`` and once per frame in ``gaitnet simulate-dataset``.
    ``yaw_deg`` (±60°) and ``roll_deg`` (±45°): the camera turned about the vertical / its
    optical axis.
    ``offset_m``: camera centre in the pelvis frame (forward 0–0.4, left ±0.3, up ±0.4 m) — on
    the belly.
    ``imu_in_camera_m`` / ``imu_rpy_deg``: the IMU origin in the camera frame (each coordinate
    within ±0.1 m: inside the camera housing) and the IMU-to-camera rotation (roll, pitch, yaw
    about the camera x, y, z axes, each within ±180°).

    The rig's motion on its strap (:mod:`gaitnet.sim.mount_dynamics`; magnitudes in
    docs/references.md, *Simulator realism: IMU and timing*): ``impact_peak_g`` (0–5 g; 0 =
    off) the heel-strike shock's peak acceleration at the pelvis at 1.3 m/s (linear in speed),
    ringing at ``impact_freq_hz`` (5–50 Hz) with damping ratio ``impact_damping_ratio``
    (0.05–1); the strap wobble, a damped spring of natural frequency ``wobble_freq_hz``
    (1–15 Hz) and damping ratio ``wobble_damping_ratio`` (0.02–1) driven by the pelvis
    acceleration and the shocks, with compliance ``wobble_gain`` (0–1; 0 = rigid) and
    ``wobble_tilt_deg_per_mm`` (0–3 °/mm) of rocking per millimetre of fore-aft / lateral
    displacement.
    """

    pitch_deg: float | tuple[float, float] = 70.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0
    offset_m: tuple[float, float, float] = (0.17, 0.0, 0.05)
    imu_in_camera_m: tuple[float, float, float] = (-0.0302, 0.0074, 0.0160)
    imu_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    impact_peak_g: float = 2.0
    impact_freq_hz: float = 20.0
    impact_damping_ratio: float = 0.3
    wobble_freq_hz: float = 4.0
    wobble_damping_ratio: float = 0.15
    wobble_gain: float = 0.3
    wobble_tilt_deg_per_mm: float = 0.5

    def __post_init__(self) -> None:
        lo, hi = PITCH_RANGE_DEG
        if isinstance(self.pitch_deg, tuple):
            check_each("pitch_deg", self.pitch_deg, lo, hi, "°")
            if len(self.pitch_deg) != 2 or self.pitch_deg[0] > self.pitch_deg[1]:
                raise ValueError(f"pitch_deg as a range must be [lo, hi], got {self.pitch_deg}")
        else:
            check_range("pitch_deg", self.pitch_deg, lo, hi, "°")
        check_range("yaw_deg", self.yaw_deg, -60.0, 60.0, "°")
        check_range("roll_deg", self.roll_deg, -45.0, 45.0, "°")
        for name, value, (a, b) in zip(
            ("offset_m[0] (forward)", "offset_m[1] (left)", "offset_m[2] (up)"),
            self.offset_m,
            ((0.0, 0.4), (-0.3, 0.3), (-0.4, 0.4)),
            strict=True,
        ):
            check_range(name, value, a, b, " m")
        check_each("imu_in_camera_m", self.imu_in_camera_m, -0.1, 0.1, " m")
        check_each("imu_rpy_deg", self.imu_rpy_deg, -180.0, 180.0, "°")
        check_range("impact_peak_g", self.impact_peak_g, 0.0, 5.0, " g")
        check_range("impact_freq_hz", self.impact_freq_hz, 5.0, 50.0, " Hz")
        check_range("impact_damping_ratio", self.impact_damping_ratio, 0.05, 1.0)
        check_range("wobble_freq_hz", self.wobble_freq_hz, 1.0, 15.0, " Hz")
        check_range("wobble_damping_ratio", self.wobble_damping_ratio, 0.02, 1.0)
        check_range("wobble_gain", self.wobble_gain, 0.0, 1.0)
        check_range("wobble_tilt_deg_per_mm", self.wobble_tilt_deg_per_mm, 0.0, 3.0, " °/mm")

    @property
    def pitch_is_drawn(self) -> bool:
        """True when ``pitch_deg`` is a range to draw from."""
        return isinstance(self.pitch_deg, tuple)

    def with_pitch(self, rng: np.random.Generator) -> MountConfig:
        """This mount with a fixed pitch: ``pitch_deg`` itself, or drawn from its range with
        ``rng`` (which is not used when the pitch is fixed)."""
        if not isinstance(self.pitch_deg, tuple):
            return self
        return replace(self, pitch_deg=float(rng.uniform(*self.pitch_deg)))

    def T_PfromC(self) -> np.ndarray:
        """Camera pose in the pelvis frame: level camera, then yaw, pitch down, roll.

        Needs a fixed pitch (:meth:`with_pitch` turns a range into one).
        """
        if isinstance(self.pitch_deg, tuple):
            raise ValueError("mount.pitch_deg is a range: draw the pitch first (with_pitch)")
        yaw = so3_exp(np.deg2rad(self.yaw_deg) * np.array([0.0, 0.0, 1.0]))
        pitch = so3_exp(np.deg2rad(self.pitch_deg) * np.array([0.0, 1.0, 0.0]))
        roll = so3_exp(np.deg2rad(self.roll_deg) * np.array([1.0, 0.0, 0.0]))
        R = yaw @ pitch @ roll @ R_PfromC_LEVEL
        return make_T(R, np.asarray(self.offset_m, dtype=np.float64))

    def T_CfromI(self) -> np.ndarray:
        rx, ry, rz = np.deg2rad(self.imu_rpy_deg)
        R = (
            so3_exp(np.array([0.0, 0.0, rz]))
            @ so3_exp(np.array([0.0, ry, 0.0]))
            @ so3_exp(np.array([rx, 0.0, 0.0]))
        )
        return make_T(R, np.asarray(self.imu_in_camera_m, dtype=np.float64))
