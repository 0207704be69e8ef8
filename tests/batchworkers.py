"""A stand-in for :func:`gaitnet.batch.task.run_session` that worker processes can import
(tests/ is on their ``sys.path``): a task named ``crash...`` kills its worker process, any
other returns at once."""

from __future__ import annotations

import os

from gaitnet.batch.task import SessionOutcome, SessionTask


def crash_or_pass(task: SessionTask) -> SessionOutcome:
    if task.name.startswith("crash"):
        os._exit(3)  # as the kernel's out-of-memory killer would end it: no cleanup, no reply
    return SessionOutcome(task.name, task.session, worker=str(os.getpid()))
