"""How one subject walks at one speed: speed laws, per-subject style, postural sway.

Speed laws (docs/references.md, *Simulator realism: gait*), ``v`` in m/s, ``v₀ = 1.3 m/s``:
- stance share of the cycle ``0.62 − 0.057 (v − 1.0)`` (62 % at 1.0 m/s, 58 % at 1.7 m/s;
  Hebenstreit et al. 2015, Perry & Burnfield 2010), so double support ``2 (stance − 0.5)``
  falls from 24 % to 16 %;
- step length ``ratio · H · (v / v₀)^exponent`` (cadence = speed / step length);
- pelvic rotation amplitude ``∝ (v / v₀)``, obliquity ``∝ (v / v₀)^0.5``, lateral excursion
  ``∝ (v / v₀)^−0.5`` (rotation and obliquity grow with speed, the side-to-side excursion
  shrinks: Bruijn et al. 2008, Orendurff et al. 2004); the vertical excursion follows from the
  legs (:mod:`gaitnet.sim.gait_pelvis`).

Per-subject style (:class:`GaitStyle`): standard-normal scores drawn once per subject (so all
walks of one subject share them), scaled by ``gait.variability`` and the between-subject spreads
of :data:`STYLE_SPREAD` (cadence at a given speed ±5 %, stance ±1 % of the cycle, pelvic
rotation / obliquity ±25 %, lateral excursion ±20 %, standing width ±3.5 cm).

Postural sway (:func:`sample_sway`): while standing the pelvis is never still; its horizontal
position drifts by a few millimetres (RMS) with most power between 0.1 and 1 Hz,
anterior-posterior larger than medio-lateral (Prieto et al. 1996; Winter 1995). Modelled as a
sum of sinusoids with random phases and log-uniform frequencies in that band, amplitude ∝
``f^−0.5``, scaled to the configured RMS. The feet do not move; the legs follow by IK.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "STYLE_SPREAD",
    "GaitStyle",
    "SpeedLaws",
    "sample_gait_style",
    "Sway",
    "sample_sway",
    "speed_laws",
]

REFERENCE_SPEED_MPS = 1.3
#: Between-subject standard deviations at ``gait.variability`` 1 (module docstring).
STYLE_SPREAD = {
    "step_ratio": 0.05,  # relative (cadence at a given speed; Oberg et al. 1993)
    "stance": 0.01,  # cycle fraction (Hebenstreit et al. 2015)
    "rotation": 0.25,  # relative (Bruijn et al. 2008; Crosbie et al. 1997)
    "obliquity": 0.25,  # relative
    "lateral": 0.20,  # relative (Orendurff et al. 2004)
    "stand_width": 0.035,  # m (natural stance 16.5 ± 3.8 cm; Kim et al. 2014)
}
STAND_WIDTH_M = 0.165  # natural standing distance between the feet (Kim et al. 2014)
STAND_GAP_M = 0.03  # at least this much floor between standing shoes
_STANCE_AT_1MPS, _STANCE_SLOPE = 0.62, -0.04 / 0.7
_SWAY_BAND_HZ = (0.1, 1.0)
_SWAY_COMPONENTS = 12


@dataclass(frozen=True)
class GaitStyle:
    """A subject's own gait: standard-normal scores (clipped to ±2), 0 = the average walker."""

    step_ratio: float = 0.0
    stance: float = 0.0
    rotation: float = 0.0
    obliquity: float = 0.0
    lateral: float = 0.0
    stand_width: float = 0.0


def sample_gait_style(rng: np.random.Generator) -> GaitStyle:
    """Six clipped standard-normal scores (one draw of six numbers)."""
    z = np.clip(rng.normal(size=6), -2.0, 2.0)
    return GaitStyle(*(float(v) for v in z))


@dataclass(frozen=True)
class SpeedLaws:
    """The speed- and subject-dependent values of one walk (fractions, m, rad)."""

    stance_fraction: float
    step_m: float
    rotation_rad: float
    obliquity_rad: float
    lateral_m: float
    stand_width_m: float


def speed_laws(
    *,
    speed_mps: float,
    height_m: float,
    style: GaitStyle,
    variability: float,
    stance_fraction: float | None,
    step_ratio: float,
    step_exponent: float,
    rotation_rad: float,
    obliquity_rad: float,
    lateral_m: float,
    stand_width_m: float | None,
    shoe_width_m: float,
) -> SpeedLaws:
    """Resolve the module docstring's laws for one subject (``style``) and speed.

    ``stance_fraction`` / ``stand_width_m`` None: from the speed law / the natural stance width
    (plus the subject's style); the amplitudes are the average walker's at 1.3 m/s. The standing
    width never lets the shoes come closer than :data:`STAND_GAP_M`.
    """
    s = STYLE_SPREAD
    ratio = speed_mps / REFERENCE_SPEED_MPS
    if stance_fraction is None:
        stance = _STANCE_AT_1MPS + _STANCE_SLOPE * (speed_mps - 1.0)
        stance += variability * s["stance"] * style.stance
    else:
        stance = stance_fraction
    step = step_ratio * height_m * ratio**step_exponent
    step *= 1.0 + variability * s["step_ratio"] * style.step_ratio
    if stand_width_m is None:
        width = STAND_WIDTH_M + variability * s["stand_width"] * style.stand_width
    else:
        width = stand_width_m
    return SpeedLaws(
        stance_fraction=float(np.clip(stance, 0.55, 0.68)),
        step_m=float(step),
        rotation_rad=float(
            rotation_rad * ratio * max(0.0, 1.0 + variability * s["rotation"] * style.rotation)
        ),
        obliquity_rad=float(
            obliquity_rad
            * ratio**0.5
            * max(0.0, 1.0 + variability * s["obliquity"] * style.obliquity)
        ),
        lateral_m=float(
            lateral_m * ratio**-0.5 * max(0.0, 1.0 + variability * s["lateral"] * style.lateral)
        ),
        stand_width_m=float(max(width, shoe_width_m + STAND_GAP_M)),
    )


@dataclass(frozen=True, eq=False)
class Sway:
    """Postural sway of the pelvis: ``sway(t)`` → ``(n, 2)`` [m] (anterior-posterior,
    medio-lateral), a sum of sinusoids per axis (module docstring)."""

    freq_hz: np.ndarray  # (2, k)
    phase: np.ndarray  # (2, k)
    amp_m: np.ndarray  # (2, k)

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        arg = 2.0 * np.pi * t[:, None, None] * self.freq_hz + self.phase
        return np.sum(np.sin(arg) * self.amp_m, axis=-1)


def sample_sway(rng: np.random.Generator, rms_ap_m: float, rms_ml_m: float) -> Sway | None:
    """Draw the sway: per axis :data:`_SWAY_COMPONENTS` log-uniform frequencies in
    :data:`_SWAY_BAND_HZ`, uniform phases, amplitudes ∝ ``f^−0.5`` scaled so that the RMS (over
    a long time) is the given one. Both RMS 0: None, nothing drawn."""
    if rms_ap_m <= 0.0 and rms_ml_m <= 0.0:
        return None
    lo, hi = np.log(_SWAY_BAND_HZ[0]), np.log(_SWAY_BAND_HZ[1])
    f = np.exp(rng.uniform(lo, hi, size=(2, _SWAY_COMPONENTS)))
    phase = rng.uniform(0.0, 2.0 * np.pi, size=(2, _SWAY_COMPONENTS))
    amp = f**-0.5
    rms = np.array([rms_ap_m, rms_ml_m])[:, None]
    amp = amp * rms / np.sqrt(0.5 * np.sum(amp**2, axis=1, keepdims=True))
    return Sway(f, phase, amp)
