"""Where the simulator's frame workers come from (:mod:`gaitnet.sim.session_frames`).

Kept apart from the frame code and free of heavy imports, so that a command can start the
workers' ``forkserver`` — which imports the simulator once — before it imports the simulator
itself: the two imports then run on two CPUs at once.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = [
    "AE_LATENCY",
    "default_workers",
    "interrupts_deferred",
    "start_forkserver",
    "start_workers",
    "worker_context",
]

FRAME_MODULE = "gaitnet.sim.session_frames"  # what the forkserver imports (its workers' code)
# frames between an auto-exposure measurement and its effect, hence frames rendered at once
# (gaitnet.sim.session_frames)
AE_LATENCY = 2


def default_workers() -> int:
    """Worker processes for a session: 2 where at least 2 CPUs are usable (the main process
    encodes and writes the PNG files meanwhile, on whichever CPU is free), else 1 (same bytes
    either way)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return AE_LATENCY if cpus >= 2 else 1


def worker_context() -> multiprocessing.context.BaseContext:
    """Where worker processes come from: a ``forkserver`` that imported the frame code
    (:data:`FRAME_MODULE`; a process forked from the main one could hang in OpenCV's thread
    pool; a ``spawn``-started one spends a second or more importing), else ``spawn``."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([FRAME_MODULE])
    return ctx


def start_workers(workers: int | None = None) -> None:
    """Start the worker processes' forkserver now when
    :func:`gaitnet.sim.session_frames.render_frames` will use one
    (it imports the simulator meanwhile, on another CPU); optional. Cheap to import: a
    command can call it before it imports the simulator itself."""
    workers = default_workers() if workers is None else int(workers)
    if min(workers, AE_LATENCY) > 1:
        start_forkserver(worker_context())


_STARTED_BY: int | None = None  # the process that started the forkserver (its pid)


def start_forkserver(ctx: multiprocessing.context.BaseContext) -> None:
    """Start ``ctx``'s forkserver, if it uses one and none runs, with SIGINT ignored.

    The forkserver is in the terminal's process group, so Ctrl-C reaches it too; Python keeps
    a SIGINT ignore inherited from its parent, so it imports the simulator undisturbed and
    exits when the main process does. The main process ignores SIGINT only for the
    milliseconds the first start takes (the main thread only: elsewhere signals cannot be
    changed); once it has started (or found) one, later calls leave SIGINT alone, so a Ctrl-C
    then is not lost (``gaitnet simulate`` calls this again when the frames start). A
    forkserver that died and is started again by such a later call does not ignore Ctrl-C.
    """
    global _STARTED_BY
    if ctx.get_start_method() != "forkserver":
        return
    from multiprocessing import forkserver

    if os.getpid() == _STARTED_BY or threading.current_thread() is not threading.main_thread():
        forkserver.ensure_running()
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL if previous is None else previous)
    _STARTED_BY = os.getpid()


@contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while worker processes start, then deliver the first one.

    A signal that interrupts the main process mid-way through sending a new worker its job
    leaves that worker reading a truncated pickle (it prints a traceback after the CLI's
    last line); held until the pool exists, the signal stops the pool in order instead.
    Only the main thread may change signal handlers: elsewhere nothing is held.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, lambda signum, _frame: caught.append(signum)) for s in held}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        if caught:
            signal.raise_signal(caught[0])
