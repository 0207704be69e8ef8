"""The filter's config (``configs/vio/default.yaml``; every key in docs/configs.md).

Sections: ``imu`` (noise densities), ``init`` (:class:`~gaitnet.vio.initialise.InitParams`),
``filter`` (which updates run, their noise and gates), ``vo``
(:class:`~gaitnet.vio.odometry.OdometryParams`), ``tags``
(:class:`~gaitnet.vio.apriltags.AprilTagParams`), ``floor``
(:class:`~gaitnet.geometry.floor_plane.FloorParams`), ``feet``
(:class:`~gaitnet.vio.feet.FootParams`),
``stance`` (:class:`~gaitnet.vio.stance_tracker.StanceParams`), ``smoother``, ``gait`` and
``scene`` (:class:`~gaitnet.vio.scene_check.SceneParams`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from gaitnet.checks import check_int_range, check_positive, check_range
from gaitnet.geometry.floor_plane import FloorParams
from gaitnet.io.types import ImuNoise, SessionCalibration
from gaitnet.vio.apriltags import AprilTagParams
from gaitnet.vio.feet import FootParams
from gaitnet.vio.initialise import InitParams
from gaitnet.vio.odometry import OdometryParams
from gaitnet.vio.scene_check import SceneParams
from gaitnet.vio.stance_tracker import StanceParams

__all__ = ["FilterParams", "GaitParams", "ImuNoiseParams", "SmootherParams", "VioConfig"]


@dataclass(frozen=True)
class ImuNoiseParams:
    """Continuous-time IMU noise densities (SI). Defaults: the BMI055 datasheet (the D455's IMU):
    gyroscope 0.014 °/s/√Hz, accelerometer 150 µg/√Hz; bias random walks are not on the
    datasheet and are set to the values commonly used for the D4xx IMU in calibration tools
    (gyro 2e-5 rad/s²/√Hz, accelerometer 3e-4 m/s³/√Hz). ``from_session``: use session.yaml's
    ``imu_noise`` when it has one. ``scale``: multiplies every density (inflates the noise to
    absorb unmodelled effects such as scale errors and vibration)."""

    gyro_noise_density: float = math.radians(0.014)
    accel_noise_density: float = 150e-6 * 9.80665
    gyro_bias_random_walk: float = 2e-5
    accel_bias_random_walk: float = 3e-4
    from_session: bool = True
    scale: float = 1.0

    def __post_init__(self) -> None:
        for name in (
            "gyro_noise_density",
            "accel_noise_density",
            "gyro_bias_random_walk",
            "accel_bias_random_walk",
            "scale",
        ):
            check_positive(name, getattr(self, name))


@dataclass(frozen=True)
class FilterParams:
    """Which updates run and their noise.

    ``*_gate_probability``: a measurement whose innovation's Mahalanobis distance exceeds the χ²
    quantile of this probability (for its dimension) is rejected and counted (0 disables the
    gate). The tag gate is loose (χ²(3) quantile 0.99999, ≈ 25.9): it refuses a pose metres off
    from a wrong decode of 2–3 tags (seen on simulated tuning sessions, where it made the filter
    diverge) but not the end sheet's correction of the walk's drift, which the filter's
    covariance covers now that it is consistent (docs/vio.md, *Filter consistency*).
    ``foot_std_m``: standard deviation of a measured stance-foot point per axis [m].
    ``partial_foot_noise``: a candidate narrower than the whole foot (the session's fullest
    views) adds half the hidden width across the foot to that standard deviation
    (:func:`gaitnet.vio.foot_model.partial_foot_noise`).
    ``min_foot_observations``: landmarks seen fewer times are not reported (the frames its
    stance track saw the foot before the stance was confirmed when a whole-enough foot was
    among them, then the accepted updates).
    ``end_sheet_std_m``: placement uncertainty of a tag sheet other than the one that
    initialised the state (the thesis's ε2: the end sheet's distance is tape-measured; a few
    millimetres).
    ``gravity_mps2``: gravity magnitude; 0 takes the accelerometer's mean magnitude while
    standing at the start (it then also absorbs the accelerometer's vertical scale error).
    ``marginalise_after_s``: a landmark not observed for this long [s] leaves the state (its
    foot has left). ``odometry_scale_std``: how far the odometry may run short or long over a
    walk, as a share of the distance since the last accepted tag update (motion blur shortens
    the visual translations by 3–5 % on long exposures; docs/vio.md): a sheet first seen after
    a walk is searched in the whole frame (every ``full_search_every``-th frame) while the
    camera is predicted within 1 m plus that share of the distance of it, and a sheet pose the
    tag gate rejects but that lies within that drift of the prediction is given to the smoother
    (not the filter): on a simulated 30 m walk the filter ended 64 cm short, its position
    standard deviation 10 cm, and the end sheet was neither searched where it was nor taken.
    ``full_search_every``: 0 never searches the whole frame after the first sheet.
    ``tag_recovery_frames``: a sheet whose position-only pose the gate refuses in this many
    decodes in a row (one frame without a decode between two allowed), steadily
    (``gaitnet.vio.tag_refusals.RECOVERY_STEP_M``), shows a filter that has drifted beyond its
    covariance: its navigation covariance is widened until the pose passes, and the pose is
    taken (``tag_recovered`` in ``summary.json``; 0: never; else at least 2). Such a sheet goes
    to the filter, not only to the smoother (``odometry_scale_std``); one found by the
    whole-frame search alone, every ``full_search_every``-th frame, is not steady. After a simulated
    full turn on the spot the filter refused the end sheet for 3.5 s while its camera height
    sank 27 cm, and the pipeline lost both feet.
    """

    use_vo: bool = True
    use_tags: bool = True
    use_feet: bool = True
    vo_gate_probability: float = 0.999
    tag_gate_probability: float = 0.99999
    foot_gate_probability: float = 0.999
    foot_std_m: float = 0.01
    partial_foot_noise: bool = True
    min_foot_observations: int = 3
    end_sheet_std_m: float = 0.005
    gravity_mps2: float = 0.0
    marginalise_after_s: float = 1.2
    odometry_scale_std: float = 0.05
    full_search_every: int = 3
    tag_recovery_frames: int = 5

    def __post_init__(self) -> None:
        for name in ("vo_gate_probability", "tag_gate_probability", "foot_gate_probability"):
            check_range(name, getattr(self, name), 0.0, 1.0 - 1e-12)
        check_positive("foot_std_m", self.foot_std_m)
        check_int_range("min_foot_observations", self.min_foot_observations, 1)
        check_range("end_sheet_std_m", self.end_sheet_std_m, 0.0)
        check_positive("marginalise_after_s", self.marginalise_after_s)
        check_range("odometry_scale_std", self.odometry_scale_std, 0.0, 1.0)
        check_int_range("full_search_every", self.full_search_every, 0)
        check_int_range("tag_recovery_frames", self.tag_recovery_frames, 0)
        if self.tag_recovery_frames == 1:
            raise ValueError(
                "tag_recovery_frames must be 0 (never) or at least 2 (one refusal alone may be "
                "a wrong decode), got 1"
            )
        if self.gravity_mps2 != 0.0:
            check_range("gravity_mps2", self.gravity_mps2, 9.7, 9.9)


@dataclass(frozen=True)
class SmootherParams:
    """The smoother over the whole session (thesis sec. 3.5; :mod:`gaitnet.vio.smoother`).

    ``enabled``: run it after the filter (``camera_frames.tum``, ``stance_feet.csv`` and
    ``strides.csv`` are then the smoothed estimates; off: the filter's). ``max_iterations``:
    Gauss–Newton iterations from the filter's estimates (1 is the thesis's single linear
    solve; the second moves the estimate by the linearisation error of the first, mm to cm on
    a walk; a third moved it by less than 0.01 mm on simulated tuning sessions).
    ``step_tol``: stop earlier when the largest step component (rad, m, m/s) is below it.
    """

    enabled: bool = True
    max_iterations: int = 2
    step_tol: float = 1e-5

    def __post_init__(self) -> None:
        check_int_range("max_iterations", self.max_iterations, 1)
        check_positive("step_tol", self.step_tol)


@dataclass(frozen=True)
class GaitParams:
    """Steady strides (:mod:`gaitnet.vio.gait`): ``max_stride_time_s`` [s] (a normal stride
    lasts 1.0–1.4 s; 2.5 s allows very slow walkers) and ``max_stance_time_s`` [s] (a stance
    seen longer than this is standing: foot-flat lasts ≤ ~0.8 s even at 0.6 m/s)."""

    max_stride_time_s: float = 2.5
    max_stance_time_s: float = 1.2

    def __post_init__(self) -> None:
        check_positive("max_stride_time_s", self.max_stride_time_s)
        check_positive("max_stance_time_s", self.max_stance_time_s)


@dataclass(frozen=True)
class VioConfig:
    """The whole filter config (module docstring)."""

    imu: ImuNoiseParams = field(default_factory=ImuNoiseParams)
    init: InitParams = field(default_factory=InitParams)
    filter: FilterParams = field(default_factory=FilterParams)
    vo: OdometryParams = field(default_factory=OdometryParams)
    tags: AprilTagParams = field(default_factory=AprilTagParams)
    floor: FloorParams = field(default_factory=FloorParams)
    feet: FootParams = field(default_factory=FootParams)
    stance: StanceParams = field(default_factory=StanceParams)
    smoother: SmootherParams = field(default_factory=SmootherParams)
    gait: GaitParams = field(default_factory=GaitParams)
    scene: SceneParams = field(default_factory=SceneParams)

    def imu_noise(self, calib: SessionCalibration) -> ImuNoise:
        """The densities the filter uses: session.yaml's when ``imu.from_session`` and the
        session has them, else this config's; times ``imu.scale``."""
        src = calib.imu_noise if (self.imu.from_session and calib.imu_noise) else self.imu
        s = self.imu.scale
        return ImuNoise(
            gyro_noise_density=src.gyro_noise_density * s,
            accel_noise_density=src.accel_noise_density * s,
            gyro_bias_random_walk=src.gyro_bias_random_walk * s,
            accel_bias_random_walk=src.accel_bias_random_walk * s,
        )
