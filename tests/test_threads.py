"""Trial thread settings: one thread everywhere inside the block, the caller's settings after it."""

import os

import cv2
import torch
from threadpoolctl import threadpool_info

from kgn_bench.threads import TRIAL_THREADS, available_cores, trial_threads


def test_trial_threads_pins_and_restores():
    torch.set_num_threads(2)
    before = (cv2.getNumThreads(), os.environ.get("LP_NUM_THREADS"))
    with trial_threads():
        assert torch.get_num_threads() == TRIAL_THREADS == 1
        assert cv2.getNumThreads() == 1 and os.environ["LP_NUM_THREADS"] == "1"
        assert all(p["num_threads"] == 1 for p in threadpool_info())
    assert torch.get_num_threads() == 2
    assert (cv2.getNumThreads(), os.environ.get("LP_NUM_THREADS")) == before


def test_available_cores():
    assert 1 <= available_cores() <= (os.cpu_count() or 1)
