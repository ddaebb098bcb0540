"""The software environment a result was produced in: the versions of every package that can move an
outcome, recorded in each run's ``run.json`` and compared by ``kgn-bench report``.

The packages are the ones the lock file ``constraints.txt`` pins for that reason: the physics (mujoco,
dm-control), the IK and its QP solver (mink, qpsolvers, daqp), the network (torch), PnP and image codecs
(opencv-python-headless), the numerics (numpy, scipy) and the meshes (trimesh). The CPU model is recorded
too: the same versions on another CPU may pick other vector kernels (torch, numpy, MuJoCo), whose last-bit
differences flip a borderline trial now and then, so runs from different CPUs agree in their rates within
the intervals, not trial by trial.
"""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version
from typing import Any

__all__ = ["OUTCOME_PACKAGES", "cpu_model", "environment", "environment_differences"]

OUTCOME_PACKAGES = ("mujoco", "dm-control", "mink", "qpsolvers", "daqp", "torch", "opencv-python-headless",
                    "numpy", "scipy", "trimesh")


def environment() -> dict[str, Any]:
    """Python, the machine's architecture and the version of each of ``OUTCOME_PACKAGES`` (None if absent)."""
    packages: dict[str, str | None] = {}
    for name in OUTCOME_PACKAGES:
        try:
            packages[name] = version(name)
        except PackageNotFoundError:
            packages[name] = None
    return {"python": platform.python_version(), "machine": platform.machine(), "cpu": cpu_model(),
            "packages": packages}


def cpu_model(cpuinfo: str | None = None) -> str | None:
    """The CPU: its model name, family and model numbers and widest vector extension, e.g. ``AMD EPYC (family
    26, model 2, AVX-512)``; from Linux ``/proc/cpuinfo`` (or the text ``cpuinfo``), else
    ``platform.processor()``; None if unknown.

    A virtual machine may name only the product line (``AMD EPYC``), which hides the generation; the family and
    model numbers tell generations apart, and the vector width decides which kernels torch, numpy and MuJoCo
    run (measured: two machines that both reported ``AMD EPYC`` gave kgnv2 106 and 109 of 120 single_household
    trials with the same code)."""
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo") as f:
                cpuinfo = f.read()
        except OSError:
            return platform.processor() or None
    fields: dict[str, str] = {}
    for line in cpuinfo.split("\n\n", 1)[0].splitlines():  # the first processor's block
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    name = fields.get("model name") or platform.processor() or None
    if name is None:
        return None
    flags = set(fields.get("flags", "").split())
    vector = next((label for flag, label in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"),
                                             ("sse4_2", "SSE4.2")) if flag in flags), None)
    details = [f"family {fields['cpu family']}" if "cpu family" in fields else None,
               f"model {fields['model']}" if "model" in fields else None, vector]
    details = [d for d in details if d]
    return f"{name} ({', '.join(details)})" if details else name


def environment_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """What differs between two ``environment()`` records, as ``name a → b`` strings (empty if nothing)."""
    out = [f"{k} {a.get(k)} → {b.get(k)}" for k in ("python", "machine") if a.get(k) != b.get(k)]
    if a.get("cpu") and b.get("cpu") and a["cpu"] != b["cpu"]:  # records made before the CPU was recorded: unknown
        out.append(f"cpu {a['cpu']} → {b['cpu']}")
    pa, pb = a.get("packages", {}), b.get("packages", {})
    out += [f"{k} {pa.get(k)} → {pb.get(k)}" for k in sorted(set(pa) | set(pb)) if pa.get(k) != pb.get(k)]
    return out
