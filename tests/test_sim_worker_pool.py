"""The simulator's worker forkserver (gaitnet.sim.worker_pool): Ctrl-C is ignored only while
the forkserver first starts, never when a running one is checked again."""

from __future__ import annotations

import multiprocessing
import signal

import pytest

from gaitnet.sim.worker_pool import start_forkserver, worker_context


@pytest.mark.skipif(
    "forkserver" not in multiprocessing.get_all_start_methods(), reason="no forkserver here"
)
def test_a_ctrl_c_while_a_running_forkserver_is_checked_is_not_lost(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # as from a terminal (a shell's background job would start with SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _check_ctrl_c_kept(monkeypatch)
    finally:
        signal.signal(signal.SIGINT, previous)


def _check_ctrl_c_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    from multiprocessing import forkserver

    ctx = worker_context()
    start_forkserver(ctx)  # started (or found) by this process
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

    def interrupted_check() -> None:
        signal.raise_signal(signal.SIGINT)  # Ctrl-C while the running server is checked

    monkeypatch.setattr(forkserver, "ensure_running", interrupted_check)
    with pytest.raises(KeyboardInterrupt):
        start_forkserver(ctx)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
