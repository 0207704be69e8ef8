"""The swing fill of ``gaitnet infer`` (``pipeline.gap_fill: swing``) on real and simulated walks.

For each clip in the AMASS ``*_poses.npz`` format (real motion capture, e.g. the CMU walks, and
walks of the simulator's gait generator written in the same format), resampled to 30 frames/s:

1. forward kinematics with the clip's rest joints (the built-in skeleton of ``--height`` when
   the file has none; ``--height`` is also the body height the lift is scaled by) gives a
   mid-foot point per side, half-way between the ankle and the SMPL foot joint (the ball of
   the foot): the same point on every clip;
2. the foot "rests" where that point's horizontal speed stays below ``--rest-speed`` for at
   least 3 frames; the rests stand in for the filter's stance landmarks and the point in the
   rest frames for the measured foot, everything between two rests is unseen;
3. :func:`gaitnet.pipeline.swing_fill.swing_fill` fills the unseen frames, and the fill is
   compared with the true point there. A straight line in time between the two rests (the
   simplest fill) is scored beside it.

    python benchmarks/bench_swing_fill.py REAL/*_poses.npz [--simulated 12]

(``REAL``: walking clips of the CMU Graphics Lab Motion Capture Database, mocap.cs.cmu.edu,
in AMASS's SMPL+H G layout, as AMASS distributes them; docs/pipeline.md has the figures.)

Prints the mean and 90th percentile of the fill's error per source, and the share of the
cycle from the end of a rest to the start of the next (over one rest-to-rest cycle), to set
beside the template's span (``pipeline.swing_span_offset_s + swing_span_per_cycle · cycle``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from gaitnet.motion.amass import load_amass_clip
from gaitnet.motion.skeleton import builtin_skeleton, forward_kinematics, from_rest_joints
from gaitnet.pipeline.config import PipelineParams
from gaitnet.pipeline.swing_fill import swing_fill
from gaitnet.training.scripts import ScriptParser
from gaitnet.vio.gait import SIDES
from gaitnet.vio.result import StanceFoot

FPS = 30.0
ANKLES, FEET = (5, 6), (7, 8)  # joint order of gaitnet.motion.skeleton.SMPL_JOINT_INDICES


def _rests(
    speed: np.ndarray, below: float, min_frames: int = 3, bridge: int = 3
) -> list[tuple[int, int]]:
    """``(first, last)`` frames of each rest; rests split by at most ``bridge`` moving frames
    (marker noise, a slip) are one."""
    still = np.flatnonzero(speed < below)
    runs: list[list[int]] = []
    for k in still.tolist():
        if runs and k - runs[-1][1] <= bridge + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    return [(a, b) for a, b in runs if b - a + 1 >= min_frames]


def score_clip(path: Path, height_m: float, rest_speed: float) -> dict[str, list[float]]:
    clip = load_amass_clip(path, fps=FPS)
    skel = (
        from_rest_joints(clip.rest_joints)
        if clip.rest_joints is not None
        else builtin_skeleton(height_m)
    )
    J = forward_kinematics(skel, clip.root_orient, clip.trans, clip.joint_aa)
    t = np.arange(clip.n_frames) / FPS
    out: dict[str, list[float]] = {"fill": [], "line": [], "fraction": []}
    measured = np.full((clip.n_frames, 2, 3), np.nan)
    stance: list[StanceFoot] = []
    truth = np.empty((clip.n_frames, 2, 3))
    for s, side in enumerate(SIDES):
        p = 0.5 * (J[:, ANKLES[s]] + J[:, FEET[s]])
        truth[:, s] = p
        speed = np.r_[np.inf, np.hypot(*np.diff(p[:, :2], axis=0).T) * FPS]
        rests = _rests(speed, rest_speed)
        for a, b in rests:
            measured[a : b + 1, s] = p[a : b + 1]
            stance.append(StanceFoot(len(stance), side, t[a], t[b], p[a, :2], np.zeros(2), 1))
        for (a0, b0), (a1, _) in zip(rests, rests[1:], strict=False):
            out["fraction"].append((t[a1] - t[b0]) / (t[a1] - t[a0]))
    filled = swing_fill(t, measured, stance, height_m, **PipelineParams().swing_timing())
    for s in range(2):
        unseen = np.isnan(measured[:, s, 0])
        use = unseen & np.isfinite(filled[:, s, 0])
        out["fill"] += np.linalg.norm(filled[use, s] - truth[use, s], axis=1).tolist()
        # the straight line in time between the neighbouring measured frames
        seen = np.flatnonzero(~unseen)
        line = np.stack(
            [np.interp(np.flatnonzero(use), seen, truth[seen, s, c]) for c in range(3)], axis=1
        )
        out["line"] += np.linalg.norm(line - truth[use, s], axis=1).tolist()
    return out


def _simulated_clips(n: int, folder: Path, seed: int) -> list[Path]:
    from gaitnet.sim.amass_clips import walk_to_amass, write_amass_poses
    from gaitnet.sim.gait import GaitConfig, generate_walk
    from gaitnet.sim.subject import sample_subject

    rng = np.random.default_rng(seed)
    paths = []
    for k in range(n):
        speed = float(rng.uniform(0.9, 1.45))  # the CMU walks' range
        walk = generate_walk(sample_subject(rng), GaitConfig(speed_mps=speed), rng)
        path = folder / f"sim_{k:02d}_poses.npz"
        paths.append(write_amass_poses(path, walk_to_amass(walk, 120.0)))
    return paths


def _report(name: str, scores: dict[str, list[float]]) -> None:
    if not scores["fill"]:
        print(f"{name:10s} no swing between two rests was found")
        return
    fill, line = np.array(scores["fill"]), np.array(scores["line"])
    frac = np.array(scores["fraction"])
    print(
        f"{name:10s} {len(fill):5d} unseen frames: template fill {100 * fill.mean():.2f} cm "
        f"(p90 {100 * np.percentile(fill, 90):.2f}), straight line {100 * line.mean():.2f} cm "
        f"(p90 {100 * np.percentile(line, 90):.2f}); rest end → next rest start "
        f"{frac.mean():.3f} ± {frac.std():.3f} of the cycle ({len(frac)} swings)"
    )


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*", type=Path, help="AMASS *_poses.npz files (real motion)")
    ap.add_argument("--simulated", type=int, default=12, help="simulated walks to score too")
    ap.add_argument("--height", type=float, default=1.75, help="body height for the lift [m]")
    ap.add_argument("--rest-speed", type=float, default=0.15, help="rest below this [m/s]")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.clips:
        real: dict[str, list[float]] = {"fill": [], "line": [], "fraction": []}
        for path in args.clips:
            for key, values in score_clip(path, args.height, args.rest_speed).items():
                real[key] += values
        _report("real", real)
    if args.simulated:
        sim: dict[str, list[float]] = {"fill": [], "line": [], "fraction": []}
        with tempfile.TemporaryDirectory() as tmp:
            for path in _simulated_clips(args.simulated, Path(tmp), args.seed):
                for key, values in score_clip(path, args.height, args.rest_speed).items():
                    sim[key] += values
        _report("simulated", sim)


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
