"""The batch's sessions as Ray tasks: on an existing Ray cluster (``--ray ADDRESS``) or on a Ray
instance started here (``--ray local``); docs/batch.md, *Ray cluster*.

Each task runs :func:`gaitnet.batch.task.run_session`, the function local workers run, on a
session path that every node must see at the same place (shared storage), and writes its
result folder there itself: only the task (paths and the resolved config, a few kB) and its
outcome travel through Ray, never frames or results. Each task asks Ray for as many CPUs as it
runs threads, so Ray never puts more threads on a node than it has CPUs.

``ray`` is imported here only, when a batch uses it (the ``cluster`` extra); without it
:func:`connect` raises a one-line :class:`~gaitnet.errors.InputError`. ``ray.init`` retries an
address that does not answer for minutes, so an address is first tried with a plain TCP
connection that gives up after :data:`CONNECT_TIMEOUT_S`.
"""

from __future__ import annotations

import contextlib
import logging
import socket
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from gaitnet.batch.task import SessionOutcome, SessionTask, run_session
from gaitnet.errors import InputError, one_line
from gaitnet.io.atomic import clean_leftovers

__all__ = ["CONNECT_TIMEOUT_S", "RAY_MISSING", "RayCluster", "connect", "run_ray"]

log = logging.getLogger(__name__)

CONNECT_TIMEOUT_S = 5.0
RAY_MISSING = "--ray: ray is not installed (pip install -e '.[cluster]')"
#: Every task's environment: OpenBLAS on one thread, as in ``gaitnet infer``.
TASK_ENV = {"OPENBLAS_NUM_THREADS": "1"}


@dataclass(frozen=True)
class RayCluster:
    """What a batch needs to know of the cluster it runs on: its CPUs in all and those of its
    smallest node (a task cannot ask for more)."""

    address: str
    cpus: int
    smallest_node_cpus: int


def _check_reachable(address: str) -> None:
    """Refuse, within :data:`CONNECT_TIMEOUT_S`, an address nothing answers at."""
    if address == "auto":  # ray finds a cluster started on this machine, or says it found none
        return
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        raise InputError(f"--ray {address}: expected HOST:PORT, ray://HOST:PORT, auto or local")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise InputError(f"--ray {address}: no Ray cluster answers there ({reason})") from None


def connect(address: str, cores: int) -> RayCluster:
    """Connect to the Ray cluster at ``address`` (``HOST:PORT``, ``ray://HOST:PORT`` or
    ``auto``), or start a local instance with ``cores`` CPUs for ``local``."""
    if address != "local":
        _check_reachable(address)
    try:
        import ray
    except ImportError:
        raise InputError(RAY_MISSING) from None
    options = {
        "logging_level": logging.ERROR,
        "log_to_driver": False,
        "runtime_env": {"env_vars": TASK_ENV},
    }
    if address == "local":
        options |= {"num_cpus": cores, "include_dashboard": False}
    try:
        ray.init(address=address, **options)
    except Exception as exc:  # ray's own: a refused connection, a version mismatch, ...
        raise InputError(f"--ray {address}: {one_line(exc, 300)}") from None
    nodes = [n for n in ray.nodes() if n.get("Alive")]
    cpus = [int(n.get("Resources", {}).get("CPU", 0)) for n in nodes]
    cpus = [c for c in cpus if c > 0]
    if not cpus:
        ray.shutdown()
        raise InputError(f"--ray {address}: the cluster has no node with a CPU")
    log.info("Ray: %d node(s), %d CPUs", len(cpus), sum(cpus))
    return RayCluster(address, sum(cpus), min(cpus))


def run_ray(
    tasks: Sequence[SessionTask],
    workers: int,
    threads: int,
    on_done: Callable[[SessionOutcome], None] | None = None,
) -> list[SessionOutcome]:
    """Run ``tasks`` as Ray tasks of ``threads`` CPUs each, at most ``workers`` at once, on the
    cluster :func:`connect` joined, then disconnect (a local instance stops). An interrupt
    cancels the running tasks and removes their staging folders."""
    import ray

    remote = ray.remote(run_session).options(num_cpus=threads, max_retries=1)
    queue = deque(tasks)
    running: dict = {}
    outcomes: list[SessionOutcome] = []
    try:
        while queue or running:
            while queue and len(running) < workers:
                task = queue.popleft()
                running[remote.remote(task)] = task
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                task = running.pop(ref)
                try:
                    outcome = ray.get(ref)
                except ray.exceptions.RayError as exc:  # the worker died, the node was lost
                    error = f"its Ray task failed: {one_line(exc, 300)}"
                    outcome = SessionOutcome(task.name, task.session, error=error)
                outcomes.append(outcome)
                if on_done is not None:
                    on_done(outcome)
    except BaseException:
        _cancel(ray, running)
        raise
    finally:
        with contextlib.suppress(Exception):
            ray.shutdown()
    return outcomes


def _cancel(ray, running: dict) -> None:
    """Stop the running tasks and remove the staging folders they leave."""
    with contextlib.suppress(Exception):
        for ref in running:
            ray.cancel(ref, force=True)
        ray.wait(list(running), num_returns=len(running), timeout=10)
    for task in running.values():
        clean_leftovers(task.out)
