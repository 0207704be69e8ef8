"""Where ``gaitnet infer`` spends its CPU: one table of CPU milliseconds per frame by stage.

For each session folder or ``.bag``, ``gaitnet infer``'s own code (the default config, or
``--config`` and ``--set KEY=VALUE``) runs twice in this process:

1. unprofiled, for the total: CPU seconds of the process per second of recording (every
   thread: the filter's and the segmentation threads'; OpenBLAS on one thread, as the
   ``gaitnet`` command runs it);
2. under ``cProfile`` with a per-thread CPU clock (``time.thread_time``), one profiler in the
   main thread, one per call in the segmentation threads and one per frame read in the
   read-ahead thread (Python 3.11: a profiler sees only its own thread), for the shares.
   Each stage is the cumulative time of the functions that do it:

   decode (``SessionFolder.frame``, ``RealSenseBag.frame``), odometry (``FrameOdometry.
   estimate``), tags (``detect_board_pose``), filter (``run_vio`` less the decode, odometry,
   tags and smoother inside it), smoother (``smooth``), HHA (``hha_encode``), segmenter
   (``OnnxSegmenter.labels``: the network and its edge refinement), post-processing
   (``foot_keypoints``), prediction (``OnnxPredictor``), correction (``correct_poses``),
   writing (``write_infer_files``), other (the profiled total less the stages).

The profiler's own overhead inflates the Python-heavy stages (the filter most); the per-stage
milliseconds are therefore the profiled run's shares of the unprofiled total.

    python benchmarks/bench_profile.py SESSION [SESSION ...] [--config FILE] [--set KEY=VALUE]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the gaitnet command sets it

import cProfile  # noqa: E402
import pstats  # noqa: E402
import tempfile  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import gaitnet.pipeline.infer as infer  # noqa: E402
from gaitnet.config import load_config  # noqa: E402
from gaitnet.io import open_session  # noqa: E402
from gaitnet.motion.onnx_runtime import OnnxPredictor  # noqa: E402
from gaitnet.pipeline.config import InferConfig  # noqa: E402
from gaitnet.pipeline.outputs import write_infer_files  # noqa: E402
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter  # noqa: E402
from gaitnet.segmentation.segment_session import default_segmenter_path  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

#: stage → the (file suffix, function name) whose cumulative CPU time it is.
STAGES: dict[str, tuple[tuple[str, str], ...]] = {
    "decode": (("io/session_folder.py", "frame"), ("io/realsense_bag.py", "frame")),
    "odometry": (("vio/odometry.py", "estimate"),),
    "tags": (("vio/apriltags.py", "detect_board_pose"),),
    "smoother": (("vio/smoother.py", "smooth"),),
    "HHA": (("segmentation/hha.py", "hha_encode"),),
    "segmenter": (("segmentation/onnx_runtime.py", "labels"),),
    "post-processing": (("segmentation/postprocess.py", "foot_keypoints"),),
    "prediction": (("motion/onnx_runtime.py", "__call__"),),
    "correction": (("pipeline/pose_correction.py", "correct_poses"),),
    "writing": (("pipeline/outputs.py", "write_infer_files"),),
}
INSIDE_THE_FILTER = ("decode", "odometry", "tags", "smoother")
ORDER = (
    "decode", "odometry", "tags", "filter", "smoother", "HHA", "segmenter", "post-processing",
    "prediction", "correction", "writing", "other",
)  # fmt: skip


def _cumulative(stats: pstats.Stats, suffix: str, name: str) -> float:
    return sum(
        row[3]
        for (path, _, func), row in stats.stats.items()  # type: ignore[attr-defined]
        if func == name and path.replace("\\", "/").endswith(suffix)
    )


def run_once(session_path: Path, cfg: InferConfig, profile: bool) -> tuple[float, dict, int, float]:
    """``gaitnet infer`` on one session: (process CPU s, stage CPU s or {}, frames, duration)."""
    session = open_session(session_path)
    segmenter = OnnxSegmenter(
        cfg.models.segmenter or default_segmenter_path(),
        threads=cfg.models.threads,
        flip_average=cfg.models.segmenter_flip_average,
        edge_refine=cfg.edge_refine,
    )
    predictor = OnnxPredictor(
        cfg.models.predictor or infer.default_predictor_path(), threads=cfg.models.threads
    )
    profilers: list[cProfile.Profile] = []
    lock = threading.Lock()

    def in_worker_threads(fn):
        """``fn`` profiled on its own when a thread other than the main one calls it (the
        segmentation threads, the frame read-ahead thread)."""

        def wrapper(*args, **kwargs):
            if threading.current_thread() is threading.main_thread():
                return fn(*args, **kwargs)
            prof = cProfile.Profile(time.thread_time)
            with lock:
                profilers.append(prof)
            prof.enable()
            try:
                return fn(*args, **kwargs)
            finally:
                prof.disable()

        return wrapper

    patches = [(infer, "measure_feet"), (type(session), "frame")]
    originals = [getattr(owner, name) for owner, name in patches]
    main = cProfile.Profile(time.thread_time)
    if profile:
        for (owner, name), fn in zip(patches, originals, strict=True):
            setattr(owner, name, in_worker_threads(fn))
        profilers.append(main)
        main.enable()
    cpu0 = time.process_time()
    try:
        result = infer.run_infer(session, cfg, segmenter, predictor)
        with tempfile.TemporaryDirectory() as tmp:
            write_infer_files(result, Path(tmp), {"session": str(session_path)})
    finally:
        main.disable()
        for (owner, name), fn in zip(patches, originals, strict=True):
            setattr(owner, name, fn)
    cpu = time.process_time() - cpu0
    times = np.asarray(session.frame_times_ns, dtype=np.float64) * 1e-9
    n, duration = len(times), float(times[-1] - times[0])
    if not profile:
        return cpu, {}, n, duration
    stats = pstats.Stats(profilers[0])
    for prof in profilers[1:]:
        stats.add(prof)
    stages = {
        stage: sum(_cumulative(stats, suffix, name) for suffix, name in funcs)
        for stage, funcs in STAGES.items()
    }
    run_vio = _cumulative(stats, "vio/run.py", "run_vio")
    stages["filter"] = max(run_vio - sum(stages[s] for s in INSIDE_THE_FILTER), 0.0)
    total = float(stats.total_tt)  # type: ignore[attr-defined]
    stages["other"] = max(total - sum(stages.values()), 0.0)
    return total, stages, n, duration


def main(argv: list[str] | None = None) -> int:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("sessions", type=Path, nargs="+", help="session folders or .bag files")
    ap.add_argument("--config", type=Path, default=None, help="a gaitnet infer config file")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="config overrides")
    args = ap.parse_args(argv)
    cfg = load_config(InferConfig, args.config, args.set)
    columns, per_second = [], []
    for path in args.sessions:
        cpu, _, n, duration = run_once(path, cfg, profile=False)
        profiled, stages, _, _ = run_once(path, cfg, profile=True)
        scale = cpu / max(profiled, 1e-9)  # the profiler's overhead out
        columns.append({s: 1e3 * stages[s] * scale / n for s in ORDER})
        per_second.append(cpu / max(duration, 1e-9))
        print(f"{path}: {n} frames, {duration:.1f} s; {cpu:.1f} CPU s unprofiled, "
              f"{profiled:.1f} profiled", flush=True)  # fmt: skip
    names = [Path(p).name for p in args.sessions]
    print("\n| CPU ms per frame | " + " | ".join(names) + " | median |")
    print("|---|" + "---|" * (len(names) + 1))
    for stage in ORDER:
        values = [c[stage] for c in columns]
        cells = " | ".join(f"{v:.1f}" for v in values)
        print(f"| {stage} | {cells} | {np.median(values):.1f} |")
    totals = [sum(c.values()) for c in columns]
    print(f"| **total** | {' | '.join(f'{v:.1f}' for v in totals)} | {np.median(totals):.1f} |")
    cells = " | ".join(f"{v:.2f}" for v in per_second)
    print(f"| CPU s per s of recording | {cells} | {np.median(per_second):.2f} |")
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
