"""The recorded environment: the versions that can move an outcome."""

from importlib.metadata import version

import pytest

from kgn_bench import kernels
from kgn_bench.environment import (
    OUTCOME_PACKAGES,
    cpu_model,
    environment,
    environment_differences,
    kernel_set,
    portable,
)
from kgn_bench.kernels import PORTABLE


def test_environment_records_every_outcome_package():
    env = environment()
    assert set(env["packages"]) == set(OUTCOME_PACKAGES)
    assert env["packages"]["mujoco"] == version("mujoco") and env["packages"]["torch"] == version("torch")
    assert env["python"].count(".") == 2


def test_environment_differences_names_what_moved():
    a = environment()
    assert environment_differences(a, a) == []
    b = {**a, "packages": {**a["packages"], "opencv-python-headless": "4.14.0"}}
    (line,) = environment_differences(a, b)
    assert line.startswith("opencv-python-headless ") and line.endswith("→ 4.14.0")


def test_the_cpu_is_recorded_and_compared_only_under_native_kernels():
    a = environment()
    assert a["cpu"] is None or (isinstance(a["cpu"], str) and a["cpu"])
    native = {**a, "kernels": {"set": "native", "reason": "KGN_BENCH_KERNELS=native", "effective": {}}}
    other = {**native, "cpu": "Some Other CPU"}
    if a["cpu"]:
        assert environment_differences(native, other) == [f"cpu {a['cpu']} → Some Other CPU"]
    older = {k: v for k, v in native.items() if k != "cpu"}  # a run.json from before the CPU was recorded
    assert environment_differences(older, other) == []


def test_two_records_with_the_portable_kernels_are_one_environment_whatever_their_cpus():
    a = {**environment(), "kernels": {"set": PORTABLE, "reason": "", "effective": {}}}
    assert portable(a)
    assert environment_differences(a, {**a, "cpu": "Some Other CPU (family 6, model 85, AVX-512)"}) == []
    native = {**a, "kernels": {"set": "native", "reason": "KGN_BENCH_KERNELS=native", "effective": {}}}
    assert environment_differences(a, native) == [f"kernels {PORTABLE} → native"]
    before = {k: v for k, v in a.items() if k != "kernels"}  # a run.json from before kernels were recorded
    assert kernel_set(before) == "native" and environment_differences(before, a) == [f"kernels native → {PORTABLE}"]


def test_this_process_records_the_portable_kernels():
    """conftest imports kgn_bench before numpy, as the command line does: every library is capped."""
    if not kernels.portable_env() or kernels.describe()["reason"].startswith("this CPU"):
        pytest.skip("a CPU without x86-64-v3")
    import cv2  # noqa: F401
    import torch  # noqa: F401

    record = environment()["kernels"]
    assert record["set"] == PORTABLE, record
    assert record["effective"]["numpy"] == "X86_V3" and record["effective"]["torch"] == "AVX2"


def test_the_cpu_record_tells_generations_apart_that_share_a_name():
    """Two virtual machines that both call their CPU "AMD EPYC": the family, model and vector width differ."""
    zen5 = ("processor\t: 0\nmodel name\t: AMD EPYC\ncpu family\t: 26\nmodel\t\t: 2\n"
            "flags\t\t: fpu sse4_2 avx avx2 avx512f\n")
    zen2 = "processor\t: 0\nmodel name\t: AMD EPYC\ncpu family\t: 23\nmodel\t\t: 49\nflags\t\t: fpu sse4_2 avx avx2\n"
    assert cpu_model(zen5 + "\n" + zen2.replace("AMD EPYC", "ignored")) == "AMD EPYC (family 26, model 2, AVX-512)"
    assert cpu_model(zen2) == "AMD EPYC (family 23, model 49, AVX2)"
    assert cpu_model("model name\t: Some CPU\n") == "Some CPU"
