"""The CPU kernels a run computes with: one portable set on every x86-64 CPU with AVX2, so that a run gives
the same records on any such CPU.

Several libraries pick their vector kernels at run time from the CPU they find. Two kernels of the same
operation may sum in another order or use another approximation, so an AVX-512 CPU and an AVX2 CPU give
network outputs, images or small matrix products that differ in the last bits, and a borderline grasp
flips. Each library has a switch, read from the environment when the library loads, that caps its
dispatch; ``apply`` sets them (``PORTABLE_ENV``) before any of them loads:

============  ================================================  =========================================
library       variable                                          what it caps
============  ================================================  =========================================
torch (ATen)  ``ATEN_CPU_CAPABILITY=avx2``                      elementwise and reduction kernels
torch         ``ONEDNN_MAX_CPU_ISA=AVX2``                       oneDNN convolutions (the network)
torch         ``MKL_CBWR=AVX2``                                 MKL's BLAS and FFT: the AVX2 code path
numpy         ``NPY_DISABLE_CPU_FEATURES=X86_V4 AVX512_ICL …``  SIMD dispatch up to x86-64-v3 (AVX2, FMA)
OpenBLAS      ``OPENBLAS_CORETYPE=Haswell``                     numpy's, scipy's and OpenCV's BLAS kernels
OpenCV        ``OPENCV_CPU_DISABLE=AVX512-SKX``                 its AVX-512 paths (on CPUs that have them)
Mesa          ``GALLIUM_OVERRIDE_CPU_CAPS=avx``                 llvmpipe's JIT: no AVX-512 instructions
Mesa          ``LP_NATIVE_VECTOR_WIDTH=256``                    llvmpipe's vector width
============  ================================================  =========================================

MuJoCo needs no switch: its wheel is compiled for one instruction set (AVX, no AVX-512, no run-time
dispatch), and glibc's libm picks its FMA variants on every CPU with AVX2 and FMA.

The set is x86-64-v3 (AVX2 + FMA), which every x86-64 CPU since 2013-2015 has. On a CPU below it, on
another architecture, or when a user asks for speed (``KGN_BENCH_KERNELS=native``), nothing is capped and
records may differ from another CPU's in the last bits; ``describe`` says which case holds and is recorded
in every run's environment (``environment.environment``), so the report and the regression check know
whether the CPU still matters.

A variable only takes effect if it is set before its library initialises. ``kgn_bench/__init__`` calls
``apply`` first thing, so the ``kgn-bench`` command, its pool workers (which inherit the environment) and
any program that imports ``kgn_bench`` before numpy are covered; Ray workers get the variables through their
``runtime_env`` (``cluster.worker_env``). A program that imported numpy or OpenCV before ``kgn_bench`` has
them uncapped, and ``describe`` reports the kernels it finds, not the ones it asked for.
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import MutableMapping
from typing import Any

__all__ = ["KERNELS_VAR", "MODES", "PORTABLE", "PORTABLE_ENV", "apply", "cpu_flags", "describe", "mode",
           "portable_env"]

KERNELS_VAR = "KGN_BENCH_KERNELS"
"""The switch: ``portable`` (the default) caps every library at ``PORTABLE``; ``native`` lets each pick the
fastest kernels of this CPU (faster on AVX-512, records no longer comparable trial by trial across CPUs)."""

MODES = ("portable", "native")

PORTABLE = "x86-64-v3"
"""The name of the portable kernel set: AVX2 and FMA, no AVX-512."""

PORTABLE_ENV: dict[str, str] = {
    "ATEN_CPU_CAPABILITY": "avx2",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "MKL_CBWR": "AVX2",
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OPENBLAS_CORETYPE": "Haswell",
    "GALLIUM_OVERRIDE_CPU_CAPS": "avx",
    "LP_NATIVE_VECTOR_WIDTH": "256",
}
"""The variables of the portable set that every CPU takes (module docstring): each caps one library's
dispatch at AVX2. ``portable_env`` adds OpenCV's, which must name only features the CPU has."""

_OPENCV_AVX512 = ("OPENCV_CPU_DISABLE", "AVX512-SKX")
"""OpenCV's one AVX-512 dispatch target in the locked wheel; OpenCV warns when asked to disable a feature the
CPU lacks, so it is set only on CPUs that have it (``_SKX_FLAGS``)."""
_SKX_FLAGS = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})

_REQUIRED_FLAGS = frozenset({"avx", "avx2", "fma"})


def cpu_flags(cpuinfo: str | None = None) -> frozenset[str]:
    """The first processor's flags from Linux ``/proc/cpuinfo`` (or the text ``cpuinfo``); empty if unknown."""
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo") as f:
                cpuinfo = f.read()
        except OSError:
            return frozenset()
    for line in cpuinfo.split("\n\n", 1)[0].splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "flags":
            return frozenset(value.split())
    return frozenset()


def portable_env(flags: frozenset[str] | None = None) -> dict[str, str]:
    """The variables that cap every library at ``PORTABLE`` on a CPU with ``flags`` (default: this one's)."""
    flags = cpu_flags() if flags is None else flags
    env = dict(PORTABLE_ENV)
    if _SKX_FLAGS <= flags:
        env[_OPENCV_AVX512[0]] = _OPENCV_AVX512[1]
    return env


def _supported(flags: frozenset[str]) -> bool:
    return platform.machine() in ("x86_64", "AMD64") and _REQUIRED_FLAGS <= flags


def mode(environ: MutableMapping[str, str] | None = None) -> str:
    """The requested mode, from ``KGN_BENCH_KERNELS`` (default ``portable``); a ``ValueError`` for another value."""
    environ = os.environ if environ is None else environ
    value = environ.get(KERNELS_VAR, "portable").strip().lower() or "portable"
    if value not in MODES:
        raise ValueError(f"{KERNELS_VAR} must be one of {', '.join(MODES)}, got {value!r}")
    return value


def apply(environ: MutableMapping[str, str] | None = None, flags: frozenset[str] | None = None) -> dict[str, str]:
    """Set ``PORTABLE_ENV`` in ``environ`` (default ``os.environ``) unless the mode is ``native`` or the CPU
    cannot run the set; a variable the user set already is kept. Returns what the portable set asks for
    (empty when nothing applies), for workers started elsewhere (Ray)."""
    environ = os.environ if environ is None else environ
    try:
        requested = mode(environ)
    except ValueError:
        return {}  # reported by describe() and refused by the command line
    flags = cpu_flags() if flags is None else flags
    if requested != "portable" or not _supported(flags):
        return {}
    env = portable_env(flags)
    for key, value in env.items():
        environ.setdefault(key, value)
    return env


def _effective() -> dict[str, str]:
    """The kernels each loaded library actually dispatches to (libraries not loaded yet are left out)."""
    out: dict[str, str] = {}
    np_core = sys.modules.get("numpy._core._multiarray_umath")
    if np_core is not None:
        features = np_core.__cpu_features__
        top = [t for t in np_core.__cpu_dispatch__ if features.get(t)]
        out["numpy"] = top[-1] if top else "baseline"
    torch = sys.modules.get("torch")
    if torch is not None:
        out["torch"] = torch.backends.cpu.get_cpu_capability()
    if "threadpoolctl" in sys.modules:
        from threadpoolctl import threadpool_info

        cores = sorted({i["architecture"] for i in threadpool_info() if i.get("internal_api") == "openblas"
                        and i.get("architecture")})
        if cores:
            out["openblas"] = "/".join(cores)
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        line = cv2.getCPUFeaturesLine().split()
        enabled = [f.lstrip("*") for f in line if not f.endswith("?")]
        out["opencv"] = enabled[-1] if enabled else "baseline"
    return out


_CAPPED = {"numpy": ("X86_V4", "AVX512_ICL", "AVX512_SPR"), "torch": ("AVX512",), "opencv": ("AVX512-SKX",),
           "openblas": ("SkylakeX", "Cooperlake", "SapphireRapids")}
"""Per library, the kernels above the portable set (what an uncapped library shows on an AVX-512 CPU)."""


def describe() -> dict[str, Any]:
    """What this process computes with, for ``run.json``: ``{"set": PORTABLE | "native", "reason": …,
    "effective": {library: top kernel}}``. ``set`` is ``PORTABLE`` only if the portable variables are all in
    force and every loaded library dispatches at or below AVX2; otherwise ``native``, with the reason
    (asked for, a CPU without AVX2, a library loaded before ``kgn_bench``, or a variable overridden)."""
    effective = _effective()
    try:
        requested = mode()
    except ValueError as e:
        return {"set": "native", "reason": str(e), "effective": effective}
    if requested == "native":
        return {"set": "native", "reason": f"{KERNELS_VAR}=native", "effective": effective}
    flags = cpu_flags()
    if not _supported(flags):
        return {"set": "native", "reason": f"this CPU ({platform.machine()}) has no {PORTABLE} kernels",
                "effective": effective}
    overridden = sorted(k for k, v in portable_env(flags).items() if os.environ.get(k) != v)
    if overridden:
        return {"set": "native", "reason": "overridden: " + ", ".join(overridden), "effective": effective}
    uncapped = sorted(lib for lib, top in effective.items() if set(top.split("/")) & set(_CAPPED.get(lib, ())))
    if uncapped:
        return {"set": "native", "reason": "loaded before kgn_bench: " + ", ".join(uncapped), "effective": effective}
    return {"set": PORTABLE, "reason": "", "effective": effective}
