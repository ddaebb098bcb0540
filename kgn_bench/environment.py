"""The software environment a result was produced in: the versions of every package that can move an
outcome, recorded in each run's ``run.json`` and compared by ``kgn-bench report``.

The packages are the ones the lock file ``constraints.txt`` pins for that reason: the physics (mujoco,
dm-control), the IK and its QP solver (mink, qpsolvers, daqp), the network (torch), PnP and image codecs
(opencv-python-headless), the numerics (numpy, scipy) and the meshes (trimesh). The CPU model and the kernel
set (``kernels.describe``) are recorded too: with the portable set every library computes with the same
AVX2 kernels on any x86-64 CPU that has them, so two records that both hold it are the same environment
whatever their CPUs; with native kernels the CPU is part of the environment, since another CPU may pick
other vector kernels whose last-bit differences flip a borderline trial.
"""

from __future__ import annotations

import platform
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from kgn_bench import kernels

__all__ = ["OUTCOME_PACKAGES", "computed_with", "cpu_model", "environment", "environment_differences", "kernel_set",
           "portable", "renderer"]

OUTCOME_PACKAGES = ("mujoco", "dm-control", "mink", "qpsolvers", "daqp", "torch", "opencv-python-headless",
                    "numpy", "scipy", "trimesh")


def environment() -> dict[str, Any]:
    """Python, the machine's architecture, the CPU, the kernel set (``kernels.describe``), the OpenGL
    renderer and the version of each of ``OUTCOME_PACKAGES`` (None if absent)."""
    packages: dict[str, str | None] = {}
    for name in OUTCOME_PACKAGES:
        try:
            packages[name] = version(name)
        except PackageNotFoundError:
            packages[name] = None
    return {"python": platform.python_version(), "machine": platform.machine(), "cpu": cpu_model(),
            "kernels": kernels.describe(), "renderer": renderer(), "packages": packages}


@lru_cache(maxsize=1)
def renderer() -> str | None:
    """The OpenGL implementation that renders the camera images (``MUJOCO_GL``'s), e.g. ``Mesa 22.3.6,
    llvmpipe (LLVM 15.0.6, 256 bits)``: a system library, not a Python package, and its version can move a
    pixel. None if no context can be made."""
    try:
        import mujoco
        from OpenGL import GL

        ctx = mujoco.GLContext(1, 1)
        ctx.make_current()
        try:
            version, name = (GL.glGetString(k).decode() for k in (GL.GL_VERSION, GL.GL_RENDERER))
        finally:
            ctx.free()
    except Exception:  # no display, no EGL: the record says unknown
        return None
    version = version.split(" ", 1)[1] if " " in version else version  # "4.5 (Compatibility Profile) Mesa …"
    version = version.split(") ", 1)[-1]
    return f"{version}, {name}"


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


def kernel_set(record: dict[str, Any]) -> str:
    """The kernel set of an ``environment()`` record: ``kernels.PORTABLE`` or ``native`` (records made before
    the kernels were recorded computed with native kernels)."""
    return (record.get("kernels") or {}).get("set", "native")


def computed_with() -> str:
    """What this process's numbers are reproducible across, in one string for a manifest: the portable kernel
    set's name (any x86-64 CPU with AVX2 gives the same results), or ``native (<CPU>)`` (only this CPU does)."""
    described = kernels.describe()
    return described["set"] if described["set"] == kernels.PORTABLE else f"native ({cpu_model()})"


def portable(record: dict[str, Any]) -> bool:
    """Whether the record's run computed with the portable kernel set, so that its CPU does not matter."""
    return kernel_set(record) == kernels.PORTABLE


def environment_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """What differs between two ``environment()`` records, as ``name a → b`` strings (empty if nothing). The
    CPUs of two records that both computed with the portable kernel set are not a difference."""
    out = [f"{k} {a.get(k)} → {b.get(k)}" for k in ("python", "machine") if a.get(k) != b.get(k)]
    if a.get("renderer") and b.get("renderer") and a["renderer"] != b["renderer"]:  # unknown in older records
        out.append(f"renderer {a['renderer']} → {b['renderer']}")
    if kernel_set(a) != kernel_set(b):
        out.append(f"kernels {kernel_set(a)} → {kernel_set(b)}")
    elif a.get("cpu") and b.get("cpu") and a["cpu"] != b["cpu"] and not portable(a):
        out.append(f"cpu {a['cpu']} → {b['cpu']}")  # records made before the CPU was recorded: unknown
    pa, pb = a.get("packages", {}), b.get("packages", {})
    out += [f"{k} {pa.get(k)} → {pb.get(k)}" for k in sorted(set(pa) | set(pb)) if pa.get(k) != pb.get(k)]
    return out
