"""Process lifetime: a command stopped by a signal stops everything it started.

Three rules, for every command that starts worker processes (``run``, ``benchmark``, ``sweep``,
``data generate``, ``objects add``):

* SIGTERM and SIGHUP end a command exactly as Ctrl-C does (``interrupts_as_keyboard``: they raise
  ``KeyboardInterrupt`` in the main thread), so the same clean-up runs: the pool's workers are stopped
  (``stop_workers``), temporary folders are removed, the run folder's lock is released, and a rerun resumes.
  A scheduler (Slurm, Kubernetes) stops a job with SIGTERM.
* A worker dies with its parent (``die_with_parent``, the pool's initializer): Linux sends it SIGKILL when
  the process that started it ends for any reason, ``kill -9`` included, so no worker is left under init.
* Workers are stopped, not waited for: a trial in flight is lost (its record was never written) and is run
  again by the rerun.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["STOP_SIGNALS", "Stopped", "die_with_parent", "interrupts_as_keyboard", "start_worker", "stop_workers"]

STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
"""The signals that end a command as Ctrl-C (SIGINT) does."""

_PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int) -> None:
    """Have the kernel send this process SIGKILL when its parent ends (Linux ``PR_SET_PDEATHSIG``); exit at
    once if the parent ``parent_pid`` is already gone. Elsewhere nothing is set."""
    if not sys.platform.startswith("linux"):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
        return
    if os.getppid() != parent_pid:  # the parent died before the call: nobody would send the signal
        os._exit(1)


def start_worker(parent_pid: int, initializer: Callable[..., None] | None, *initargs: Any) -> None:
    """A pool worker's first call: ``die_with_parent``, the default SIGINT handler's behaviour for a worker
    (ignored: the parent decides when the pool stops), then ``initializer(*initargs)``."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_DFL)
    if initializer is not None:
        initializer(*initargs)


def stop_workers(pool: Any) -> None:
    """Kill the worker processes of a ``concurrent.futures.ProcessPoolExecutor`` and reap them, then shut
    it down without waiting for its jobs."""
    processes = list(getattr(pool, "_processes", {}).values())  # no public handle before Python 3.14
    for p in processes:
        if p.is_alive():
            p.kill()
    for p in processes:
        p.join(timeout=5)
    pool.shutdown(wait=False, cancel_futures=True)


class Stopped(KeyboardInterrupt):
    """``KeyboardInterrupt`` raised by a stop signal; ``signum`` is the signal (exit status 128 + signum)."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum


def _raise_interrupt(signum: int, frame: Any) -> None:
    raise Stopped(signum)


@contextmanager
def interrupts_as_keyboard() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise ``KeyboardInterrupt`` in the main thread, as SIGINT does;
    the previous handlers come back after it. Outside the main thread nothing is changed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, _raise_interrupt) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
