"""The ``gait`` section of the simulator's config (:class:`GaitConfig`).

Key table with ranges: docs/simulator.md; the speed laws and per-subject style behind
``stance_fraction`` None, ``variability``, the pelvis amplitudes, ``stand_width_m`` and the sway
keys: :mod:`gaitnet.sim.gait_style`.
"""

from __future__ import annotations

from dataclasses import dataclass

from gaitnet.checks import check_range

__all__ = ["MAX_TO_PITCH_DEG", "GaitConfig"]

MAX_TO_PITCH_DEG = 70.0
_LOWEST_STANCE = 0.55  # the speed law's stance fraction never goes below this


@dataclass(frozen=True)
class GaitConfig:
    """How the subject walks. Amplitudes are half of the peak-to-peak excursion.

    The pelvis vertical excursion is not a parameter: it follows from the legs, whose stance
    knee is designed by ``knee_extended_deg`` (heel strike, mid-stance, standing) and
    ``knee_loading_deg`` (loading-response peak). The pelvis amplitudes are the average
    subject's at 1.3 m/s; they scale with the speed and the subject
    (:mod:`gaitnet.sim.gait_style`), as do the stance share (``stance_fraction`` None), the step
    length and the standing width (``stand_width_m`` None); ``variability`` scales the
    between-subject spread (0: every subject walks alike). ``sway_*_rms_m``: postural sway of the
    pelvis while standing. ``toe_off_ankle_deg``: the ankle angle the shoe's heel-up pitch at toe
    off is designed for (``toe_off_pitch_deg`` is the least pitch); ``swing_ankle_deg``: the
    ankle from mid-swing to terminal swing. Valid ranges: ``__post_init__`` (the key table of
    docs/simulator.md lists them).
    """

    speed_mps: float = 1.2
    walk_length_m: float = 5.0
    step_width_m: float = 0.10
    step_length_cv: float = 0.03
    step_time_cv: float = 0.03
    step_width_std_m: float = 0.01
    stand_start_s: float = 1.5
    stand_end_s: float = 1.5
    stand_width_m: float | None = None
    turn_deg: float = 0.0
    variability: float = 1.0
    pelvis_lateral_m: float = 0.02
    pelvis_rotation_deg: float = 4.5
    pelvis_obliquity_deg: float = 4.0
    pelvis_tilt_deg: float = 2.0
    sway_ap_rms_m: float = 0.003
    sway_ml_rms_m: float = 0.002
    toe_clearance_m: float = 0.015
    heel_strike_pitch_deg: float = 12.0
    toe_off_pitch_deg: float = 35.0
    toe_off_ankle_deg: float = 0.0
    push_off_ankle_deg: float = -15.0
    swing_ankle_deg: float = 0.0
    toe_out_deg: float = 5.0
    stance_fraction: float | None = None
    knee_extended_deg: float = 3.0
    knee_loading_deg: float = 17.0
    foot_flat_fraction: float = 0.09
    heel_off_fraction: float = 0.38
    min_heel_off_fraction: float = 0.30
    step_length_height_ratio: float = 0.40
    step_length_speed_exponent: float = 0.5
    first_foot: str = "random"

    def __post_init__(self) -> None:
        check_range("speed_mps", self.speed_mps, 0.6, 1.7)
        check_range("walk_length_m", self.walk_length_m, 3.0, 100.0)
        check_range("step_width_m", self.step_width_m, 0.0, 0.3)
        check_range("stand_start_s", self.stand_start_s, 1.0, 60.0)
        check_range("stand_end_s", self.stand_end_s, 1.0, 60.0)
        if self.stand_width_m is not None:
            check_range("stand_width_m", self.stand_width_m, 0.05, 0.4)
        check_range("turn_deg", self.turn_deg, -360.0, 360.0)
        check_range("variability", self.variability, 0.0, 2.0)
        check_range("toe_clearance_m", self.toe_clearance_m, 0.005, 0.05)
        if self.stance_fraction is not None:
            check_range("stance_fraction", self.stance_fraction, 0.55, 0.7)
        stance = _LOWEST_STANCE if self.stance_fraction is None else self.stance_fraction
        check_range("knee_extended_deg", self.knee_extended_deg, 2.0, 10.0)
        check_range("knee_loading_deg", self.knee_loading_deg, self.knee_extended_deg, 30.0)
        check_range("foot_flat_fraction", self.foot_flat_fraction, 0.02, 0.15)
        check_range("heel_off_fraction", self.heel_off_fraction, 0.2, stance - 0.1)
        check_range(
            "min_heel_off_fraction",
            self.min_heel_off_fraction,
            self.foot_flat_fraction + 0.05,
            self.heel_off_fraction,
        )
        for name in ("step_length_cv", "step_time_cv", "step_width_std_m"):
            check_range(name, getattr(self, name), 0.0, 0.1)
        check_range("pelvis_lateral_m", self.pelvis_lateral_m, 0.0, 0.06)
        for name in ("pelvis_rotation_deg", "pelvis_obliquity_deg"):
            check_range(name, getattr(self, name), 0.0, 15.0)
        check_range("pelvis_tilt_deg", self.pelvis_tilt_deg, 0.0, 10.0)
        for name in ("sway_ap_rms_m", "sway_ml_rms_m"):
            check_range(name, getattr(self, name), 0.0, 0.02)
        check_range("heel_strike_pitch_deg", self.heel_strike_pitch_deg, 5.0, 30.0)
        check_range("toe_off_pitch_deg", self.toe_off_pitch_deg, 15.0, 50.0)
        check_range("toe_off_ankle_deg", self.toe_off_ankle_deg, -30.0, 10.0)
        check_range("push_off_ankle_deg", self.push_off_ankle_deg, -30.0, 0.0)
        check_range("swing_ankle_deg", self.swing_ankle_deg, -15.0, 15.0)
        check_range("toe_out_deg", self.toe_out_deg, -10.0, 25.0)
        check_range("step_length_height_ratio", self.step_length_height_ratio, 0.3, 0.5)
        check_range("step_length_speed_exponent", self.step_length_speed_exponent, 0.0, 1.0)
        if self.first_foot not in ("left", "right", "random"):
            raise ValueError(f"first_foot must be left, right or random, got {self.first_foot!r}")
