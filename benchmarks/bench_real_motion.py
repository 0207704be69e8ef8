"""The whole pipeline on real walking: motion-capture clips played by the simulator.

For each AMASS-format clip (``*_poses.npz``; e.g. the CMU walks), or with ``--loop S`` its own
gait cycles looped to S seconds (:func:`gaitnet.motion.augment.loop_clip`: a long walk from
short captures), and with ``--mirror`` its left/right mirror image
(:func:`gaitnet.motion.augment.mirror_clip`), and for ``--generated N``
sessions of the gait generator beside them (seeds 2000…), this runs what a user runs:

    gaitnet simulate --motion CLIP --seed S --out W/<name>  [--sim KEY=VALUE ...]
    gaitnet infer W/<name> --out W/<name>-infer            [--set KEY=VALUE ...]
    gaitnet evaluate W/<name>-infer --session W/<name>

and prints one row per session: strides matched per side (matched / true), stride RMSE, foot
NMATE over the measured and over the filled frames (left / right) and the 7-joint MPJPE after
a yaw + translation alignment, then the means per source (real, mirrored, generated). Sessions
already simulated with the same command are reused (``W/<name>/sim_command.txt``).

    python benchmarks/bench_real_motion.py CLIP [CLIP ...] [--mirror] [--generated N]
        [--loop S] [--seeds 1 2] [--work DIR] [--sim KEY=VALUE ...] [--set KEY=VALUE ...]
        [--json OUT]
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from gaitnet.errors import InputError
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.motion.amass import MotionClip, read_amass_npz
from gaitnet.motion.augment import loop_clip, mirror_clip
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES
from gaitnet.training.scripts import ScriptParser

REPO = Path(__file__).resolve().parents[1]
GENERATED_SEED = 2000


def write_clip(clip: MotionClip, template: Path, out: Path) -> Path:
    """``clip`` written in ``template``'s layout (SMPL+H G ``poses``, its other keys kept)."""
    with np.load(template) as data:
        arrays = {k: data[k] for k in data.files}
    poses = np.zeros((clip.n_frames, arrays["poses"].shape[1] // 3, 3))
    poses[:, 0] = clip.root_orient
    poses[:, list(ROTATED_SMPL_INDICES)] = clip.joint_aa
    arrays.update(poses=poses.reshape(clip.n_frames, -1), trans=clip.trans)
    for key in ("dmpls",):
        if key in arrays and arrays[key].ndim == 2:
            arrays[key] = np.zeros((clip.n_frames, arrays[key].shape[1]), arrays[key].dtype)
    if clip.rest_joints is not None:
        arrays["gaitnet_rest_joints"] = clip.rest_joints
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(out, **arrays)
    return out


def _gaitnet(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "gaitnet.cli", *args], capture_output=True, text=True, cwd=REPO
    )


def run_session(
    name: str, sim_args: list[str], work: Path, infer_set: list[str]
) -> dict[str, object]:
    """Simulate (unless cached), infer and evaluate one session; its metrics or its error."""
    session, result = work / name, work / f"{name}-infer"
    command = " ".join(sim_args)
    stamp = session / "sim_command.txt"
    if not (stamp.is_file() and stamp.read_text() == command):
        done = _gaitnet("simulate", *sim_args, "--out", str(session), "--overwrite")
        if done.returncode != 0:
            return {"name": name, "error": done.stderr.strip().splitlines()[-1]}
        stamp.write_text(command)
    done = _gaitnet("infer", str(session), "--out", str(result), "--overwrite", *infer_set)
    if done.returncode != 0:
        return {"name": name, "error": done.stderr.strip().splitlines()[-1]}
    report = evaluate_result(result, session)
    return {"name": name, **report.metrics, "counts": report.counts}


def _true_strides(session: Path) -> dict[str, int]:
    rows = (session / "groundtruth" / "strides.csv").read_text().splitlines()[1:]
    return {s: sum(1 for r in rows if r.startswith(f"{s},")) for s in ("left", "right")}


def _cm(value: object) -> str:
    return f"{100 * float(value):.2f}" if isinstance(value, (int, float)) else "–"


def row(r: dict, work: Path) -> str:
    if "error" in r:
        return f"{r['name']:32s} refused: {r['error']}"
    true = _true_strides(work / str(r["name"]))
    n = r.get("n_strides", {})
    matched = " / ".join(f"{n.get(s, 0)}/{true[s]}" for s in ("left", "right"))
    nmate, filled = r.get("foot_nmate_m", {}), r.get("foot_nmate_filled_m", {})
    rmse = _cm(r.get("stride_rmse_m", {}).get("all"))
    return (
        f"{r['name']:32s} strides {matched:11s} RMSE {rmse:>5s}"
        f"  NMATE {_cm(nmate.get('left'))} / {_cm(nmate.get('right'))}"
        f"  filled {_cm(filled.get('left'))} / {_cm(filled.get('right'))}"
        f"  MPJPE {_cm(r.get('mpjpe_aligned_m'))} cm"
    )


def summary(rows: list[dict], work: Path) -> dict[str, float]:
    ok = [r for r in rows if "error" not in r]

    def mean(get) -> float:
        values = [v for v in (get(r) for r in ok) if v is not None]
        return float(np.mean(values)) if values else float("nan")

    unmatched = 0
    for r in ok:
        true = _true_strides(work / str(r["name"]))
        unmatched += sum(true[s] - r.get("n_strides", {}).get(s, 0) for s in true)
    return {
        "sessions": len(rows),
        "refused": len(rows) - len(ok),
        "unmatched_true_strides": unmatched,
        "stride_rmse_m": mean(lambda r: r.get("stride_rmse_m", {}).get("all")),
        "foot_nmate_m": mean(
            lambda r: np.mean(list(r.get("foot_nmate_m", {}).values()) or [np.nan])
        ),
        "foot_nmate_filled_m": mean(
            lambda r: np.mean(list(r.get("foot_nmate_filled_m", {}).values()) or [np.nan])
        ),
        "mpjpe_aligned_m": mean(lambda r: r.get("mpjpe_aligned_m")),
    }


def main() -> None:
    parser = ScriptParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("clips", nargs="*", type=Path)
    parser.add_argument("--mirror", action="store_true", help="also each clip's mirror image")
    parser.add_argument("--generated", type=int, default=0, help="generated sessions beside")
    parser.add_argument(
        "--loop",
        type=float,
        metavar="SECONDS",
        help="play each clip's own gait cycles looped to this length (gaitnet.motion.augment."
        "loop_clip) instead of the clip as captured",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--work", type=Path, default=REPO / "runs" / "bench_real_motion")
    parser.add_argument("--sim", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    work = args.work.resolve()
    for clip in args.clips:
        if not clip.is_file():
            raise InputError(f"{clip}: no such clip file")
    jobs: list[tuple[str, str, list[str]]] = []
    for clip in args.clips:
        motion, stem = read_amass_npz(clip), clip.stem
        sources = [("real", clip.resolve())]
        if args.loop:
            motion, stem = loop_clip(motion, args.loop), f"{stem}_loop{args.loop:g}"
            sources = [("real", write_clip(motion, clip, work / "clips" / f"{stem}.npz"))]
        if args.mirror:
            mirrored = mirror_clip(motion)
            path = write_clip(mirrored, clip, work / "clips" / f"{stem}_mirror.npz")
            sources.append(("mirrored", path))
        for kind, path in sources:
            for seed in args.seeds:
                name = f"{path.stem.removesuffix('_poses')}_s{seed}"
                jobs.append((kind, name, ["--motion", str(path), "--seed", str(seed), *args.sim]))
    for k in range(args.generated):
        seed = GENERATED_SEED + k
        jobs.append(("generated", f"generated_s{seed}", ["--seed", str(seed)]))
    results: dict[str, list[dict]] = {}
    for kind, name, sim_args in jobs:
        r = run_session(name, sim_args, work, args.set)
        results.setdefault(kind, []).append(r)
        print(f"{kind:9s} {row(r, work)}", flush=True)
    out = {
        kind: {"summary": summary(rows, work), "sessions": rows} for kind, rows in results.items()
    }
    for kind, data in out.items():
        s = data["summary"]
        print(
            f"{kind:9s} mean over {s['sessions'] - s['refused']} sessions ({s['refused']} refused, "
            f"{s['unmatched_true_strides']} true strides unmatched): stride RMSE "
            f"{_cm(s['stride_rmse_m'])} cm, NMATE {_cm(s['foot_nmate_m'])} cm, filled "
            f"{_cm(s['foot_nmate_filled_m'])} cm, MPJPE {_cm(s['mpjpe_aligned_m'])} cm"
        )
    if args.json:
        args.json.write_text(json.dumps(out, indent=2, default=float))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
