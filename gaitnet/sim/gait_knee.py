"""The knee flexion each leg is designed to have while it carries the body (the pelvis height
follows from it: :func:`gaitnet.sim.gait_pelvis.design_heights`).

In cycle fractions ``φ`` of a leg (0 = its heel strike, 1 = its next heel strike): the knee
extends from ``terminal_swing_rad`` to ``extended_rad`` in the last ``_SWING_LEAD`` before the
heel strike, bumps to ``loading_rad`` in loading response (peak at ``_LOADING_PEAK``, extended
again by ``_LOADING_END``) and is extended in mid-stance; from ``_CARRY_FULL`` to
``_CARRY_END`` the leg stops counting (its knee may flex as the body falls toward the other
foot, whose heel strike ends the vault). Standing: both legs at ``extended_rad``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.sim.gait_plan import StepPlan, smoothstep7

__all__ = ["StanceKnee", "stance_knee"]

_LOADING_PEAK = 0.13  # loading-response knee peak
_LOADING_END = 0.36  # ... the stance knee is extended again
_SWING_LEAD = 0.10  # the landing leg starts to count this long before its heel strike
_CARRY_FULL = 0.25  # the stance leg counts fully until here,
_CARRY_END = 0.37  # ... and no more from here
_HS_EMPHASIS = 100.0  # extra weight around the heel strike (knee nearly straight),
_HS_EMPHASIS_WIDTH = 0.03  # ... over about this (standard deviation),
_MS_EMPHASIS = 10.0  # ... and around mid-stance
_MS_PHASE = 0.27
_MS_EMPHASIS_WIDTH = 0.04


@dataclass(frozen=True)
class StanceKnee:
    """Designed knee flexion [rad] of a leg while it carries the body (module docstring).

    ``extended_rad`` at heel strike, in mid-stance and while standing; ``loading_rad`` at the
    loading-response peak after a steady-length step (shorter steps flex less);
    ``terminal_swing_rad`` when the landing leg starts to count, ``_SWING_LEAD`` of the cycle
    before its heel strike; ``trailing_rad`` when the stance leg stops counting.
    """

    extended_rad: float
    loading_rad: float
    terminal_swing_rad: float
    trailing_rad: float


def _loading_bump(u: np.ndarray) -> np.ndarray:
    """``(u/u_p)^a ((1 − u)/(1 − u_p))^c`` on [0, 1] (0 outside): peak 1 at ``u_p``, C³ at 1."""
    a = 2.0
    u_p = _LOADING_PEAK / _LOADING_END
    c = a * (1.0 - u_p) / u_p
    u = np.clip(u, 0.0, 1.0)
    return (u / u_p) ** a * ((1.0 - u) / (1.0 - u_p)) ** c


def stance_knee(plan: StepPlan, t: np.ndarray, knee: StanceKnee) -> tuple[np.ndarray, np.ndarray]:
    """Designed knee flexion [rad] and weight ≥ 0 of each leg (n, 2) on the grid ``t``.

    With the cycle phase ``φ`` of a stance (0 at its heel strike ``h_k``, 1 two steps later):
    the weight rises from 0 at ``φ = −_SWING_LEAD`` to 1 half-way to the heel strike (terminal
    swing: the knee extends from ``terminal_swing_rad`` to ``extended_rad``), is raised
    around the heel strike and mid-stance (``_HS_EMPHASIS``, ``_MS_EMPHASIS``: the knee is
    nearly straight there), and falls to 0 from ``_CARRY_FULL`` to ``_CARRY_END`` (the knee
    design bends toward ``trailing_rad``); the loading bump peaks at ``_LOADING_PEAK``. Step
    length scales the bump, the terminal-swing flexion and the emphasis (the closing step
    lands beside the other foot). The standing stances at the start weigh 1 until they stop
    counting like any stance, the final ones until the end. The knee is NaN where the weight
    is 0.
    """
    h, arc = plan.step_hs, plan.step_arc
    n_steps = len(h) - 1
    first = int(plan.step_side[0])
    theta = np.full((len(t), 2), np.nan)
    weight = np.zeros((len(t), 2))
    for side in (0, 1):
        # (heel-strike step index, loading amplitude) per stance; index −1: virtual h_{−1}
        rows = [(-1 if side == first else 0, 0.0)]
        for k in range(1, n_steps + 1):
            if int(plan.step_side[k - 1]) == side:
                scale = float(np.clip((arc[k] - arc[k - 1]) / plan.steady_step_m, 0.0, 1.0))
                rows.append((k, scale))
        for i, (k, scale) in enumerate(rows):
            h_k = h[k] if k >= 0 else h[0] - (h[1] - h[0])
            step = h[k + 1] - h_k if k + 1 <= n_steps else h[k] - h[k - 1]
            phi = (t - h_k) / (2.0 * step)
            lead = _SWING_LEAD * max(scale, 0.2)  # a short step lands more gently
            w = np.ones_like(t)
            if i > 0:  # landing: rises in terminal swing, emphasised around the heel strike
                w *= smoothstep7((phi + lead) / (0.5 * lead))
                w *= 1.0 + scale * _HS_EMPHASIS * np.exp(-0.5 * (phi / _HS_EMPHASIS_WIDTH) ** 2)
                w *= 1.0 + scale * _MS_EMPHASIS * np.exp(
                    -0.5 * ((phi - _MS_PHASE) / _MS_EMPHASIS_WIDTH) ** 2
                )
            late = smoothstep7((phi - _CARRY_FULL) / (_CARRY_END - _CARRY_FULL))
            final = i + 1 == len(rows)
            if not final:  # stops counting in terminal stance
                w *= 1.0 - late
            m = w > 0.0
            swing = np.clip(-phi[m] / lead, 0.0, 1.0) if i > 0 else 0.0
            flex = scale * (knee.terminal_swing_rad - knee.extended_rad)
            th = knee.extended_rad + flex * (1.0 - smoothstep7(1.0 - swing))
            if not final:
                th = th + (knee.trailing_rad - knee.extended_rad) * late[m]
            bump = scale * _loading_bump(phi[m] / _LOADING_END)
            theta[m, side] = th + (knee.loading_rad - knee.extended_rad) * bump
            weight[m, side] = w[m]
    return theta, weight
