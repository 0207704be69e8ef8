"""The kinds of synthetic clips in the motion predictor's training mix (issue 12).

:mod:`gaitnet.sim.amass_clips` writes one clip per (subject, walk) draw; each draw first picks a
clip KIND with the weights of :class:`gaitnet.sim.amass_clips.SyntheticWalksConfig`
(``mix_*`` keys), then builds the clip's motion here:

* ``walk``: one whole walk (standing start, gait initiation, steady walking with an optional
  turn spread over the walk, stopping, standing end): the clips the model was first trained on;
* ``sharp_turn``: a walk whose turn (``sharp_turn_range_deg``) happens within a short arc
  (``turn_arc_range_m``) at a random point of the walk;
* ``speed_change``: a walk whose speed drifts smoothly from the drawn speed to another one in
  the simulator's range 0.6–1.7 m/s, at least ``min_speed_change_mps`` away;
* ``pause``: two walks of the same subject joined by a standing pause: the second walk starts
  where the first stopped, facing its way, at a speed of its own; the standing poses are
  cross-faded (slerp) over ``_BLEND_S`` while both stand still. ``pause_range_s`` is the
  standing time added between the walks; the body stands still about 2 s longer (the
  simulator's settling at the end of one walk and before the next);
* ``standing``: standing still with the simulator's postural sway for ``standing_range_s``
  (the standing start of a walk, cut before the first step).

Every walk may be imperfect: step-length and step-time asymmetry between the feet drawn from
``asymmetry_range`` (random sign) on top of the step-to-step variability of the gait config.
The random draws of a clip come from its subject's generator in a fixed order; with the default
config (only ``walk``, no asymmetry) nothing extra is drawn, so the clips of earlier versions
are reproduced.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from gaitnet.motion.heading import heading_angle
from gaitnet.sim.gait import GaitConfig, Walk, generate_walk
from gaitnet.sim.gait_plan import WalkVariation, smoothstep7
from gaitnet.sim.subject import Subject

if TYPE_CHECKING:
    from gaitnet.sim.amass_clips import SyntheticWalksConfig

__all__ = [
    "CLIP_KINDS",
    "ClipMotion",
    "choose_kind",
    "clip_motion",
    "join_with_pause",
    "sample_gait_config",
]

#: Clip kinds, in the order of their ``mix_*`` weights.
CLIP_KINDS: tuple[str, ...] = ("walk", "sharp_turn", "speed_change", "pause", "standing")
#: Simulator's walking speed range [m/s] (GaitConfig.speed_mps).
SPEED_LIMITS_MPS = (0.6, 1.7)
_BLEND_S = 0.5

Band = tuple[float, float]
Pose = tuple[np.ndarray, np.ndarray, np.ndarray]  # root_orient (T,3), trans (T,3), joint_aa


@dataclass(frozen=True)
class ClipMotion:
    """A clip's motion as a function of the sampling rate, and what the manifest records."""

    sample: Callable[[float], Pose]
    duration_s: float
    skeleton_rest_joints: np.ndarray
    speed_mps: float
    turn_deg: float
    walk_length_m: float
    speed_change: float = 0.0
    pause_s: float = 0.0
    variation: WalkVariation | None = None  # of the (first) walk


def _uniform_in_bands(rng: np.random.Generator, bands: Iterable[Band]) -> float:
    """Uniform over the union of disjoint intervals (weighted by their widths)."""
    bands = list(bands)
    widths = np.array([hi - lo for lo, hi in bands])
    u = float(rng.uniform(0.0, widths.sum()))
    for (lo, _), w in zip(bands, widths, strict=True):
        if u <= w:
            return float(lo + u)
        u -= float(w)
    return float(bands[-1][1])


def sample_gait_config(
    rng: np.random.Generator, cfg: SyntheticWalksConfig, speed_bands: tuple[Band, ...]
) -> GaitConfig:
    """A random :class:`GaitConfig` for one walk (speed from ``speed_bands``).

    Style parameters the installed generator does not have are left out (the simulator
    evolves; the draws from ``rng`` stay the same either way).
    """
    turn = 0.0
    if rng.uniform() < cfg.turn_probability:
        turn = float(rng.uniform(*cfg.turn_range_deg)) * float(rng.choice([-1.0, 1.0]))
    rng.uniform(0.58, 0.64)  # was the stance fraction: now the speed law's (kept: same draws)
    heel_off = float(rng.uniform(0.34, 0.42))
    values: dict[str, float] = {
        "speed_mps": _uniform_in_bands(rng, speed_bands),
        "walk_length_m": float(rng.uniform(*cfg.walk_length_range_m)),
        "step_width_m": float(rng.uniform(0.06, 0.14)),
        "step_length_cv": float(rng.uniform(*cfg.step_cv_range)),
        "step_time_cv": float(rng.uniform(*cfg.step_cv_range)),
        "step_width_std_m": float(rng.uniform(*cfg.step_width_std_range_m)),
        "stand_start_s": float(rng.uniform(*cfg.stand_range_s)),
        "stand_end_s": float(rng.uniform(*cfg.stand_range_s)),
        "turn_deg": turn,
        "toe_out_deg": float(rng.uniform(0.0, 10.0)),
        # Style parameters, varied around the simulator's defaults where the generator has them.
        "pelvis_vertical_m": float(rng.uniform(0.015, 0.025)),
        "pelvis_lateral_m": float(rng.uniform(0.015, 0.025)),
        "pelvis_rotation_deg": float(rng.uniform(3.0, 5.0)),
        "pelvis_obliquity_deg": float(rng.uniform(3.0, 5.0)),
        "pelvis_tilt_deg": float(rng.uniform(1.0, 3.0)),
        "toe_clearance_m": float(rng.uniform(0.01, 0.02)),
        "heel_strike_pitch_deg": float(rng.uniform(10.0, 15.0)),
        "toe_off_pitch_deg": float(rng.uniform(30.0, 40.0)),
        "heel_off_fraction": heel_off,
        "min_heel_off_fraction": 0.30,
    }
    known = {f.name for f in fields(GaitConfig)}
    return GaitConfig(**{k: v for k, v in values.items() if k in known})


def choose_kind(rng: np.random.Generator, weights: dict[str, float]) -> str:
    """A kind drawn with ``weights``; no draw when only one kind has a positive weight."""
    kinds = [k for k in CLIP_KINDS if weights.get(k, 0.0) > 0]
    if len(kinds) == 1:
        return kinds[0]
    p = np.array([weights[k] for k in kinds], dtype=np.float64)
    return kinds[int(rng.choice(len(kinds), p=p / p.sum()))]


def _times(duration_s: float, fps: float) -> np.ndarray:
    return np.arange(int(math.floor(duration_s * fps + 1e-9)) + 1) / fps


def _walk_sampler(walk: Walk, t_end: float | None = None) -> Callable[[float], Pose]:
    def sample(fps: float) -> Pose:
        return walk.smpl_pose(_times(walk.duration_s if t_end is None else t_end, fps))

    return sample


def _variation(
    rng: np.random.Generator, cfg: SyntheticWalksConfig, kind: str, gait: GaitConfig
) -> tuple[WalkVariation | None, GaitConfig]:
    """The kind's within-walk variation (draws in a fixed order) and the adjusted gait."""
    values: dict[str, float | None] = {}
    lo, hi = cfg.asymmetry_range
    if hi > 0:
        for name in ("step_length_asymmetry", "step_time_asymmetry"):
            values[name] = float(rng.uniform(lo, hi)) * float(rng.choice([-1.0, 1.0]))
    if kind == "sharp_turn":
        turn = float(rng.uniform(*cfg.sharp_turn_range_deg)) * float(rng.choice([-1.0, 1.0]))
        values["turn_arc_m"] = float(rng.uniform(*cfg.turn_arc_range_m))
        values["turn_at"] = float(rng.uniform(0.3, 0.7))
        gait = replace(gait, turn_deg=turn)
    elif kind == "speed_change":
        v0, gap = gait.speed_mps, cfg.min_speed_change_mps
        slower = (SPEED_LIMITS_MPS[0], v0 - gap) if v0 - gap > SPEED_LIMITS_MPS[0] else None
        faster = (v0 + gap, SPEED_LIMITS_MPS[1]) if v0 + gap < SPEED_LIMITS_MPS[1] else None
        band = [b for b in (slower, faster) if b is not None]
        target = float(rng.uniform(*band[int(rng.integers(len(band)))]))
        values["speed_change"] = min(max(target / v0 - 1.0, -0.6), 1.0)
    if not values:
        return None, gait
    return WalkVariation(**values), gait  # type: ignore[arg-type]


def clip_motion(
    rng: np.random.Generator,
    subject: Subject,
    cfg: SyntheticWalksConfig,
    kind: str,
    draw_gait: Callable[[], GaitConfig],
) -> ClipMotion:
    """Build one clip of ``kind`` (module docstring); may raise if the generator rejects it."""
    gait = draw_gait()
    if kind == "standing":
        stand = float(rng.uniform(*cfg.standing_range_s))
        walk = generate_walk(subject, replace(gait, stand_start_s=stand), rng)
        return ClipMotion(
            _walk_sampler(walk, stand), stand, walk.skeleton.rest_joints, 0.0, 0.0, 0.0
        )
    if kind == "pause":
        pause = float(rng.uniform(*cfg.pause_range_s))
        half = max(1.0, 0.5 * pause + 0.5 * _BLEND_S)
        var1, gait1 = _variation(rng, cfg, "walk", replace(gait, stand_end_s=half))
        first = generate_walk(subject, gait1, rng, variation=var1)
        var2, gait2 = _variation(rng, cfg, "walk", replace(draw_gait(), stand_start_s=half))
        second = generate_walk(subject, gait2, rng, variation=var2)
        duration = first.duration_s + second.duration_s - _BLEND_S

        def sample(fps: float) -> Pose:
            a = first.smpl_pose(_times(first.duration_s, fps))
            b = second.smpl_pose(_times(second.duration_s, fps))
            return join_with_pause(a, b, max(2, round(_BLEND_S * fps)))

        return ClipMotion(
            sample, duration, first.skeleton.rest_joints, gait1.speed_mps,
            gait1.turn_deg + gait2.turn_deg, gait1.walk_length_m + gait2.walk_length_m,
            pause_s=pause, variation=var1,
        )  # fmt: skip
    variation, gait = _variation(rng, cfg, kind, gait)
    walk = generate_walk(subject, gait, rng, variation=variation)
    return ClipMotion(
        _walk_sampler(walk), walk.duration_s, walk.skeleton.rest_joints, gait.speed_mps,
        gait.turn_deg, gait.walk_length_m,
        speed_change=0.0 if variation is None else variation.speed_change, variation=variation,
    )  # fmt: skip


def join_with_pause(a: Pose, b: Pose, n_blend: int) -> Pose:
    """Clip ``a`` then clip ``b`` (both standing at the junction), cross-faded over ``n_blend``.

    ``b`` is rotated about the vertical and shifted so that it starts where ``a`` ends, facing
    the same way (heading of the last / first root orientation; the rest pelvis is the origin
    of the simulator's skeleton, so rotating ``trans`` rotates the body). Over the last
    ``n_blend`` frames of ``a`` and the first of ``b`` the rotations are slerped and the
    translation interpolated with a smoothstep weight.
    """
    root_a, trans_a, aa_a = a
    root_b, trans_b, aa_b = b
    yaw = float(heading_angle(root_a[-n_blend]) - heading_angle(root_b[0]))
    Rz = Rotation.from_rotvec([0.0, 0.0, yaw])
    root_b = (Rz * Rotation.from_rotvec(root_b)).as_rotvec()
    trans_b = Rz.apply(trans_b)
    trans_b[:, :2] += trans_a[-n_blend, :2] - trans_b[0, :2]
    w = smoothstep7(np.linspace(0.0, 1.0, n_blend))
    tracks_a = np.concatenate([root_a[-n_blend:, None], aa_a[-n_blend:]], axis=1)
    tracks_b = np.concatenate([root_b[:n_blend, None], aa_b[:n_blend]], axis=1)
    ra, rb = (
        Rotation.from_rotvec(tracks_a.reshape(-1, 3)),
        Rotation.from_rotvec(tracks_b.reshape(-1, 3)),
    )
    wj = np.repeat(w, tracks_a.shape[1])[:, None]
    mixed = (ra * Rotation.from_rotvec(wj * (ra.inv() * rb).as_rotvec())).as_rotvec()
    mixed = mixed.reshape(tracks_a.shape)
    trans_mid = (1.0 - w)[:, None] * trans_a[-n_blend:] + w[:, None] * trans_b[:n_blend]
    root = np.concatenate([root_a[:-n_blend], mixed[:, 0], root_b[n_blend:]])
    aa = np.concatenate([aa_a[:-n_blend], mixed[:, 1:], aa_b[n_blend:]])
    trans = np.concatenate([trans_a[:-n_blend], trans_mid, trans_b[n_blend:]])
    return root, trans, aa
