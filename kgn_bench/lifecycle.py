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

A file being written when the signal comes is finished first (``deferred_stop``, around every
``io.atomic_write``): the stop takes effect right after it, so a checkpoint or a record is whole or absent.
A signal sent to the whole process group (``kill -- -PGID``, a scheduler stopping a job) reaches the workers
too: they ignore it (``ignore_stop_signals``) and are stopped by their parent as above.
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

__all__ = ["STOP_SIGNALS", "Stopped", "deferred_stop", "die_with_parent", "ignore_stop_signals",
           "interrupts_as_keyboard", "loader_worker_init", "start_worker", "stop_workers"]

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


def ignore_stop_signals() -> None:
    """In a worker process: SIGINT, SIGTERM and SIGHUP ignored, so a signal sent to the whole process group
    leaves the worker to its parent, which stops it (``stop_workers``, a DataLoader's shut-down) after its own
    clean-up."""
    for sig in (signal.SIGINT, *STOP_SIGNALS):
        signal.signal(sig, signal.SIG_IGN)


def loader_worker_init(worker_id: int) -> None:
    """``worker_init_fn`` of a training ``torch.utils.data.DataLoader``: the worker dies with the training
    process (``die_with_parent``) and ignores the stop signals (``ignore_stop_signals``): a group SIGTERM
    stops the training process, which shuts its loader down, instead of killing the loader under it."""
    die_with_parent(os.getppid())
    ignore_stop_signals()


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


@contextmanager
def deferred_stop() -> Iterator[None]:
    """Within the block, SIGINT, SIGTERM and SIGHUP are held: one that arrives is acted on when the block
    ends (its previous handler called: ``Stopped`` or ``KeyboardInterrupt`` raised, a default action taken
    by re-sending the signal), so the block (a file being written) is never cut in the middle. Outside the
    main thread nothing is changed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    held = [sig for sig in (signal.SIGINT, *STOP_SIGNALS) if signal.getsignal(sig) is not None]  # None: not Python's
    previous = {sig: signal.signal(sig, lambda signum, frame: pending.append(signum)) for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if pending:
            handler = previous[pending[0]]
            if callable(handler):
                handler(pending[0], None)
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), pending[0])
