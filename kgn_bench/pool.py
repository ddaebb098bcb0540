"""The one resumable job pool behind benchmark runs and dataset generation.

Callers keep their own record of finished work on disk (``trials.jsonl``, whole scene folders) and pass
only the jobs still to do, so a rerun resumes. Jobs run in this process when ``workers`` is 1 (or one job is
left), else in ``spawn``ed worker processes, each set up once by ``initializer``; results come back as they
finish and ``on_result`` stores each at once, so a kill loses only the jobs in flight. Workers die with this
process, and an exception or a signal here stops them at once (``kgn_bench.lifecycle``).

``backend`` says where the jobs run: ``Backend()`` (the default) is this machine's pool above;
``Backend("ray", address)`` hands them to ``kgn_bench.cluster`` (one Ray task per job, results streamed back to
this process, which stores them exactly as with the local pool). Ray is imported only then.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, replace
from multiprocessing import get_context
from typing import Any, TypeVar

from kgn_bench.errors import InputError, KGNBenchError
from kgn_bench.lifecycle import start_worker, stop_workers

__all__ = ["BACKENDS", "LOCAL", "Backend", "PoolError", "run_jobs"]

BACKENDS = ("local", "ray")

J = TypeVar("J")
R = TypeVar("R")


class PoolError(KGNBenchError, RuntimeError):
    """A worker process died (killed, out of memory, a crash in native code) while jobs were running."""


@dataclass(frozen=True)
class Backend:
    """Where jobs run. ``local``: this process or its spawned workers. ``ray``: a Ray cluster at ``address``
    (None: ``RAY_ADDRESS``, else a local Ray on this machine's cores), each job a task holding ``num_cpus``
    CPUs and ``num_gpus`` GPUs (a fraction shares one: 0.25 puts four jobs on a GPU)."""

    kind: str = "local"
    address: str | None = None
    num_cpus: float = 1.0
    num_gpus: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in BACKENDS:
            raise InputError(f"backend must be one of {', '.join(BACKENDS)}, got {self.kind!r}")
        if self.kind == "local" and (self.address or self.num_gpus):
            raise InputError("--address and --num-gpus need --backend ray")
        if self.num_cpus <= 0 or self.num_gpus < 0:
            raise ValueError("num_cpus must be > 0 and num_gpus ≥ 0")

    def reserving(self, num_cpus: float, num_gpus: float = 0.0) -> Backend:
        """This backend with each job reserving ``num_cpus`` CPUs and ``num_gpus`` GPUs (a task's
        ``[resources]``), unless ``--num-gpus`` already set the GPUs here. The local pool reserves nothing and
        is returned as it is."""
        if self.kind == "local":
            return self
        return replace(self, num_cpus=num_cpus, num_gpus=self.num_gpus or num_gpus)

    def prepare(self, initializer: Callable[..., None] | None = None, initargs: Iterable[Any] = (),
                workers: int = 1) -> Callable[[], None]:
        """Start checking that the jobs can run there; the returned call waits for the answer, so that the
        caller's own checks overlap it, and must be made before anything is written. For Ray: join the cluster
        (an unreachable one raises here) and set up the ``workers`` that will run the jobs with
        ``initializer(*initargs)`` (``cluster.ClusterError`` in one line from the wait if the first set-up fails).
        Locally: nothing to check."""
        if self.kind == "ray":
            from kgn_bench.cluster import connect

            return connect(self.address, initializer, initargs, self.num_cpus, self.num_gpus, workers)
        return lambda: None


LOCAL = Backend()


def run_jobs(jobs: Sequence[J], work: Callable[[J], R], on_result: Callable[[R], Any], *, workers: int = 1,
             initializer: Callable[..., None] | None = None, initargs: Iterable[Any] = (),
             local: Callable[[], AbstractContextManager[Any]] = nullcontext, what: str = "jobs",
             backend: Backend = LOCAL) -> None:
    """Run ``work(job)`` for every job and pass each result to ``on_result`` (in completion order).

    ``local`` is entered around the in-process path (e.g. the trial thread settings); ``initializer``
    prepares each worker process. An exception from ``work`` stops the pool (pending jobs are cancelled)
    and is raised here; a worker that dies raises ``PoolError`` naming ``what``. On ``backend`` ray,
    ``workers`` is the number of jobs in flight on the cluster (``cluster.run_ray_jobs``).
    """
    if workers < 1:
        raise ValueError("workers must be ≥ 1")
    if backend.kind == "ray":
        from kgn_bench.cluster import run_ray_jobs

        if jobs:
            run_ray_jobs(jobs, work, on_result, address=backend.address, workers=workers, initializer=initializer,
                         initargs=initargs, num_cpus=backend.num_cpus, num_gpus=backend.num_gpus, what=what)
        return
    if workers == 1 or len(jobs) <= 1:
        with local():
            for job in jobs:
                on_result(work(job))
        return
    pool = ProcessPoolExecutor(min(workers, len(jobs)), mp_context=get_context("spawn"), initializer=start_worker,
                               initargs=(os.getpid(), initializer, *initargs))
    try:
        futures = [pool.submit(work, job) for job in jobs]
        for fut in as_completed(futures):
            on_result(fut.result())
    except BrokenProcessPool:
        stop_workers(pool)
        raise PoolError(f"a worker process died while running {what}; the finished ones are kept, rerun the same "
                        "command to resume") from None
    except BaseException:  # an error, Ctrl-C, SIGTERM: the workers stop now, the finished jobs are kept
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)
