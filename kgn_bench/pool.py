"""The one resumable job pool behind benchmark runs and dataset generation.

Callers keep their own record of finished work on disk (``trials.jsonl``, whole scene folders) and pass
only the jobs still to do, so a rerun resumes. Jobs run in this process when ``workers`` is 1 (or one job is
left), else in ``spawn``ed worker processes, each set up once by ``initializer``; results come back as they
finish and ``on_result`` stores each at once, so a kill loses only the jobs in flight.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import AbstractContextManager, nullcontext
from multiprocessing import get_context
from typing import Any, TypeVar

from kgn_bench.errors import KGNBenchError

__all__ = ["PoolError", "run_jobs"]

J = TypeVar("J")
R = TypeVar("R")


class PoolError(KGNBenchError, RuntimeError):
    """A worker process died (killed, out of memory, a crash in native code) while jobs were running."""


def run_jobs(jobs: Sequence[J], work: Callable[[J], R], on_result: Callable[[R], Any], *, workers: int = 1,
             initializer: Callable[..., None] | None = None, initargs: Iterable[Any] = (),
             local: Callable[[], AbstractContextManager[Any]] = nullcontext, what: str = "jobs") -> None:
    """Run ``work(job)`` for every job and pass each result to ``on_result`` (in completion order).

    ``local`` is entered around the in-process path (e.g. the trial thread settings); ``initializer``
    prepares each worker process. An exception from ``work`` stops the pool (pending jobs are cancelled)
    and is raised here; a worker that dies raises ``PoolError`` naming ``what``.
    """
    if workers < 1:
        raise ValueError("workers must be ≥ 1")
    if workers == 1 or len(jobs) <= 1:
        with local():
            for job in jobs:
                on_result(work(job))
        return
    try:
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=get_context("spawn"), initializer=initializer,
                                 initargs=tuple(initargs)) as pool:
            futures = [pool.submit(work, job) for job in jobs]
            try:
                for fut in as_completed(futures):
                    on_result(fut.result())
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
    except BrokenProcessPool:
        raise PoolError(f"a worker process died while running {what}; the finished ones are kept, rerun the same "
                        "command to resume") from None
