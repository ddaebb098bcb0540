"""One task run at several values of one setting (depth-noise strength, the selector's λ, its score form...).

Each value gets its own run folder ``OUT/<key>=<value>`` (so every point resumes like any run), and the sweep
writes ``OUT/sweep.json`` and ``OUT/sweep.md``: per value the success rate (and, for clearance tasks, the clear
rate) with Wilson 95 % intervals and the most frequent failure reasons. All values see the same scenes: the
scene of trial i depends only on the task's seed and i.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kgn_bench.config import TaskConfig, apply_override
from kgn_bench.io import atomic_write_text

from .runner import run_benchmark
from .stats import Rate

__all__ = ["SweepPoint", "run_sweep", "sweep_markdown"]


@dataclass(frozen=True)
class SweepPoint:
    """One value of the swept setting, its run folder and that run's summary."""

    value: str
    out: Path
    summary: dict[str, Any]


def _pct(rate: dict[str, Any]) -> str:
    return str(Rate.from_dict(rate)).replace(" %", "")


def sweep_markdown(task: TaskConfig, detector: str, key: str, points: list[SweepPoint]) -> str:
    """The sweep's table: one row per value."""
    clearance = task.clearance
    head = f"| {key} | success % [95 % CI] (k/n) |" + (" clear % [95 % CI] (k/n) |" if clearance else "")
    lines = [f"# Sweep of {key}: {task.name} with {detector} (seed {task.seed})", "", head + " main failures |",
             "|---|---|" + ("---|" if clearance else "") + "---|"]
    for p in points:
        rates = p.summary["rates"]
        failures = sorted(((n, r) for r, n in p.summary["failures"].items() if n), reverse=True)
        main = ", ".join(f"{r} {n}" for n, r in failures[:3]) or "none"
        row = f"| {p.value} | {_pct(rates['success'])} |" + (f" {_pct(rates['clear'])} |" if clearance else "")
        lines.append(row + f" {main} |")
    return "\n".join(lines) + "\n"


def run_sweep(task: TaskConfig, detector: str, key: str, values: list[str], out: Path, workers: int = 1,
              progress: bool = True) -> list[SweepPoint]:
    """Run ``task`` with ``detector`` once per value of setting ``key`` (``config.apply_override``); all
    values are validated before the first trial runs."""
    if not values:
        raise ValueError("a sweep needs at least one value")
    tasks = [apply_override(task, key, v) for v in values]
    out = Path(out)
    points = []
    for value, t in zip(values, tasks):
        folder = out / f"{key}={value}"
        result = run_benchmark(t, detector, folder, workers=workers, progress=progress)
        points.append(SweepPoint(value, folder, result.summary))
    out.mkdir(parents=True, exist_ok=True)
    payload = {"task": task.name, "detector": detector, "seed": task.seed, "key": key,
               "points": [{"value": p.value, "run": str(p.out), **p.summary} for p in points]}
    atomic_write_text(out / "sweep.json", json.dumps(payload, indent=1) + "\n")
    atomic_write_text(out / "sweep.md", sweep_markdown(task, detector, key, points))
    return points
