"""One session of a batch, run where a worker runs it: a local worker process or a Ray task
(the same function, so both write the same folders; docs/batch.md).

:func:`run_session` opens the session, runs ``gaitnet infer``'s own code
(:func:`gaitnet.pipeline.infer_folder.write_infer_folder`) into ``DIR/<name>/`` and returns a
:class:`SessionOutcome`; it never raises for a broken session: the error's one line is in the
outcome, so one failure stops nothing. The two networks are loaded once per worker process
and kept for its next sessions. Warnings the pipeline logs while it runs travel back in the
outcome, for the calling process to log under the session's name.
"""

from __future__ import annotations

import logging
import os
import socket
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from gaitnet.errors import USER_ERRORS, one_line, user_error_message

if TYPE_CHECKING:  # a worker imports the pipeline with its first session, not before
    from gaitnet.pipeline.config import InferConfig
    from gaitnet.pipeline.infer_folder import InferModels

__all__ = [
    "COMPLETE_FILE",
    "SessionOutcome",
    "SessionTask",
    "is_complete",
    "run_session",
    "thread_settings",
    "usable_cores",
]

COMPLETE_FILE = "summary.json"
"""A result folder is complete when it holds this file: ``gaitnet infer`` writes it last into
the staging folder, which then appears whole (:mod:`gaitnet.pipeline.infer_folder`)."""


def is_complete(folder: Path) -> bool:
    """Whether ``folder`` is a complete result (:data:`COMPLETE_FILE`)."""
    return (folder / COMPLETE_FILE).is_file()


def usable_cores() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def thread_settings(cores: int, workers: int) -> tuple[int, int]:
    """``(pipeline.workers, models.threads)`` for one of ``workers`` sessions run at once on
    ``cores`` CPUs: each session gets ``max(1, cores // workers)`` threads, the segmentation
    threads first (at most 2, ``gaitnet infer``'s default), then onnxruntime threads per
    network call, so that workers × threads ≤ cores wherever workers ≤ cores."""
    budget = max(1, cores // max(1, workers))
    segmentation = min(2, budget)
    return segmentation, max(1, budget // segmentation)


@dataclass(frozen=True)
class SessionTask:
    """What a worker needs for one session: the session's path, the output folder, the
    resolved config (threads included) and ``software`` for ``summary.json``."""

    session: str
    name: str
    out: str
    config: InferConfig
    software: str


@dataclass(frozen=True)
class SessionOutcome:
    """How one session went: ``error`` is None when its folder was written, else one line;
    ``detail`` the traceback of a bug in gaitnet (else empty); ``warnings`` what the pipeline
    logged; ``startup_s`` the seconds before the pipeline started (imports and models on a
    worker's first session, opening the session), ``infer_s`` the pipeline and the writing,
    ``cpu_s`` the CPU seconds of the worker process (all its threads) over both;
    ``worker`` ``host:pid`` of the process that ran it."""

    name: str
    session: str
    error: str | None = None
    detail: str = ""
    warnings: tuple[str, ...] = field(default_factory=tuple)
    startup_s: float = 0.0
    infer_s: float = 0.0
    cpu_s: float = 0.0
    worker: str = ""

    @property
    def ok(self) -> bool:
        """The result folder was written."""
        return self.error is None


_MODELS: dict[tuple, InferModels] = {}  # the networks this worker process has loaded


def _models(cfg: InferConfig) -> InferModels:
    from gaitnet.pipeline.infer_folder import load_models

    key = (cfg.models, cfg.edge_refine)
    if key not in _MODELS:
        _MODELS.clear()
        _MODELS[key] = load_models(cfg)
    return _MODELS[key]


class _Collect(logging.Handler):
    """Keep the messages of warnings and errors logged during one session."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(one_line(record.getMessage(), limit=500))


def run_session(task: SessionTask) -> SessionOutcome:
    """Run ``gaitnet infer`` on ``task.session`` into ``task.out`` (module docstring); a folder
    there without :data:`COMPLETE_FILE` is replaced."""
    start, cpu = time.perf_counter(), time.process_time()
    collect = _Collect()
    root = logging.getLogger()
    root.addHandler(collect)
    error, detail, startup = None, "", 0.0
    try:
        from gaitnet.io import open_session
        from gaitnet.pipeline.infer_folder import write_infer_folder

        models = _models(task.config)
        session = open_session(task.session)
        startup = time.perf_counter() - start
        write_infer_folder(
            session,
            task.config,
            models,
            task.out,
            {"path": task.session, "software": task.software},
            overwrite=True,
        )
    except USER_ERRORS as exc:
        error = user_error_message(exc)
    except Exception as exc:  # a bug in gaitnet: named as one, and the others go on
        error = f"internal error, a bug in gaitnet: {type(exc).__name__}: {one_line(exc, 300)}"
        detail = traceback.format_exc()
    finally:
        root.removeHandler(collect)
    total = time.perf_counter() - start
    return SessionOutcome(
        name=task.name,
        session=task.session,
        error=error,
        detail=detail,
        warnings=tuple(collect.messages),
        startup_s=startup if error is None else 0.0,
        infer_s=total - startup if error is None else total,
        cpu_s=time.process_time() - cpu,
        worker=f"{socket.gethostname()}:{os.getpid()}",
    )
