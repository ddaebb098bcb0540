"""The recorded environment: the versions that can move an outcome."""

from importlib.metadata import version

from kgn_bench.environment import OUTCOME_PACKAGES, cpu_model, environment, environment_differences


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


def test_the_cpu_is_recorded_and_compared_when_both_records_know_it():
    a = environment()
    assert a["cpu"] is None or (isinstance(a["cpu"], str) and a["cpu"])
    other = {**a, "cpu": "Some Other CPU"}
    if a["cpu"]:
        assert environment_differences(a, other) == [f"cpu {a['cpu']} → Some Other CPU"]
    older = {k: v for k, v in a.items() if k != "cpu"}  # a run.json from before the CPU was recorded
    assert environment_differences(older, other) == []


def test_the_cpu_record_tells_generations_apart_that_share_a_name():
    """Two virtual machines that both call their CPU "AMD EPYC": the family, model and vector width differ."""
    zen5 = ("processor\t: 0\nmodel name\t: AMD EPYC\ncpu family\t: 26\nmodel\t\t: 2\n"
            "flags\t\t: fpu sse4_2 avx avx2 avx512f\n")
    zen2 = "processor\t: 0\nmodel name\t: AMD EPYC\ncpu family\t: 23\nmodel\t\t: 49\nflags\t\t: fpu sse4_2 avx avx2\n"
    assert cpu_model(zen5 + "\n" + zen2.replace("AMD EPYC", "ignored")) == "AMD EPYC (family 26, model 2, AVX-512)"
    assert cpu_model(zen2) == "AMD EPYC (family 23, model 49, AVX2)"
    assert cpu_model("model name\t: Some CPU\n") == "Some CPU"
