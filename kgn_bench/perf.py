"""Speed measurements printed as figures (``kgn-bench perf ...``); results/perf.md keeps them."""

from __future__ import annotations

import os
import platform
import tempfile
from pathlib import Path

from kgn_bench.data.generate import TIMING_KEYS, GenerateConfig, generate_dataset

__all__ = ["perf_data"]


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
    total = sum(per_view.values())
    lines = [
        f"data generation: mode {mode}, {scenes} scenes x {views} views, {workers} worker(s), "
        f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}",
        "",
        f"views/s (wall, incl. worker start-up): {stats.views_per_second:.1f}",
        f"wall: {stats.wall:.1f} s for {stats.views} views",
        "",
        "| stage | ms per view | share |",
        "| --- | ---: | ---: |",
    ]
    for k in TIMING_KEYS:
        lines.append(f"| {k} | {per_view[k]:.1f} | {100 * per_view[k] / total:.0f} % |")
    lines.append(f"| total (worker time) | {total:.1f} | 100 % |")
    return "\n".join(lines)
