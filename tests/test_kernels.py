"""The portable kernel set: which switches are set, when, and what the libraries then dispatch to."""

import json
import os
import subprocess
import sys

import pytest

from kgn_bench import kernels
from kgn_bench.pool import run_jobs

AVX2 = frozenset({"sse4_2", "avx", "avx2", "fma"})
SKX = AVX2 | {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"}
X86 = os.uname().machine == "x86_64"


@pytest.mark.skipif(not X86, reason="the portable set is for x86-64")
def test_apply_sets_every_switch_and_opencvs_only_where_the_cpu_has_avx512():
    env: dict[str, str] = {}
    assert kernels.apply(env, AVX2) == kernels.PORTABLE_ENV == env
    assert "OPENCV_CPU_DISABLE" not in env  # OpenCV warns when told to disable a feature the CPU lacks
    env = {}
    kernels.apply(env, SKX)
    assert env == {**kernels.PORTABLE_ENV, "OPENCV_CPU_DISABLE": "AVX512-SKX"}


def test_apply_keeps_what_the_user_set_and_does_nothing_natively_or_below_avx2():
    env = {"OPENBLAS_CORETYPE": "Zen"}
    kernels.apply(env, AVX2)
    assert env["OPENBLAS_CORETYPE"] == "Zen"
    env = {kernels.KERNELS_VAR: "native"}
    assert kernels.apply(env, SKX) == {} and env == {kernels.KERNELS_VAR: "native"}
    env = {}
    assert kernels.apply(env, frozenset({"sse4_2", "avx"})) == {} and env == {}


def test_an_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="KGN_BENCH_KERNELS must be one of portable, native"):
        kernels.mode({kernels.KERNELS_VAR: "fast"})


def test_cpu_flags_come_from_the_first_processor():
    text = "processor\t: 0\nflags\t\t: fpu avx avx2\n\nprocessor\t: 1\nflags\t\t: fpu avx avx2 avx512f\n"
    assert kernels.cpu_flags(text) == frozenset({"fpu", "avx", "avx2"})


def _describe_in(env: dict[str, str], first: str = "kgn_bench") -> dict:
    code = (f"import {first}, kgn_bench, numpy, cv2, torch, json; from kgn_bench import kernels; "
            "print(json.dumps(kernels.describe()))")
    base = {k: v for k, v in os.environ.items() if k not in kernels.portable_env() and k != kernels.KERNELS_VAR}
    proc = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                          check=True)
    return json.loads(proc.stdout)


needs_v3 = pytest.mark.skipif(not (X86 and AVX2 <= kernels.cpu_flags()), reason="a CPU without x86-64-v3")


@needs_v3
def test_a_process_that_imports_kgn_bench_first_computes_with_the_portable_set():
    d = _describe_in({})
    assert d["set"] == kernels.PORTABLE and d["reason"] == ""
    assert d["effective"]["numpy"] == "X86_V3" and d["effective"]["torch"] == "AVX2"
    assert d["effective"]["opencv"] == "AVX2"


@needs_v3
def test_native_mode_and_a_library_loaded_first_are_reported_as_native():
    d = _describe_in({kernels.KERNELS_VAR: "native"})
    assert d["set"] == "native" and d["reason"] == "KGN_BENCH_KERNELS=native"
    if "avx512f" in kernels.cpu_flags():  # only a CPU above the set shows uncapped kernels
        assert d["effective"]["torch"] == "AVX512"
        d = _describe_in({}, first="numpy")
        assert d["set"] == "native" and d["reason"].startswith("loaded before kgn_bench: numpy")


def _describe_job(_: int) -> dict:
    return kernels.describe()


@needs_v3
def test_pool_workers_inherit_the_portable_set():
    import numpy  # noqa: F401  (loaded in the worker too, by the job's module)

    out: list[dict] = []
    run_jobs([0, 1], _describe_job, out.append, workers=2)
    assert [d["set"] for d in out] == [kernels.PORTABLE] * 2


def test_ray_workers_get_the_drivers_switches():
    from kgn_bench.cluster import worker_env

    env = worker_env()
    for key in kernels.PORTABLE_ENV:
        assert env.get(key) == os.environ.get(key)
