"""``gaitnet batch`` throughput: sessions per hour with 1 and 2 local workers and on a local Ray
instance, each session's cost split into start-up and processing, and an estimate for N nodes
from the measured cost (docs/batch.md, *Benchmark*).

Every configuration runs the same sessions into a fresh output folder through the library's
own :func:`gaitnet.batch.run.run_batch`. Per session it reports the start-up (imports and the
two networks on a worker's first session, then opening the session) and the processing (the
pipeline and the writing); ``fixed`` is the wall time of the busiest worker spent outside any
session (starting processes or the Ray instance, handing out tasks, writing the cohort), and
``CPU`` the CPU seconds of the worker process per session (all its threads). It then times
reading the frames alone (decoding every colour and depth PNG, page cache warm) and the bytes a
session reads, and estimates N nodes: compute-bound from the median CPU seconds per session of
the 1-worker run (a worker's first session carries its imports and models, so the median
leaves them out; they are paid once per worker), storage-bound from ``--storage-mbps`` of
shared storage.

    python benchmarks/bench_batch.py SESSION [SESSION ...] [--no-ray] [--nodes 1 4 16 64]
        [--cores-per-node C] [--storage-mbps 110] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from gaitnet.batch.run import BatchResult, plan_batch, run_batch
from gaitnet.batch.task import usable_cores
from gaitnet.io import open_session
from gaitnet.training.scripts import ScriptParser

READ_PARTS = ("color", "depth", "imu.csv", "session.yaml")  # what gaitnet infer reads


def _bytes_read(session: Path) -> int:
    """The bytes of a session folder the pipeline reads (a .bag: the file)."""
    if session.is_file():
        return session.stat().st_size
    paths = [session / p for p in READ_PARTS]
    files = [f for p in paths for f in ([p] if p.is_file() else p.rglob("*") if p.is_dir() else [])]
    return sum(f.stat().st_size for f in files if f.is_file())


def _read_seconds(session: Path) -> float:
    """CPU seconds to open the session and decode every frame."""
    start = time.process_time()
    for _ in open_session(session).frames():
        pass
    return time.process_time() - start


def _row(label: str, result: BatchResult) -> dict[str, float | str]:
    ok = [o for o in result.outcomes if o.ok]
    if len(ok) != len(result.outcomes):
        failed = "; ".join(f"{o.name}: {o.error}" for o in result.outcomes if not o.ok)
        raise RuntimeError(f"{label}: sessions failed: {failed}")
    busiest: dict[str, float] = defaultdict(float)
    for o in ok:
        busiest[o.worker] += o.startup_s + o.infer_s
    return {
        "label": label,
        "n": len(ok),
        "wall_s": result.wall_s,
        "per_hour": 3600.0 * len(ok) / result.wall_s,
        "startup_s": float(np.mean([o.startup_s for o in ok])),
        "infer_s": float(np.mean([o.infer_s for o in ok])),
        "cpu_s": float(np.median([o.cpu_s for o in ok])),
        "fixed_s": result.wall_s - max(busiest.values()),
        "workers": result.workers,
        "threads": result.threads[0] * result.threads[1],
    }


def _print_rows(rows: list[dict]) -> None:
    print(
        f"{'configuration':24s} {'sessions':>8s} {'wall [s]':>9s} {'sessions/h':>11s} "
        f"{'start-up [s]':>13s} {'processing [s]':>15s} {'CPU [s]':>8s} {'fixed [s]':>10s}"
    )
    for r in rows:
        print(
            f"{r['label']:24s} {r['n']:8d} {r['wall_s']:9.1f} {r['per_hour']:11.0f} "
            f"{r['startup_s']:13.2f} {r['infer_s']:15.2f} {r['cpu_s']:8.1f} {r['fixed_s']:10.1f}"
        )


def _print_estimate(rows: list[dict], args, mb: float, read_s: float, cores: int) -> None:
    core_s = rows[0]["cpu_s"]  # the 1-worker run
    node_cores = args.cores_per_node or cores
    storage = 3600.0 * args.storage_mbps / mb
    print(
        f"\nper session: {mb:.0f} MB read (colour, depth, IMU); decoding its frames alone "
        f"{read_s:.1f} s of one core; {core_s:.1f} CPU seconds in all (median, 1 worker)"
    )
    print(
        f"estimate for N nodes of {node_cores} cores, shared storage at {args.storage_mbps:g} "
        "MB/s (start-up is paid once per worker process and is left out):"
    )
    print(f"{'nodes':>6s} {'compute-bound [sessions/h]':>27s} {'storage-bound':>14s}  limit")
    for n in args.nodes:
        compute = 3600.0 * n * node_cores / core_s
        limit = "storage" if storage < compute else "compute"
        print(f"{n:6d} {compute:27.0f} {storage:14.0f}  {limit}")


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sessions", nargs="+", type=Path, metavar="SESSION")
    ap.add_argument("--no-ray", action="store_true", help="skip the local Ray run")
    ap.add_argument("--nodes", nargs="+", type=int, default=[1, 4, 16, 64], metavar="N")
    ap.add_argument("--cores-per-node", type=int, default=0, metavar="C", help="0: this machine's")
    ap.add_argument("--storage-mbps", type=float, default=110.0, metavar="MB_S")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="config overrides")
    args = ap.parse_args()
    configurations = [("local, 1 worker", 1, None), ("local, 2 workers", 2, None)]
    if not args.no_ray:
        configurations.append(("Ray (local), 2 tasks", 2, "local"))
    tmp = Path(tempfile.mkdtemp(prefix="bench_batch_"))
    rows = []
    try:
        for i, (label, workers, ray) in enumerate(configurations):
            plan = plan_batch([str(s) for s in args.sessions], tmp / str(i), None, args.set)
            result = run_batch(plan, "gaitnet bench_batch", workers, ray)
            rows.append(_row(label, result))
            print(f"{label}: {rows[-1]['wall_s']:.1f} s", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    cores = usable_cores()
    print(f"\n{len(args.sessions)} sessions on {cores} cores")
    _print_rows(rows)
    mb = float(np.mean([_bytes_read(s) for s in args.sessions])) / 1e6
    read_s = float(np.mean([_read_seconds(s) for s in args.sessions]))
    _print_estimate(rows, args, mb, read_s, cores)


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
