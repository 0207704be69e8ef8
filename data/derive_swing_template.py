"""Derive the swing template of ``gaitnet infer``'s gap fill from the gait generator.

    python data/derive_swing_template.py [--subjects 6] [--seed 0]

Prints the mean progress, lift and sideways (outwards) path from heel off to the next foot
flat (:mod:`gaitnet.sim.swing_profile`) of the point the pose correction is given for a foot,
the segmenter's keypoint as the correction models it (``KEYPOINT_OFFSET_M`` from the ankle, for
a body of ``REFERENCE_HEIGHT_M``, :mod:`gaitnet.pipeline.config`), over random subjects
walking 10 m at 0.8–1.6 m/s, at the 21 template points, as the arrays ``SWING_PROGRESS``,
``SWING_LIFT`` and ``SWING_SIDEWAYS`` of
``gaitnet/pipeline/swing_fill.py``, with their swing-to-swing spread and the heel-off share of
the gait cycle; then the line ``span = a + b · cycle`` through the spans that lay the committed
template best over each swing at 0.6–1.7 m/s (``SWING_SPAN_OFFSET_S``,
``SWING_SPAN_PER_CYCLE``: the defaults of ``pipeline.swing_span_offset_s`` and
``swing_span_per_cycle``), and the line ``span = c + d · (FF' − FF_c)`` through the same spans,
``FF_c`` the other foot's foot flat between (``SWING_SPAN_CONTRALATERAL_OFFSET_S``,
``SWING_SPAN_PER_CONTRALATERAL``: the defaults of ``pipeline.swing_span_contralateral_offset_s``
and ``swing_span_per_contralateral``). The committed values are this script's output with the
defaults.
"""

from __future__ import annotations

import argparse

import numpy as np

from gaitnet.pipeline.config import KEYPOINT_OFFSET_M, REFERENCE_HEIGHT_M
from gaitnet.pipeline.swing_fill import SWING_PROGRESS, SWING_TAU
from gaitnet.sim.swing_profile import ShoePoint, derive_swing_span, derive_swing_template


def keypoint() -> ShoePoint:
    """The segmenter's keypoint as the pose correction models it (``KEYPOINT_OFFSET_M`` from
    the ankle, for a body of ``REFERENCE_HEIGHT_M``)."""
    return ShoePoint.from_smpl_offset(KEYPOINT_OFFSET_M, REFERENCE_HEIGHT_M)


def _row(values: np.ndarray) -> str:
    return ", ".join(f"{v:.4f}" for v in values)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--subjects", type=int, default=6, help="subjects per speed (default 6)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.subjects < 1:
        ap.error("--subjects must be at least 1")
    t = derive_swing_template(SWING_TAU, subjects=args.subjects, seed=args.seed, point=keypoint())
    print(f"{int(t['swings'][0])} swings")
    print(f"SWING_PROGRESS = [{_row(t['progress'])}]")
    print(f"  spread (std)   [{_row(t['progress_std'])}]")
    print(f"SWING_LIFT = [{_row(t['lift'])}]")
    print(f"  spread (std)   [{_row(t['lift_std'])}]")
    print(f"SWING_SIDEWAYS = [{_row(t['sideways'])}]")
    print(f"  spread (std)   [{_row(t['sideways_std'])}]")
    mean, std = t["fraction"]
    print(f"heel off to next foot flat: {mean:.3f} ± {std:.3f} of the gait cycle")
    span = derive_swing_span(SWING_TAU, SWING_PROGRESS, seed=args.seed, point=keypoint())
    print(
        f"span over {int(span['swings'])} swings at 0.6–1.7 m/s: "
        f"SWING_SPAN_OFFSET_S = {span['offset_s']:.3f}, "
        f"SWING_SPAN_PER_CYCLE = {span['per_cycle']:.3f} "
        f"(residual {span['residual_s']:.3f} s; a share of the cycle alone: "
        f"{span['proportional_residual_s']:.3f} s)"
    )
    print(
        f"span from the other foot's foot flat over {int(span['contralateral_swings'])} swings: "
        f"SWING_SPAN_CONTRALATERAL_OFFSET_S = {span['contralateral_offset_s']:.3f}, "
        f"SWING_SPAN_PER_CONTRALATERAL = {span['per_contralateral']:.3f} "
        f"(residual {span['contralateral_residual_s']:.3f} s; the cycle's line on the same "
        f"swings: {span['cycle_residual_same_s']:.3f} s)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
