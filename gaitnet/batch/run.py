"""A batch from start to end (``gaitnet batch``; docs/batch.md): find the sessions, skip those
whose result is complete, run the others on local worker processes or on Ray, then write
``failures.csv``, ``cohort.csv`` and ``cohort.html`` into the output folder.

:func:`plan_batch` checks everything a user can get wrong before anything runs (the sessions,
their names, the output folder, the config); :func:`run_batch` runs the plan.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from gaitnet.batch.cohort import CohortRow, cohort_csv, cohort_rows, write_failures
from gaitnet.batch.sessions import BatchSession, find_sessions
from gaitnet.batch.task import (
    SessionOutcome,
    SessionTask,
    is_complete,
    thread_settings,
    usable_cores,
)
from gaitnet.config import load_config
from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text
from gaitnet.pipeline.config import InferConfig

__all__ = ["BatchPlan", "BatchResult", "plan_batch", "run_batch"]

log = logging.getLogger(__name__)

MAX_WORKERS = 1024


@dataclass(frozen=True)
class BatchPlan:
    """A checked batch: its ``sessions``, the output folder ``out``, and the inference config
    file and ``KEY=VALUE`` overrides every session runs with."""

    sessions: list[BatchSession]
    out: Path
    config: str | None = None
    overrides: tuple[str, ...] = ()

    def todo(self) -> list[BatchSession]:
        """The sessions whose result folder is not complete."""
        return [s for s in self.sessions if not is_complete(self.out / s.name)]


@dataclass
class BatchResult:
    """What a batch did: the ``outcomes`` of the sessions it ran (in the order they ended),
    the names it ``skipped`` (complete already), the ``rows`` of ``cohort.csv``, the
    ``workers`` and the threads of each session ``(pipeline.workers, models.threads)`` (of
    its config: the overrides' where they set them)."""

    plan: BatchPlan
    outcomes: list[SessionOutcome] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    rows: list[CohortRow] = field(default_factory=list)
    workers: int = 0
    threads: tuple[int, int] = (0, 0)
    wall_s: float = 0.0

    @property
    def failed(self) -> list[SessionOutcome]:
        """The sessions that failed, in name order."""
        return sorted((o for o in self.outcomes if not o.ok), key=lambda o: o.name)


def plan_batch(
    inputs: Sequence[str | Path],
    out: str | Path,
    config: str | None = None,
    overrides: Sequence[str] = (),
) -> BatchPlan:
    """Find the sessions (:func:`gaitnet.batch.sessions.find_sessions`) and check the config
    and the model files it names; :class:`InputError` / ``ConfigError`` with one line."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    sessions = find_sessions(inputs, out)
    cfg = load_config(InferConfig, config, list(overrides))
    for key in ("segmenter", "predictor"):
        path = getattr(cfg.models, key)
        if path is not None and not Path(path).is_file():
            raise InputError(f"models.{key}: {path}: no such file")
    return BatchPlan(sessions, out, config, tuple(overrides))


def _tasks(
    plan: BatchPlan, todo: Sequence[BatchSession], threads: tuple[int, int], software: str
) -> list[SessionTask]:
    """Each session's task; the thread settings come before the user's overrides, which win."""
    thread_keys = [f"pipeline.workers={threads[0]}", f"models.threads={threads[1]}"]
    cfg = load_config(InferConfig, plan.config, [*thread_keys, *plan.overrides])
    out = plan.out.absolute()
    return [SessionTask(str(s.path), s.name, str(out / s.name), cfg, software) for s in todo]


def _report(outcome: SessionOutcome) -> None:
    for message in outcome.warnings:
        log.warning("%s: %s", outcome.name, message)
    if outcome.detail:
        log.error("%s: a bug in gaitnet; please report it with:\n%s", outcome.name, outcome.detail)


def _check_workers(workers: int | None) -> None:
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"--workers must be within 1–{MAX_WORKERS}, got {workers}")


def run_batch(
    plan: BatchPlan,
    software: str,
    workers: int | None = None,
    ray: str | None = None,
    on_start: Callable[[int, int], None] | None = None,
    on_done: Callable[[SessionOutcome], None] | None = None,
) -> BatchResult:
    """Run ``plan`` (module docstring) on ``workers`` local processes, or on Ray with ``ray``
    (an address, or ``local``); ``workers`` default: half the CPUs (of the cluster with Ray).
    ``on_start(total, skipped)`` is called once the workers are ready, ``on_done(outcome)`` as
    each session ends; ``software`` goes into each ``summary.json``."""
    _check_workers(workers)
    start = time.perf_counter()
    todo = plan.todo()
    result = BatchResult(plan, skipped=[s.name for s in plan.sessions if s not in todo])

    def done(outcome: SessionOutcome) -> None:
        _report(outcome)
        if on_done is not None:
            on_done(outcome)

    if todo:
        result.workers, cores, node_cpus = _capacity(ray, workers)
        tasks = _tasks(plan, todo, thread_settings(cores, result.workers), software)
        models, pipeline = tasks[0].config.models, tasks[0].config.pipeline
        result.threads = (pipeline.workers, models.threads)
        plan.out.mkdir(parents=True, exist_ok=True)
        if on_start is not None:
            on_start(len(plan.sessions), len(result.skipped))
        if ray is None:
            from gaitnet.batch.local import run_local

            result.outcomes = run_local(tasks, result.workers, done)
        else:
            from gaitnet.batch.ray_runner import run_ray

            cpus = min(node_cpus, max(1, pipeline.workers * models.threads))
            result.outcomes = run_ray(tasks, result.workers, cpus, done)
    elif on_start is not None:
        on_start(len(plan.sessions), len(result.skipped))
    plan.out.mkdir(parents=True, exist_ok=True)
    _write_tables(result)
    result.wall_s = time.perf_counter() - start
    return result


def _capacity(ray: str | None, workers: int | None) -> tuple[int, int, int]:
    """``(workers, cores, node_cpus)``: the sessions run at once, the CPUs they share (for
    :func:`~gaitnet.batch.task.thread_settings`) and the most CPUs one may ask for: this
    machine's, or, with Ray, the cluster's once joined (a session at most the CPUs of its
    smallest node)."""
    if ray is None:
        cores = usable_cores()
        return workers or max(1, cores // 2), cores, cores
    from gaitnet.batch.ray_runner import connect

    cluster = connect(ray, usable_cores())
    workers = workers or max(1, cluster.cpus // 2)
    cores = min(cluster.cpus, cluster.smallest_node_cpus * workers)
    return workers, cores, cluster.smallest_node_cpus


def _write_tables(result: BatchResult) -> None:
    """``failures.csv``, ``cohort.csv`` and ``cohort.html`` of the complete sessions."""
    from gaitnet.batch.cohort_html import render_cohort  # matplotlib: only once it is needed

    out = result.plan.out
    write_failures(out / "failures.csv", result.failed)
    names = [s.name for s in result.plan.sessions if is_complete(out / s.name)]
    result.rows = cohort_rows(out, names)
    atomic_write_text(out / "cohort.csv", cohort_csv(result.rows))
    atomic_write_text(out / "cohort.html", render_cohort(result.rows, result.failed))
