"""The instep marker's path from heel off to the next foot flat, in generated walks.

The pipeline fills a foot's unseen swing from a template of this path
(:mod:`gaitnet.pipeline.swing_fill`); this module measures it on the simulator's walks so the
template's numbers can be re-derived (``data/derive_swing_template.py``, and a test that
checks the committed table against a fresh derivation).

For one foot between heel off ``HO`` of stance ``i`` and foot flat ``FF'`` of stance
``i + 1``, with ``m(t)`` the instep marker (:meth:`gaitnet.sim.gait.Walk.marker_points`),
``τ = (t − HO) / (FF' − HO)``, ``d = m(FF') − m(HO)`` and ``u`` the horizontal unit vector of
``d``:

- progress ``ρ(τ) = (m(t) − m(HO))·u / |d_xy|`` (0 → 1 along the step);
- lift ``λ(τ) = (m_z(t) − m_z(HO) − ρ(τ) d_z) / H`` (height above the straight line between
  the two rests, as a fraction of the body height ``H``).
"""

from __future__ import annotations

import numpy as np

from gaitnet.sim.gait import GaitConfig, Walk, generate_walk
from gaitnet.sim.scene import SIDES
from gaitnet.sim.subject import sample_subject

__all__ = ["derive_swing_template", "swing_profiles"]


def swing_profiles(walk: Walk, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(progress, lift, fraction)`` of every swing of ``walk`` (module docstring) at ``tau``:
    progress and lift (m, len(tau)); fraction (m,): ``(FF' − HO) / (FF' − FF)``, the share of
    the gait cycle (foot flat to foot flat) that heel off precedes the next foot flat by."""
    tau = np.asarray(tau, dtype=np.float64)
    progress, lift, fraction = [], [], []
    for s, side in enumerate(SIDES):
        ev = walk.events[side]
        for i in range(len(ev.ho_s) - 1):
            ff0, ho, ff1 = ev.ff_s[i], ev.ho_s[i], ev.ff_s[i + 1]
            if not np.isfinite([ff0, ho, ff1]).all() or not ff0 < ho < ff1:
                continue
            m = walk.marker_points(ho + tau * (ff1 - ho))[:, s]
            d = m[-1] - m[0]
            step = float(np.hypot(d[0], d[1]))
            if step < 0.2:  # a shuffle, not a swing
                continue
            u = np.array([d[0], d[1], 0.0]) / step
            rho = (m - m[0]) @ u / step
            progress.append(rho)
            lift.append((m[:, 2] - m[0, 2] - rho * d[2]) / walk.subject.height_m)
            fraction.append((ff1 - ho) / (ff1 - ff0))
    if not progress:
        return np.empty((0, len(tau))), np.empty((0, len(tau))), np.empty(0)
    return np.array(progress), np.array(lift), np.array(fraction)


def derive_swing_template(
    tau: np.ndarray,
    speeds_mps: tuple[float, ...] = (0.8, 1.0, 1.2, 1.4, 1.6),
    subjects: int = 6,
    seed: int = 0,
    walk_length_m: float = 10.0,
) -> dict[str, np.ndarray]:
    """Mean and spread of :func:`swing_profiles` over ``subjects`` random subjects walking
    ``walk_length_m`` at each of ``speeds_mps`` (the simulator's default gait otherwise):
    ``progress``, ``lift`` (len(tau)), their standard deviations ``progress_std``,
    ``lift_std``, and ``fraction`` (mean, std)."""
    rng = np.random.default_rng(seed)
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for speed in speeds_mps:
        cfg = GaitConfig(speed_mps=float(speed), walk_length_m=float(walk_length_m))
        for _ in range(subjects):
            walk = generate_walk(sample_subject(rng), cfg, rng)
            parts.append(swing_profiles(walk, tau))
    progress = np.concatenate([p for p, _, _ in parts])
    lift = np.concatenate([q for _, q, _ in parts])
    fraction = np.concatenate([f for _, _, f in parts])
    return {
        "progress": progress.mean(axis=0),
        "progress_std": progress.std(axis=0),
        "lift": lift.mean(axis=0),
        "lift_std": lift.std(axis=0),
        "fraction": np.array([fraction.mean(), fraction.std()]),
        "swings": np.array([len(progress)]),
    }
