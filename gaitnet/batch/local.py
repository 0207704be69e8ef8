"""Local workers: ``workers`` processes, each running one session at a time
(:func:`gaitnet.batch.task.run_session`; docs/batch.md, *Workers and threads*).

- The processes are started with ``spawn`` (a fresh interpreter: no thread pool of this process
  is copied into them) while this process ignores Ctrl-C, so they ignore it for life: an
  interrupt reaches this process alone, which stops them (SIGTERM) and removes the staging
  folders of the sessions they were writing. OpenBLAS runs on one thread in them, as in
  ``gaitnet infer`` (``OPENBLAS_NUM_THREADS``, unless it is set).
- At most ``workers`` sessions are handed out at once, so a worker that dies (out of memory,
  killed) takes only the sessions that were running with it: those run again one by one, and
  the one whose worker dies alone is a failure.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context

from gaitnet.batch.task import SessionOutcome, SessionTask, run_session
from gaitnet.io.atomic import clean_leftovers

__all__ = ["run_local"]

log = logging.getLogger(__name__)

DIED = "its worker process died (out of memory, or killed)"


@contextlib.contextmanager
def _worker_environment() -> Iterator[None]:
    """OpenBLAS on one thread in the processes started meanwhile (this process's own numpy
    has read the variable already)."""
    key = "OPENBLAS_NUM_THREADS"
    added = key not in os.environ
    if added:
        os.environ[key] = "1"
    try:
        yield
    finally:
        if added:
            os.environ.pop(key, None)


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while worker processes may start (they keep the ignore; module
    docstring); only the main thread may change it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class _Pool:
    """A process pool that hands out sessions and knows which it handed out."""

    def __init__(self, workers: int) -> None:
        self.executor = ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"))
        self.running: dict[Future, SessionTask] = {}

    def submit(self, task: SessionTask) -> None:
        with _sigint_ignored():  # a submit starts a worker process when none is idle
            self.running[self.executor.submit(run_session, task)] = task

    def stop(self) -> None:
        """Terminate the workers and remove what the sessions they ran left half-written."""
        # ProcessPoolExecutor has no public way to stop its workers mid-task (Python 3.11)
        processes = list((getattr(self.executor, "_processes", None) or {}).values())
        for process in processes:
            with contextlib.suppress(Exception):
                process.terminate()
        for process in processes:
            process.join(timeout=10)
        self.executor.shutdown(wait=True, cancel_futures=True)
        for task in self.running.values():
            clean_leftovers(task.out)


def run_local(
    tasks: Sequence[SessionTask],
    workers: int,
    on_done: Callable[[SessionOutcome], None] | None = None,
) -> list[SessionOutcome]:
    """Run ``tasks`` on ``workers`` local processes (module docstring); ``on_done(outcome)``
    is called as each session ends. Returns the outcomes in the order the sessions ended."""
    queue, suspects = deque(tasks), deque[SessionTask]()
    outcomes: list[SessionOutcome] = []
    lone: SessionTask | None = None  # a suspect running alone
    pool: _Pool | None = None
    with _worker_environment():
        try:
            while queue or suspects or (pool and pool.running):
                if pool is None:
                    pool = _Pool(workers)
                if suspects and not pool.running:
                    lone = suspects.popleft()
                    pool.submit(lone)
                while not suspects and queue and len(pool.running) < workers:
                    pool.submit(queue.popleft())
                done, _ = wait(pool.running, return_when=FIRST_COMPLETED)
                broken = False
                for future in done:
                    task = pool.running.pop(future)
                    try:
                        outcome = future.result()
                    except BrokenProcessPool:
                        broken = True
                        if task is not lone:
                            log.warning("%s: a worker process died; running it again", task.name)
                            suspects.append(task)
                            continue
                        outcome = SessionOutcome(task.name, task.session, error=DIED)
                    lone = None if task is lone else lone
                    outcomes.append(outcome)
                    if on_done is not None:
                        on_done(outcome)
                if broken and not pool.running:
                    pool.stop()
                    pool = None
        except BaseException:
            if pool is not None:
                pool.stop()
                pool = None
            raise
        finally:
            if pool is not None:
                pool.executor.shutdown(wait=True)
    return outcomes
