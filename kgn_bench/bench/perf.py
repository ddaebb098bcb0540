"""Speed measurements printed as figures (``kgn-bench perf ...``); results/perf.md keeps them."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kgn_bench.data.generate import TIMING_KEYS, GenerateConfig, generate_dataset
from kgn_bench.errors import InputError, KGNBenchError

__all__ = ["PerfError", "perf_backends", "perf_data", "perf_detector", "perf_import", "perf_run", "perf_train"]


class PerfError(KGNBenchError, RuntimeError):
    """A measurement that cannot be made: a command it times failed, or runs it compares differ."""


def perf_data(scenes: int = 20, workers: int = 2, mode: str = "multi", views: int = 5, seed: int = 0) -> str:
    """Generate ``scenes`` scenes into a temporary folder and report views/s and the time split.

    The split sums worker CPU-side seconds per stage (settle = build + place + settle physics,
    annotate = grasp families + collision labels, render = renderer set-up + RGB/depth/mask passes,
    write = PNG + JSON); with W workers the stages overlap, so their sum is about W × wall time.
    Returns a Markdown report.
    """
    config = GenerateConfig(mode=mode, scenes=scenes, views=views, seed=seed)
    with tempfile.TemporaryDirectory(prefix="kgn-perf-") as tmp:
        stats = generate_dataset(config, Path(tmp) / "data", workers=workers, progress=False)
    per_view = {k: 1e3 * stats.timings[k] / stats.views for k in TIMING_KEYS}
    lines = [
        f"data generation: mode {mode}, {scenes} scenes x {views} views, {workers} worker(s), "
        f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}",
        "",
        f"views/s (wall, incl. worker start-up): {stats.views_per_second:.1f}",
        f"wall: {stats.wall:.1f} s for {stats.views} views",
        "",
    ]
    return "\n".join(lines + _stage_table(per_view, "view"))


def perf_import(mesh: str | Path | None = None, faces: int = 20_000, verify: int = 160, hulls: int = 8) -> str:
    """Import one mesh into a temporary, empty library (so CoACD's cache is cold) and report the time of each
    stage (repair, CoACD, antipodal sampling, physics check, preview). Without ``mesh``: a 12 cm torus of
    ``faces`` triangles, non-convex, so CoACD has work to do. Returns a Markdown report."""
    import json

    import trimesh

    from kgn_bench.objects.importer import ImportConfig, import_mesh

    with tempfile.TemporaryDirectory(prefix="kgn-perf-") as tmp:
        if mesh is None:
            minor = 50
            major = max(3, round(faces / (2 * minor)))
            mesh = Path(tmp) / "torus.ply"
            trimesh.creation.torus(0.045, 0.015, major_sections=major, minor_sections=minor).export(mesh)
        folder = import_mesh(mesh, "perf_object", ImportConfig(verify=verify, hulls=hulls), root=Path(tmp) / "lib")
        manifest = json.loads((folder / "object.json").read_text())
    timing = manifest["timing_s"]
    total = timing.pop("total")
    g = manifest["grasps"]
    lines = [
        f"object import: {Path(mesh).name}, {manifest['faces']} faces, {manifest['hulls']} hulls, "
        f"{g['checked']} of {g['candidates']} candidates checked, {g['held']} held; {os.cpu_count()} cores",
        "",
        f"wall: {total:.1f} s",
        "",
        "| stage | s | share |",
        "| --- | ---: | ---: |",
    ]
    lines += [f"| {k} | {v:.2f} | {100 * v / total:.0f} % |" for k, v in timing.items()]
    return "\n".join(lines)


def _stage_table(ms: dict[str, float], per: str) -> list[str]:
    """Markdown rows: each stage's milliseconds per item and its share of the total."""
    total = sum(ms.values())
    rows = [f"| stage | ms per {per} | share |", "| --- | ---: | ---: |"]
    rows += [f"| {k} | {v:.1f} | {100 * v / total:.0f} % |" for k, v in ms.items()]
    return [*rows, f"| total (worker time) | {total:.1f} | 100 % |"]


def perf_run(task_path: str | Path, detector: str = "oracle", trials: int = 2, workers: int = 2) -> str:
    """Run ``trials`` per object of a benchmark task into a temporary folder; report trials/min and the
    per-trial split (setup = scene build + placement, render, detect, select, simulate = motion physics
    and IK). Stages are per-trial worker seconds; with W workers throughput ≈ W / (sum of stages)."""
    from kgn_bench.bench.runner import run_benchmark
    from kgn_bench.config import load_task

    task = load_task(task_path).with_overrides(trials=trials)
    with tempfile.TemporaryDirectory(prefix="kgn-perf-") as tmp:
        result = run_benchmark(task, detector, Path(tmp) / "run", workers=workers, progress=False)
    t = result.timing
    lines = [
        f"benchmark: {task.name} ({task.protocol}), detector {detector}, {task.n_trials} trials, {workers} worker(s), "
        f"{os.cpu_count()} cores",
        "",
        f"trials/min (wall, incl. worker start-up): {t['trials_per_minute']}",
        f"wall: {t['wall_s']:.1f} s; simulated motion per trial: {t['simulated_s_per_trial']:.1f} s",
        "",
    ]
    return "\n".join(lines + _stage_table({k: 1e3 * v for k, v in t["per_trial_s"].items()}, "trial"))


def perf_backends(task_path: str | Path, detector: str = "kgnv2", workers: int = 2, rounds: int = 3,
                  address: str | None = None, trials: int | None = None) -> str:
    """The overhead of Ray against the local pool: ``kgn-bench run TASK`` timed from start to exit (a new
    process each, as a user runs it) on the local pool, on a Ray the command starts for itself, and (with
    ``address``) on the running Ray head there, in turn for ``rounds`` rounds, each into a new folder.

    Overhead = mean(Ray) / mean(local) − 1. The backends must give byte-identical ``summary.json`` files;
    a difference or a failed command raises ``PerfError``. ``trials`` (per object) shortens the task.
    Returns a Markdown report."""
    from kgn_bench.config import load_task

    task = load_task(task_path)
    backends = {"local pool": [], "Ray started by the command": ["--backend", "ray"]}
    if address:
        backends[f"Ray head at {address}"] = ["--backend", "ray", "--address", address]
    base = [sys.executable, "-m", "kgn_bench.cli", "run", str(task_path), "--detector", detector,
            "--workers", str(workers), "--quiet"] + (["--trials", str(trials)] if trials else [])
    walls: dict[str, list[float]] = {name: [] for name in backends}
    with tempfile.TemporaryDirectory(prefix="kgn-perf-") as tmp:
        summaries = []
        for r in range(rounds):
            for k, (name, extra) in enumerate(backends.items()):
                out = Path(tmp) / f"{r}_{k}"
                start = time.perf_counter()
                done = subprocess.run([*base, "--out", str(out), *extra], capture_output=True, text=True)
                walls[name].append(time.perf_counter() - start)
                if done.returncode:
                    last = (done.stderr.strip().splitlines() or ["no output"])[-1]
                    raise PerfError(f"`kgn-bench run` on the {name} failed (exit {done.returncode}): {last}")
                summaries.append((out / "summary.json").read_bytes())
    if len(set(summaries)) != 1:
        raise PerfError("the backends' summary.json files differ: the runs are not the same")
    n = task.with_overrides(trials=trials).n_trials if trials else task.n_trials
    names = list(backends)
    local = sum(walls[names[0]]) / rounds
    lines = [
        f"Ray against the local pool: {task.name} with {detector}, {n} trials, {workers} workers, {os.cpu_count()} "
        f"cores, {platform.processor() or platform.machine()}; each `kgn-bench run` timed from start to exit",
        "",
        "| round | " + " | ".join(names) + " |",
        "| --- |" + " ---: |" * len(names),
    ]
    lines += [f"| {r + 1} | " + " | ".join(f"{walls[name][r]:.1f} s" for name in names) + " |" for r in range(rounds)]
    means = [sum(walls[name]) / rounds for name in names]
    cells = [f"{m:.1f} s" + ("" if i == 0 else f" (**{100 * (m / local - 1):+.1f} %**)") for i, m in enumerate(means)]
    lines.append("| mean | " + " | ".join(cells) + " |")
    lines += ["", f"summary.json byte-identical in all {len(summaries)} runs"]
    return "\n".join(lines)


def _frames(data: Path | None, frames: int) -> list:
    """The first ``frames + 1`` views (one warm-up) of the test split of ``data``, or of a seeded 4-scene
    multi-object dataset generated in a temporary folder, as ``Observation``s (camera pose ``T_world_cam``)."""
    from kgn_bench.data.format import SceneAnnotation, read_split, read_view, scene_dir
    from kgn_bench.types import Observation

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(data) if data else Path(tmp) / "ds"
        if data is None:
            generate_dataset(GenerateConfig(mode="multi", scenes=4, views=5, seed=0), root, workers=1, progress=False)
            scenes = list(range(4))
        else:
            scenes = read_split(root, "test")
        observations = []
        for s in scenes:
            ann = SceneAnnotation.load(scene_dir(root, s) / "scene.json")
            for v in range(len(ann.camera_poses)):
                rgbd = read_view(scene_dir(root, s), v)
                observations.append(Observation(rgbd.rgb, rgbd.depth, ann.intrinsics, ann.camera_poses[v]))
                if len(observations) >= frames + 1:
                    break
            if len(observations) >= frames + 1:
                break
    return observations


def _time_frames(det, observations: list, learned: bool) -> tuple[dict[str, list[float]], list[int]]:
    """Seconds per frame after the first (a warm-up): per stage (the detector's own ``timing``) for a learned
    detector, of the whole ``detect`` call otherwise; and the candidates per frame."""
    times: dict[str, list[float]] = {k: [] for k in (("preprocess", "network", "decode", "pnp") if learned
                                                     else ("detect",))}
    counts = []
    for i, obs in enumerate(observations):
        det.reset([0, i])
        t = time.perf_counter()
        cands = det.detect(obs)
        elapsed = time.perf_counter() - t
        if i == 0:
            continue  # warm-up
        for k in times:
            times[k].append(det.timing.get(k, 0.0) if learned else elapsed)
        counts.append(len(cands))
    return times, counts


def perf_detector(variant: str = "kgnv2", weights: str | Path | None = None, frames: int = 20,
                  threads: int = 2, data: Path | None = None) -> str:
    """Detector frames per second at 640×480 on ``threads`` torch threads (medians over ``frames`` frames after
    one warm-up). ``variant`` is a learned variant (then preprocessing, network, decode (peaks, filters,
    translation) and PnP are timed separately) or any other non-privileged detector name (timed as a whole).

    Frames come from the test split of ``data`` when given, else from freshly generated multi-object
    scenes (one seeded 4-scene dataset in a temporary folder).
    """

    import numpy as np
    import torch

    from kgn_bench.detectors import LEARNED, make_detector
    from kgn_bench.detectors.kgn import KGNDetector

    torch.set_num_threads(threads)
    det = KGNDetector(variant, weights) if variant in LEARNED else make_detector(variant, weights)
    if det.privileged:
        raise InputError(f"detector {variant!r} is privileged (it needs the simulator): time it with perf run")
    observations = _frames(data, frames)
    learned = isinstance(det, KGNDetector)
    times, counts = _time_frames(det, observations, learned)
    ms = {k: 1e3 * float(np.median(v)) for k, v in times.items()}
    total = sum(ms.values())
    about = (f"({det.model.meta.get('parameters', 'n/a')} parameters), input scale "
             f"{det.model.input_config.input_scale}, " if learned else "")
    lines = [
        f"detector {variant} {about}{len(counts)} frames at 640×480, {threads} torch threads",
        "",
        *_stage_table(ms, "frame"),
        "",
        f"median {1e3 / total:.1f} frames/s; candidates per frame: median {int(np.median(counts))}, max {max(counts)}",
    ]
    return "\n".join(lines)


def perf_train(data: Path, variant: str = "kgnv2", strides: tuple[int, ...] = (4, 2),
               precisions: tuple[str, ...] = ("float32", "bfloat16"), batches: int = 6, batch_size: int = 8,
               threads: int = 1, layouts: tuple[bool, ...] = (False, True)) -> str:
    """One KGN training step, split: preparing a batch (reading the views, augmentation, targets: what the
    data-loading process does) and the step (forward, loss, backward, Adam), for each output stride and
    forward precision and memory layout (``layouts``: channels-last off, on; ``[train] channels_last``), on
    ``threads`` torch threads; medians over ``batches`` after one warm-up. Samples/s is
    ``batch_size`` over the longer of the two (a loading process overlaps them) and over their sum (loading
    in the training process, ``workers = 0``). The CPU kernels are the process's (``KGN_BENCH_KERNELS``):
    bfloat16 is only fast with native ones on a CPU that has it (``training.train.autocast_dtype``)."""
    import numpy as np
    import torch

    from kgn_bench.kernels import describe
    from kgn_bench.model.losses import LossWeights
    from kgn_bench.model.network import NetworkConfig, build_network
    from kgn_bench.model.variants import get_variant
    from kgn_bench.training.dataset import AugmentConfig, GraspViewDataset
    from kgn_bench.training.train import train_step

    torch.set_num_threads(threads)
    v = get_variant(variant)
    rows = []
    for stride in strides:
        ds = GraspViewDataset(Path(data), "train", v, augment=AugmentConfig(), seed=0, stride=stride)
        load_ms, batch_list = [], []
        for b in range(batches + 1):
            t = time.perf_counter()
            items = [ds[(b * batch_size + i) % len(ds)] for i in range(batch_size)]
            x = torch.stack([it[0] for it in items])
            targets = {k: torch.stack([it[1][k] for it in items]) for k in items[0][1]}
            load_ms.append(1e3 * (time.perf_counter() - t))
            batch_list.append((x, targets))
        for precision in precisions:
            for channels_last in layouts:
                torch.manual_seed(0)
                net = build_network(v, NetworkConfig(output_stride=stride)).use_channels_last(channels_last).train()
                optim = torch.optim.Adam(net.parameters(), lr=1e-3)
                step_ms, dtype = [], torch.bfloat16 if precision == "bfloat16" else None
                for x, targets in batch_list:
                    t = time.perf_counter()
                    train_step(net, optim, x, targets, v, LossWeights(), dtype)
                    step_ms.append(1e3 * (time.perf_counter() - t))
                load, step = float(np.median(load_ms[1:])), float(np.median(step_ms[1:]))
                rows.append(f"| {stride} | {precision} | {'channels-last' if channels_last else 'contiguous'} "
                            f"| {load:.0f} | {step:.0f} | {1e3 * batch_size / max(load, step):.1f} "
                            f"| {1e3 * batch_size / (load + step):.1f} |")
    kernels = describe()
    return "\n".join([
        f"{variant} training step, batch {batch_size} of 256×256 crops from {data}, {threads} torch thread(s); "
        f"kernels: {kernels['set']}" + (f" ({kernels['reason']})" if kernels["reason"] else ""),
        "",
        "| output stride | forward | layout | batch prep (ms) | step (ms) | samples/s, loader process "
        "| samples/s, in-process |",
        "| --- | --- | --- | --- | --- | --- | --- |",
        *rows,
    ])
