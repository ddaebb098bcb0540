"""CoACD run in a child process: a C++ assertion inside CoACD aborts the process that calls it, so the
importer calls it here and turns a crash into an ``ObjectError`` instead of losing the caller.

This module imports nothing but numpy, coacd and ``kgn_bench.lifecycle``, so the spawned child starts quickly;
the child dies with its parent, and a signal that stops the import stops it too.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context

import numpy as np

from kgn_bench.lifecycle import die_with_parent, stop_workers

__all__ = ["CoACDCrash", "decompose"]


class CoACDCrash(RuntimeError):
    """The child running CoACD died (an assertion or a signal), or CoACD raised."""


def _run(vertices: np.ndarray, faces: np.ndarray, settings: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    import os

    import coacd

    quiet = os.open(os.devnull, os.O_WRONLY)  # an assertion's message goes to the C stderr; the caller reports
    os.dup2(quiet, 2)

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(vertices, faces), **settings)
    return [(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in parts]


def decompose(vertices: np.ndarray, faces: np.ndarray, settings: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    """``coacd.run_coacd`` with keyword ``settings`` on the mesh, in a spawned child process; the convex
    pieces as (vertices, faces) arrays. ``CoACDCrash`` names what went wrong."""
    pool = ProcessPoolExecutor(1, mp_context=get_context("spawn"), initializer=die_with_parent,
                               initargs=(os.getpid(),))
    try:
        result = pool.submit(_run, np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64),
                             settings).result()
    except BrokenProcessPool:
        stop_workers(pool)
        raise CoACDCrash("CoACD crashed (its process died)") from None
    except Exception as e:  # CoACD raises RuntimeError and others from C++
        stop_workers(pool)
        raise CoACDCrash(f"CoACD failed ({type(e).__name__}: {e})") from None
    except BaseException:  # Ctrl-C, SIGTERM: the child stops with the command
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)
    return result
