"""The swing fill of ``gaitnet infer`` (``pipeline.gap_fill: swing``) on real and simulated walks.

For each clip in the AMASS ``*_poses.npz`` format (real motion capture, e.g. the CMU walks, and
walks of the simulator's gait generator written in the same format), resampled to 30 frames/s:

1. forward kinematics with the clip's rest joints (the built-in skeleton of ``--height`` when
   the file has none; ``--height`` is also the body height the template's lift and sideways
   bow are scaled by) gives a
   mid-foot point per side, half-way between the ankle and the SMPL foot joint (the ball of
   the foot): the same point on every clip;
2. the foot "rests" where that point's horizontal speed stays below ``--rest-speed`` for at
   least 3 frames; the rests stand in for the filter's stance landmarks and the point in the
   rest frames for the measured foot, everything between two rests is unseen (with
   ``--point keypoint`` the measured and scored point is instead the keypoint as the pose
   correction models it, the ankle plus ``KEYPOINT_OFFSET_M`` scaled by ``--height`` in the
   ankle's frame of the clip's pose: the point the template follows; the rests are still the
   mid-foot point's);
3. :func:`gaitnet.pipeline.swing_fill.swing_fill` fills the unseen frames (the default
   ``pipeline.swing_*`` keys, but ``--start-delay`` for ``pipeline.swing_start_delay_s``; with
   ``--no-rest-bound`` the rests handed to it end at their first frame, so the swing's start
   is the timing line's alone, never the rest's end: the rest frames stay measured and the
   unseen frames the same), and the fill is compared with the true point there. A straight
   line in time between the two rests (the simplest fill) is scored beside it.

    python benchmarks/bench_swing_fill.py REAL/*_poses.npz [--simulated 12]
        [--start-delay S] [--no-rest-bound] [--point midfoot|keypoint] [--camera-peak]

(``REAL``: walking clips of the CMU Graphics Lab Motion Capture Database, mocap.cs.cmu.edu,
in AMASS's SMPL+H G layout, as AMASS distributes them; docs/pipeline.md has the figures.)

Prints the mean and 90th percentile of the fill's error per source, its mean sideways error
and mean |sideways| error (horizontal, square to the foot's walking direction, + away from the
body's midline), and the share of the cycle from the end of a rest to the start of the next
(over one rest-to-rest cycle), to set beside the template's span
(``pipeline.swing_span_offset_s + swing_span_per_cycle · cycle``).

With ``--camera-peak``, also where a camera worn on the pelvis is highest within each swing:
a virtual camera at the simulator's mount offset (:data:`CAMERA_IN_PELVIS_M`, SMPL's root
frame) moved by the clip's pelvis joint and root rotation; its height's highest frame between
the end of one rest and the start of the next (refined by a parabola, interior maxima only),
as a share τ of that interval: mean ± standard deviation per source and the range per clip
(docs/pipeline.md, *The camera's highest point*).
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from gaitnet.geometry import so3_exp
from gaitnet.motion.amass import load_amass_clip
from gaitnet.motion.skeleton import (
    LowerBodySkeleton,
    builtin_skeleton,
    forward_kinematics,
    from_rest_joints,
)
from gaitnet.pipeline.config import (
    KEYPOINT_OFFSET_M,
    REFERENCE_HEIGHT_M,
    InferCorrectionParams,
    PipelineParams,
)
from gaitnet.pipeline.pose_residuals import ChainGeometry, foot_points
from gaitnet.pipeline.swing_fill import swing_fill
from gaitnet.training.scripts import ScriptParser
from gaitnet.vio.gait import SIDES
from gaitnet.vio.result import StanceFoot

FPS = 30.0
ANKLES, FEET = (5, 6), (7, 8)  # joint order of gaitnet.motion.skeleton.SMPL_JOINT_INDICES
CAMERA_IN_PELVIS_M = np.array([0.0, 0.05, 0.17])
"""The simulator's camera (``mount.offset_m``: 0.17 m forward, 0.05 m up) in SMPL's root frame
(x left, y up, z forward)."""


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


def _clip_joints(path: Path, height_m: float):
    """The clip at :data:`FPS`, its skeleton (the clip's rest joints, else the built-in
    skeleton of ``height_m``) and its joints by forward kinematics."""
    clip = load_amass_clip(path, fps=FPS)
    skel = (
        from_rest_joints(clip.rest_joints)
        if clip.rest_joints is not None
        else builtin_skeleton(height_m)
    )
    return clip, skel, forward_kinematics(skel, clip.root_orient, clip.trans, clip.joint_aa)


def _foot_rests(
    J: np.ndarray, side: int, rest_speed: float
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The mid-foot point of ``side`` (half-way between the ankle and the foot joint) and its
    rests (:func:`_rests` of its horizontal speed)."""
    p = 0.5 * (J[:, ANKLES[side]] + J[:, FEET[side]])
    speed = np.r_[np.inf, np.hypot(*np.diff(p[:, :2], axis=0).T) * FPS]
    return p, _rests(speed, rest_speed)


def keypoints_on_pose(
    skel: LowerBodySkeleton,
    root_orient: np.ndarray,
    trans: np.ndarray,
    joint_aa: np.ndarray,
    height_m: float,
) -> np.ndarray:
    """The keypoint of each foot (n, 2, 3) as the pose correction models it: its foot point
    (:func:`gaitnet.pipeline.pose_residuals.foot_points`) with ``KEYPOINT_OFFSET_M`` scaled to
    ``height_m``, on poses ``root_orient`` (n, 3), ``trans`` (n, 3), ``joint_aa`` (n, 8, 3)
    (SMPL: hips, knees, ankles, feet) of skeleton ``skel``."""
    offset = np.array(KEYPOINT_OFFSET_M) * height_m / REFERENCE_HEIGHT_M
    params = replace(InferCorrectionParams(), marker_offset_m=tuple(offset))
    poses = np.concatenate([root_orient, joint_aa[:, :6].reshape(len(joint_aa), 18)], axis=1)
    return foot_points(ChainGeometry.build(skel, params), poses, trans)


def score_clip(
    path: Path,
    height_m: float,
    rest_speed: float,
    timing: dict[str, float] | None = None,
    rest_bound: bool = True,
    point: str = "midfoot",
) -> dict[str, list[float]]:
    """Per unseen frame the fill's and the straight line's 3-D error and the fill's sideways
    error (``fill``, ``line``, ``sideways``), per rest-to-rest cycle the unseen share
    (``fraction``); ``timing``: :func:`swing_fill`'s keyword arguments (default: the config's);
    ``rest_bound`` False: the rests end at their first frame for the fill; ``point``
    ``"keypoint"``: the keypoint is measured and scored instead of the mid-foot point (module
    docstring)."""
    if point not in ("midfoot", "keypoint"):
        raise ValueError(f"score_clip: point must be midfoot or keypoint, got {point!r}")
    clip, skel, J = _clip_joints(path, height_m)
    keypoints = None
    if point == "keypoint":
        keypoints = keypoints_on_pose(skel, clip.root_orient, clip.trans, clip.joint_aa, height_m)
    t = np.arange(clip.n_frames) / FPS
    out: dict[str, list[float]] = {"fill": [], "line": [], "sideways": [], "fraction": []}
    measured = np.full((clip.n_frames, 2, 3), np.nan)
    stance: list[StanceFoot] = []
    truth = np.empty((clip.n_frames, 2, 3))
    for s, side in enumerate(SIDES):
        p, rests = _foot_rests(J, s, rest_speed)
        if keypoints is not None:
            p = keypoints[:, s]
        truth[:, s] = p
        for a, b in rests:
            measured[a : b + 1, s] = p[a : b + 1]
            last = t[b] if rest_bound else t[a]
            stance.append(StanceFoot(len(stance), side, t[a], last, p[a, :2], np.zeros(2), 1))
        for (a0, b0), (a1, _) in zip(rests, rests[1:], strict=False):
            out["fraction"].append((t[a1] - t[b0]) / (t[a1] - t[a0]))
    timing = PipelineParams().swing_timing() if timing is None else timing
    filled = swing_fill(t, measured, stance, height_m, **timing)
    for s in range(2):
        unseen = np.isnan(measured[:, s, 0])
        use = unseen & np.isfinite(filled[:, s, 0])
        error = filled[use, s] - truth[use, s]
        out["fill"] += np.linalg.norm(error, axis=1).tolist()
        ahead = truth[-1, s, :2] - truth[0, s, :2]  # a straight walk's direction
        outwards = np.array([-ahead[1], ahead[0]]) / np.hypot(*ahead) * (1 - 2 * s)
        out["sideways"] += (error[:, :2] @ outwards).tolist()
        # the straight line in time between the neighbouring measured frames
        seen = np.flatnonzero(~unseen)
        line = np.stack(
            [np.interp(np.flatnonzero(use), seen, truth[seen, s, c]) for c in range(3)], axis=1
        )
        out["line"] += np.linalg.norm(line - truth[use, s], axis=1).tolist()
    return out


def camera_peak_phases(path: Path, height_m: float, rest_speed: float) -> list[float]:
    """Per swing between two rests of a foot, where the virtual camera is highest, as a share
    of the time from the end of the first rest to the start of the next (module docstring)."""
    clip, _, J = _clip_joints(path, height_m)
    z = (J[:, 0] + so3_exp(clip.root_orient) @ CAMERA_IN_PELVIS_M)[:, 2]
    phases = []
    for s in range(2):
        p, rests = _foot_rests(J, s, rest_speed)
        for (_, b0), (a1, _) in zip(rests, rests[1:], strict=False):
            inside = np.arange(b0 + 1, a1)
            if len(inside) < 3:
                continue
            k = int(inside[np.argmax(z[inside])])
            if k in (inside[0], inside[-1]):
                continue
            curve = z[k - 1] - 2 * z[k] + z[k + 1]
            top = k + (0.5 * (z[k - 1] - z[k + 1]) / curve if curve < 0 else 0.0)
            phases.append((top - b0) / (a1 - b0))
    return phases


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
    if not scores.get("fill"):
        print(f"{name:10s} no swing between two rests was found")
        return
    fill, line = np.array(scores["fill"]), np.array(scores["line"])
    sideways, frac = np.array(scores["sideways"]), np.array(scores["fraction"])
    print(
        f"{name:10s} {len(fill):5d} unseen frames: template fill {100 * fill.mean():.2f} cm "
        f"(p90 {100 * np.percentile(fill, 90):.2f}; sideways {100 * sideways.mean():+.2f}, "
        f"|sideways| {100 * np.abs(sideways).mean():.2f}), straight line "
        f"{100 * line.mean():.2f} cm (p90 {100 * np.percentile(line, 90):.2f}); rest end → "
        f"next rest start {frac.mean():.3f} ± {frac.std():.3f} of the cycle ({len(frac)} swings)"
    )


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*", type=Path, help="AMASS *_poses.npz files (real motion)")
    ap.add_argument("--simulated", type=int, default=12, help="simulated walks to score too")
    ap.add_argument(
        "--height", type=float, default=1.75, help="body height for the lift and bow [m]"
    )
    ap.add_argument("--rest-speed", type=float, default=0.15, help="rest below this [m/s]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--start-delay", type=float, default=None,
        help="pipeline.swing_start_delay_s for the fill [s] (default: the config's)",
    )  # fmt: skip
    ap.add_argument(
        "--no-rest-bound", action="store_true",
        help="the timing line alone sets each swing's start (not the rest's end)",
    )  # fmt: skip
    ap.add_argument(
        "--point", choices=("midfoot", "keypoint"), default="midfoot",
        help="the point measured at rest and scored (default midfoot)",
    )  # fmt: skip
    ap.add_argument(
        "--camera-peak", action="store_true",
        help="also print where a pelvis-worn camera is highest within each swing",
    )  # fmt: skip
    args = ap.parse_args()
    params = PipelineParams()
    if args.start_delay is not None:
        try:
            params = replace(params, swing_start_delay_s=args.start_delay)
        except ValueError as exc:  # out of the key's range
            ap.error(f"--start-delay: {exc}")
    timing = params.swing_timing()
    sources = []
    if args.clips:
        sources.append(("real", list(args.clips)))
    with tempfile.TemporaryDirectory() as tmp:
        if args.simulated:
            sources.append(("simulated", _simulated_clips(args.simulated, Path(tmp), args.seed)))
        for name, paths in sources:
            scores: dict[str, list[float]] = {}
            for path in paths:
                bound = not args.no_rest_bound
                found = score_clip(path, args.height, args.rest_speed, timing, bound, args.point)
                for key, values in found.items():
                    scores.setdefault(key, []).extend(values)
            _report(name, scores)
            if args.camera_peak:
                per_clip = [camera_peak_phases(p, args.height, args.rest_speed) for p in paths]
                every = np.concatenate([np.asarray(c, float) for c in per_clip])
                ranges = ", ".join(f"{min(c):.2f}–{max(c):.2f}" for c in per_clip if c)
                print(
                    f"{name:10s} camera highest at τ {every.mean():.3f} ± {every.std():.3f} of "
                    f"the rest end → next rest start ({len(every)} swings); per clip {ranges}"
                )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
