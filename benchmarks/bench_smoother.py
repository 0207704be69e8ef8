"""Smoother speed and accuracy on a synthetic 60 s, 30 Hz session (run by hand).

A walking-like analytic IMU trajectory with BMI055-class noise and constant biases, noisy VO
relative poses between consecutive frames, stance-foot landmarks (one every ``--step-s``,
seen for 0.6 s, 1 cm noise) and the end sheet's tag positions (tests/smootherfactory.py); a
small filter built from the core fills the record exactly as ``run.py`` does. Printed: problem
size, time per phase (best of ``--repeat``; wall and CPU thread time — the machine is shared),
the cost per Gauss–Newton iteration, how far 1, 2, 3 iterations stop from the converged
estimate, and the filter's vs the smoother's errors against the truth (IMU position and
attitude RMSE, landmark RMSE, same-foot stride-length RMSE).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_smoother.py [--duration 60] [--seed 1]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from smootherfactory import SynthConfig, make_problem  # noqa: E402

from gaitnet.geometry import quat_boxminus  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402
from gaitnet.vio.smoother import SmootherOptions, smooth  # noqa: E402


def _stride_rmse(est: dict[int, np.ndarray], truth: dict[int, np.ndarray]) -> float:
    ids = sorted(est)
    errs = [
        np.linalg.norm(est[b] - est[a]) - np.linalg.norm(truth[b] - truth[a])
        for a, b in zip(ids[:-2], ids[2:], strict=True)
    ]
    return float(np.sqrt(np.mean(np.square(errs))))


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    t0 = time.perf_counter()
    pb = make_problem(SynthConfig(duration_s=args.duration), args.seed)
    rec = pb.record
    print(
        f"synthetic session: {args.duration:.0f} s, {rec.n_frames} frames, {len(rec.vo)} VO, "
        f"{len(rec.feet)} foot observations of {len(rec.landmarks)} landmarks, "
        f"{len(rec.tags)} tag positions (simulated, filtered: {time.perf_counter() - t0:.1f} s)"
    )

    best = None
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), time.thread_time()
        result = smooth(rec)
        wall, cpu = time.perf_counter() - w0, time.thread_time() - c0
        if best is None or wall < best[0]:
            best = (wall, cpu, result)
    assert best is not None
    wall, cpu, result = best
    n = 9 * rec.n_frames + 6 + 2 * len(result.landmarks)
    print(f"unknowns {n}, residuals {sum(result.n_residuals.values())}")
    print(
        f"smooth(): wall {wall:.3f} s, CPU {cpu:.3f} s (best of {args.repeat}); "
        f"{result.iterations} Gauss-Newton iterations"
    )
    for phase, sec in result.timings_s.items():
        print(f"  {phase:<11} {sec:7.3f} s")
    w0, c0 = time.perf_counter(), time.thread_time()
    smooth(rec, SmootherOptions(landmark_covariance=False))
    print(
        f"without landmark covariances: wall {time.perf_counter() - w0:.3f} s, "
        f"CPU {time.thread_time() - c0:.3f} s"
    )
    print("cost per iteration:", ", ".join(f"{c:.6g}" for c in result.cost))

    ref = smooth(rec, SmootherOptions(max_iterations=20, step_tol=1e-10))
    for it in (1, 2, 3):
        r = smooth(rec, SmootherOptions(max_iterations=it, landmark_covariance=False))
        dp = np.abs(r.p_IinW - ref.p_IinW).max()
        dth = np.abs(quat_boxminus(r.q, ref.q)).max()
        dl = max(np.linalg.norm(r.landmarks[i] - ref.landmarks[i]) for i in ref.landmarks)
        print(
            f"  {it} iteration(s): max |Δp| {dp * 1e3:.4f} mm, max |Δθ| {np.degrees(dth):.5f}°, "
            f"max |Δlandmark| {dl * 1e3:.4f} mm from the converged estimate "
            f"({ref.iterations} iterations)"
        )

    def pos(p: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum((p - pb.p) ** 2, axis=1))))

    def att(q: np.ndarray) -> float:
        return float(np.degrees(np.sqrt(np.mean(np.sum(quat_boxminus(q, pb.q) ** 2, axis=1)))))

    def lm(est: dict[int, np.ndarray]) -> float:
        return float(
            np.sqrt(np.mean([np.sum((est[i] - pb.landmarks[i]) ** 2) for i in result.landmarks]))
        )

    print(f"{'':<10}{'pos RMSE':>12}{'att RMSE':>12}{'landmark':>12}{'stride':>12}")
    for name, p, q, lms in (
        ("filter", rec.p_IinW, rec.q, pb.filter_landmarks),
        ("smoother", result.p_IinW, result.q, result.landmarks),
    ):
        print(
            f"{name:<10}{pos(p) * 100:>10.2f}cm{att(q):>11.3f}°{lm(lms) * 100:>10.2f}cm"
            f"{_stride_rmse(lms, pb.landmarks) * 100:>10.2f}cm"
        )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
