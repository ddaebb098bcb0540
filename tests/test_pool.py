"""The job pool: the same results in process and in workers, a dead worker named in one line."""

import os
from contextlib import contextmanager

import pytest

from kgn_bench.pool import LOCAL, Backend, PoolError, run_jobs


def square(x: int) -> int:
    return x * x


def die(x: int) -> int:
    if x == 2:
        os._exit(3)  # a worker killed mid-job
    return x


def fail(x: int) -> int:
    raise ValueError(f"bad job {x}")


@pytest.mark.parametrize("workers", [1, 2])
def test_results_arrive_once_each(workers):
    got = []
    run_jobs(list(range(6)), square, got.append, workers=workers)
    assert sorted(got) == [0, 1, 4, 9, 16, 25]


def test_the_local_context_wraps_the_in_process_path():
    events = []

    @contextmanager
    def local():
        events.append("enter")
        yield
        events.append("exit")

    run_jobs([1, 2], square, lambda r: events.append(r), local=local)
    assert events == ["enter", 1, 4, "exit"]


def test_a_dead_worker_is_one_line_and_finished_results_are_kept():
    got = []
    with pytest.raises(PoolError, match=r"^a worker process died while running my jobs; the finished ones are kept"):
        run_jobs([0, 1, 2, 3, 4, 5], die, got.append, workers=2, what="my jobs")
    assert set(got) <= {0, 1, 3, 4, 5}


def test_a_job_error_is_raised_as_it_is():
    with pytest.raises(ValueError, match="bad job"):
        run_jobs([1, 2, 3], fail, print, workers=2)
    with pytest.raises(ValueError, match="workers"):
        run_jobs([1], square, print, workers=0)


def test_a_ray_backend_reserves_the_tasks_resources_unless_the_command_set_gpus():
    ray = Backend("ray", address="10.0.0.1:6379")
    assert ray.reserving(2.0, 0.5) == Backend("ray", address="10.0.0.1:6379", num_cpus=2.0, num_gpus=0.5)
    assert Backend("ray", num_gpus=0.25).reserving(1.0, 0.5).num_gpus == 0.25  # --num-gpus wins
    assert LOCAL.reserving(4.0, 1.0) is LOCAL  # the local pool reserves nothing
