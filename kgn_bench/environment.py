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


def cpu_model() -> str | None:
    """The CPU's model name (Linux ``/proc/cpuinfo``, else ``platform.processor()``), None if unknown."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.partition(":")[2].strip() or None
    except OSError:
        pass
    return platform.processor() or None


def environment_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """What differs between two ``environment()`` records, as ``name a → b`` strings (empty if nothing)."""
    out = [f"{k} {a.get(k)} → {b.get(k)}" for k in ("python", "machine") if a.get(k) != b.get(k)]
    if a.get("cpu") and b.get("cpu") and a["cpu"] != b["cpu"]:  # records made before the CPU was recorded: unknown
        out.append(f"cpu {a['cpu']} → {b['cpu']}")
    pa, pb = a.get("packages", {}), b.get("packages", {})
    out += [f"{k} {pa.get(k)} → {pb.get(k)}" for k in sorted(set(pa) | set(pb)) if pa.get(k) != pb.get(k)]
    return out
