"""Thread settings of trial execution, identical in every path so that outcomes do not depend on how
trials are scheduled.

A trial runs its detector, the selector and the physics on one thread: torch (intra-op), OpenCV, the BLAS
and OpenMP pools (through threadpoolctl) and Mesa's software rasteriser (``LP_NUM_THREADS``) all get one.
Floating-point reductions split over a different number of threads add in a different order, and a
difference in the last bit of a network output can flip a grasp; with one thread everywhere a trial gives
the same record in the main process (``--workers 1``), in a local pool worker or on a cluster worker.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["TRIAL_THREADS", "available_cores", "pin_worker_threads", "trial_threads"]

TRIAL_THREADS = 1
"""Threads per trial (every library)."""


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity, else ``os.cpu_count()``)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _set_torch_threads(n: int) -> int | None:
    """Set torch's intra-op threads if torch is loaded; returns the previous count (None without torch)."""
    torch = sys.modules.get("torch")
    if torch is None:
        return None
    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    return previous


def pin_worker_threads() -> None:
    """For a process that only runs jobs (a pool or cluster worker): one thread everywhere, for good. Call it
    after the detector is built, so that torch, if the detector loaded it, is covered too."""
    os.environ["LP_NUM_THREADS"] = str(TRIAL_THREADS)
    os.environ.setdefault("OMP_NUM_THREADS", str(TRIAL_THREADS))
    import cv2
    from threadpoolctl import threadpool_limits

    cv2.setNumThreads(TRIAL_THREADS)
    threadpool_limits(TRIAL_THREADS)
    _set_torch_threads(TRIAL_THREADS)


@contextmanager
def trial_threads() -> Iterator[None]:
    """Within the block, this process runs with the trial thread settings; the previous ones come back
    after it (for trials run in the caller's own process)."""
    import cv2
    from threadpoolctl import threadpool_limits

    saved_lp = os.environ.get("LP_NUM_THREADS")
    saved_cv = cv2.getNumThreads()
    torch = sys.modules.get("torch")
    saved_torch = torch.get_num_threads() if torch is not None else None  # before threadpoolctl lowers OpenMP's
    try:
        with threadpool_limits(TRIAL_THREADS):  # entered first and left first: it restores OpenMP's count
            os.environ["LP_NUM_THREADS"] = str(TRIAL_THREADS)
            cv2.setNumThreads(TRIAL_THREADS)
            _set_torch_threads(TRIAL_THREADS)
            yield
    finally:
        cv2.setNumThreads(saved_cv)
        if saved_torch is not None:
            _set_torch_threads(saved_torch)
        if saved_lp is None:
            os.environ.pop("LP_NUM_THREADS", None)
        else:
            os.environ["LP_NUM_THREADS"] = saved_lp
