"""Which library's CPU dispatch reaches an outcome, and what the portable kernel set costs
(``kgn-bench perf kernels``).

Each variant runs a probe in a fresh process, since the switches (``kernels.PORTABLE_ENV``) only act when a
library loads: ``native`` (nothing capped), ``portable`` (everything capped, the default), and for each
library the portable set with that library's switches left out. A probe hashes what each layer produces:

* ``images``: the RGB, depth and mask PNGs of a seeded 2-scene, 2-view multi-object dataset (Mesa's
  llvmpipe renders them);
* ``scenes``: the scenes' annotations (settled object poses from MuJoCo, grasp labels from numpy);
* ``detections``: kgnv2's candidates on those 4 views, every array bit for bit (torch, OpenCV's resize and
  PnP, numpy's decoding), and the detector's median time per frame on one thread;
* ``records`` (with ``records=True``): the trial records, less their timings, of the CI regression tasks
  ``ci_regression`` and ``ci_pile`` with kgnv2 (``fingerprint``), which is what a benchmark reports.

A library whose row differs from ``portable`` reaches that layer through its dispatch on this CPU. On a CPU
without AVX-512 every variant computes the same (nothing to cap), which is the point of the set.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from kgn_bench import kernels

__all__ = ["LAYERS", "LIBRARIES", "probe", "study", "variants"]

LIBRARIES: dict[str, tuple[str, ...]] = {
    "torch: ATen kernels": ("ATEN_CPU_CAPABILITY",),
    "torch: oneDNN convolutions": ("ONEDNN_MAX_CPU_ISA",),
    "torch: MKL": ("MKL_CBWR",),
    "numpy: SIMD dispatch": ("NPY_DISABLE_CPU_FEATURES",),
    "OpenBLAS (numpy, scipy, OpenCV)": ("OPENBLAS_CORETYPE",),
    "OpenCV: dispatch": ("OPENCV_CPU_DISABLE",),
    "Mesa llvmpipe": ("GALLIUM_OVERRIDE_CPU_CAPS", "LP_NATIVE_VECTOR_WIDTH"),
}
"""Each library's switches in ``kernels.portable_env``."""

LAYERS = ("images", "scenes", "detections", "records")

_RECORD_TASKS = ("ci_regression", "ci_pile")


def variants() -> dict[str, dict[str, str]]:
    """The environment of every variant's process (on top of this one's, less the portable variables)."""
    portable = kernels.portable_env()
    out = {"native": {kernels.KERNELS_VAR: "native"}, "portable": {kernels.KERNELS_VAR: "portable", **portable}}
    for library, keys in LIBRARIES.items():
        if any(k in portable for k in keys):
            out[f"portable, {library} native"] = {
                kernels.KERNELS_VAR: "native", **{k: v for k, v in portable.items() if k not in keys}}
    return out


def _sha(chunks: list[bytes]) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(hashlib.sha256(c).digest())
    return h.hexdigest()[:16]


def probe(records: bool = False) -> dict[str, Any]:
    """Hash every layer in this process (module docstring); returns ``{layer: digest, "ms_per_frame": …,
    "kernels": kernels.describe()}``."""
    import numpy as np
    import torch

    from kgn_bench.data.format import SceneAnnotation, read_split, read_view, scene_dir
    from kgn_bench.data.generate import GenerateConfig, generate_dataset
    from kgn_bench.detectors.base import Observation
    from kgn_bench.detectors.kgn import KGNDetector

    torch.set_num_threads(1)
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="kgn-kernels-") as tmp:
        root = Path(tmp) / "ds"
        generate_dataset(GenerateConfig(mode="multi", scenes=2, views=2, seed=0), root, workers=1, progress=False)
        files = sorted(p for p in root.rglob("*") if p.is_file())
        out["images"] = _sha([p.read_bytes() for p in files if p.suffix in (".png", ".npz")])
        out["scenes"] = _sha([p.read_bytes() for p in files if p.name == "scene.json"])
        detector = KGNDetector("kgnv2")
        observations = []
        for s in read_split(root, "train") + read_split(root, "test"):
            ann = SceneAnnotation.load(scene_dir(root, s) / "scene.json")
            for v in range(len(ann.camera_poses)):
                rgbd = read_view(scene_dir(root, s), v)
                observations.append(Observation(rgbd.rgb, rgbd.depth, ann.intrinsics, ann.camera_poses[v]))
        chunks, times = [], []
        for _ in range(3):
            chunks = []
            for i, obs in enumerate(observations):
                detector.reset([0, i])
                t = time.perf_counter()
                c = detector.detect(obs)
                times.append(time.perf_counter() - t)
                chunks += [np.ascontiguousarray(a).tobytes() for a in (c.poses, c.widths, c.confidences,
                                                                        c.reprojection_errors)]
        out["detections"] = _sha(chunks)
        out["ms_per_frame"] = round(1e3 * float(np.median(times)), 2)
        if records:
            from kgn_bench.bench.check import read_run
            from kgn_bench.bench.runner import run_benchmark
            from kgn_bench.config import load_task, validate

            digests = []
            for task in _RECORD_TASKS:
                run = Path(tmp) / task
                config = load_task(task)  # what `kgn-bench run TASK --detector kgnv2 --workers 1 --quiet` runs
                validate(config, task)
                run_benchmark(config, "kgnv2", run, workers=1, progress=False)
                digests += [t.sha256.encode() for t in read_run(run).fingerprint.trials]
            out["records"] = _sha(digests)
    out["kernels"] = kernels.describe()
    return out


def _run_variant(env: dict[str, str], records: bool) -> dict[str, Any]:
    base = {k: v for k, v in os.environ.items() if k not in kernels.portable_env() and k != kernels.KERNELS_VAR}
    cmd = [sys.executable, "-m", "kgn_bench.bench.kernel_study"] + (["--records"] if records else [])
    proc = subprocess.run(cmd, env={**base, **env}, capture_output=True, text=True, check=False)
    if proc.returncode:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the probe failed ({tail})")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def study(records: bool = False) -> str:
    """Run every variant's probe and return the Markdown table: per library, whether it was forced down on
    this CPU, which layers changed against ``portable``, and how the portable set pins it."""
    results = {name: _run_variant(env, records) for name, env in variants().items()}
    layers = [layer for layer in LAYERS if layer in results["portable"]]
    ref = results["portable"]

    def changed(r: dict[str, Any]) -> str:
        diff = [layer for layer in layers if r[layer] != ref[layer]]
        return ", ".join(diff) if diff else "none"

    portable = kernels.portable_env()
    lines = [f"CPU: {_cpu()}; layers compared: {', '.join(layers)}", "",
             "| library | forced down here | layers that change | ms / frame (kgnv2, 1 thread) | pinned by |",
             "|---|---|---|---:|---|"]
    lines.append(f"| all (native) | - | {changed(results['native'])} | {results['native']['ms_per_frame']} | - |")
    lines.append(f"| none (portable) | - | - | {ref['ms_per_frame']} | all of the below |")
    for library, keys in LIBRARIES.items():
        name = f"portable, {library} native"
        if name not in results:
            lines.append(f"| {library} | no (nothing above AVX2 on this CPU) | - | - | - |")
            continue
        pins = ", ".join(f"`{k}={portable[k]}`" for k in keys if k in portable)
        r = results[name]
        lines.append(f"| {library} | yes | {changed(r)} | {r['ms_per_frame']} | {pins} |")
    lines.append("| MuJoCo | no switch: compiled for AVX, no AVX-512, no run-time dispatch | - | - | - |")
    return "\n".join(lines)


def _cpu() -> str:
    from kgn_bench.environment import cpu_model

    return cpu_model() or "unknown"


if __name__ == "__main__":
    print(json.dumps(probe(records="--records" in sys.argv)))
