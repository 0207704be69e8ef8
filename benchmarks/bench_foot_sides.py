"""Left/right of the foot post-processing against the simulator's side map (run by hand).

Renders ``--frames`` frames of ``gaitnet simulate-dataset`` (``--config``, seed ``--seed``) and
runs :func:`gaitnet.segmentation.postprocess.foot_keypoints` on the true label map with the
sensor's depth, with the frame's gravity and without (``gravity_C=None``: the floor normal
from the no-IMU fit). Each foot found is compared with the majority side of the simulator's
side map under its mask. Printed per mode: feet found, agreeing, disagreeing, unknown, the
same for frames with one foot in view, how the sides were decided, the share of keypoints
with a 3-D point, and the post-processing's milliseconds per frame (one thread). Seeds 900+
were used to choose the rule's defaults; report other seeds.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_foot_sides.py --frames 50 --seed 1
"""

from __future__ import annotations

import os
import time
from collections import Counter
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.segmentation.postprocess import FootKeypointParams, foot_keypoints  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.dataset import simulate_frame  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SIDES = {1: "left", 2: "right"}


def side_agreement(
    frames, params: FootKeypointParams, use_gravity: bool
) -> tuple[dict[str, int], float]:
    """Counts of feet by outcome over ``frames`` (module docstring), and the seconds
    :func:`foot_keypoints` took."""
    c: Counter = Counter()
    seconds = 0.0
    for f in frames:
        g = f.gravity_C() if use_gravity else None
        tic = time.perf_counter()
        feet = foot_keypoints(f.render.label, f.depth_m, f.K, params, gravity_C=g)
        seconds += time.perf_counter() - tic
        single = len(feet) == 1
        for foot in feet:
            sides = f.render.instance[foot.mask]
            truth = SIDES.get(int(np.bincount(sides, minlength=3)[1:].argmax()) + 1)
            outcome = "agree" if foot.side == truth else "disagree"
            if foot.side == "unknown":
                outcome = "unknown"
            c["feet"] += 1
            c[outcome] += 1
            if single:
                c["single"] += 1
                c[f"single_{outcome}"] += 1
            c["points"] += sum(p is not None for p in foot.keypoints_C.values())
    return dict(c), seconds


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "sim" / "tiny.yaml")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cfg = load_config(SimConfig, args.config)
    frames = [simulate_frame(cfg, args.seed, i) for i in range(args.frames)]
    h, w = frames[0].depth_m.shape
    print(f"{len(frames)} frames {w}×{h} ({args.config.name}, seed {args.seed})")
    params = FootKeypointParams()
    for name, use_gravity in (("gravity", True), ("no gravity", False)):
        c, seconds = side_agreement(frames, params, use_gravity)
        n = max(c.get("feet", 0), 1)
        s = max(c.get("single", 0), 1)
        print(
            f"  {name:10s}: {c.get('feet', 0)} feet, agree {c.get('agree', 0)} "
            f"({100 * c.get('agree', 0) / n:.1f} %), disagree {c.get('disagree', 0)}, unknown "
            f"{c.get('unknown', 0)}; one foot in view: {c.get('single', 0)} feet, agree "
            f"{c.get('single_agree', 0)} ({100 * c.get('single_agree', 0) / s:.1f} %), "
            f"disagree {c.get('single_disagree', 0)}; keypoints with 3-D "
            f"{100 * c.get('points', 0) / (3 * n):.1f} %; "
            f"{1e3 * seconds / len(frames):.2f} ms per frame"
        )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
