"""One task run at several values of one setting (depth-noise strength, the selector's λ, the camera...).

Each value gets its own run folder ``OUT/<key>=<value>`` (so every point resumes like any run), and the sweep
writes ``OUT/sweep.json``, ``OUT/sweep.md`` (per value the success rate and, for clearance tasks, the clear
rate, with Wilson 95 % intervals and the most frequent failure reasons) and ``OUT/sweep.png`` (rate against
value, the interval shaded). With several detectors (``run_detector_sweep``) each runs its own sweep into
``OUT/<detector>``, and ``OUT/sweep.{md,json,png}`` put them side by side: a camera sweep
(``camera.elevation_deg``, ``camera.azimuth_deg``, ``camera.distance``) is a viewpoint study. All values see
the same scenes: the scene of trial i depends only on the task's seed and i.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kgn_bench.config import TaskConfig, apply_override
from kgn_bench.io import atomic_write_text
from kgn_bench.pool import LOCAL, Backend
from kgn_bench.viz.figures import Line, Panel, line_panels, save_figure

from .runner import RunResult, run_many
from .stats import Rate

__all__ = ["DetectorSweep", "SweepPoint", "detector_sweep_markdown", "run_detector_sweep", "run_sweep", "sweep_figure",
           "sweep_markdown"]


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


def _sweep_runs(task: TaskConfig, detector: str, key: str, values: list[str], out: Path
                ) -> list[tuple[TaskConfig, str, Path]]:
    """The runs of a sweep, each (task at one value, detector, ``out/<key>=<value>``); every value is checked
    here (``ConfigError``), before any trial runs."""
    if not values:
        raise ValueError("a sweep needs at least one value")
    return [(apply_override(task, key, v), detector, Path(out) / f"{key}={v}") for v in values]


def _write_sweep(task: TaskConfig, detector: str, key: str, values: list[str], out: Path,
                 runs: list[tuple[TaskConfig, str, Path]], results: list[RunResult]) -> list[SweepPoint]:
    """The sweep's files in ``out`` from its finished runs; returns its points."""
    points = [SweepPoint(v, f, r.summary) for v, (_, _, f), r in zip(values, runs, results)]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    payload = {"task": task.name, "detector": detector, "seed": task.seed, "key": key,
               "points": [{"value": p.value, "run": str(p.out), **p.summary} for p in points]}
    atomic_write_text(out / "sweep.json", json.dumps(payload, indent=1) + "\n")
    atomic_write_text(out / "sweep.md", sweep_markdown(task, detector, key, points))
    save_figure(sweep_figure(task, key, {detector: points}), out / "sweep.png")
    return points


def run_sweep(task: TaskConfig, detector: str, key: str, values: list[str], out: Path, workers: int = 1,
              progress: bool = True, backend: Backend = LOCAL) -> list[SweepPoint]:
    """Run ``task`` with ``detector`` once per value of setting ``key`` (``config.apply_override``); all
    values are validated before the first trial runs, and the values' runs share one pool."""
    runs = _sweep_runs(task, detector, key, values, out)
    results = run_many(runs, workers=workers, progress=progress, backend=backend)
    return _write_sweep(task, detector, key, values, out, runs, results)


@dataclass(frozen=True)
class DetectorSweep:
    """A sweep of setting ``key`` over ``values`` for every detector of ``detectors``, into ``out``: each
    detector's sweep in ``out/<detector>`` and the side-by-side files in ``out``. ``runs`` lists its runs for
    ``runner.run_many`` (so that one pool may run several sweeps and other runs together), ``write`` makes its
    files from their results."""

    task: TaskConfig
    detectors: tuple[str, ...]
    key: str
    values: tuple[str, ...]
    out: Path

    def __post_init__(self) -> None:
        if not self.detectors:
            raise ValueError("a sweep needs at least one detector")

    def runs(self) -> list[tuple[TaskConfig, str, Path]]:
        """Every (task at a value, detector, folder), detector by detector; checks every value."""
        return [r for det in self.detectors
                for r in _sweep_runs(self.task, det, self.key, list(self.values), Path(self.out) / det)]

    def write(self, results: list[RunResult]) -> dict[str, list[SweepPoint]]:
        """Each detector's sweep files and the side-by-side ones, from the results of ``runs()`` in order."""
        runs, n, out = self.runs(), len(self.values), Path(self.out)
        series = {det: _write_sweep(self.task, det, self.key, list(self.values), out / det,
                                    runs[k * n:(k + 1) * n], results[k * n:(k + 1) * n])
                  for k, det in enumerate(self.detectors)}
        payload = {"task": self.task.name, "seed": self.task.seed, "key": self.key, "values": list(self.values),
                   "detectors": {det: [{"value": p.value, "run": str(p.out), **p.summary} for p in points]
                                 for det, points in series.items()}}
        atomic_write_text(out / "sweep.json", json.dumps(payload, indent=1) + "\n")
        atomic_write_text(out / "sweep.md", detector_sweep_markdown(self.task, self.key, series))
        save_figure(sweep_figure(self.task, self.key, series), out / "sweep.png")
        return series


def run_detector_sweep(task: TaskConfig, detectors: list[str], key: str, values: list[str], out: Path,
                       workers: int = 1, progress: bool = True, backend: Backend = LOCAL
                       ) -> dict[str, list[SweepPoint]]:
    """``run_sweep`` for each detector into ``out/<detector>``, all of them on one pool, then the
    side-by-side table, JSON and plot."""
    sweep = DetectorSweep(task, tuple(detectors), key, tuple(values), Path(out))
    return sweep.write(run_many(sweep.runs(), workers=workers, progress=progress, backend=backend))


def _positions(values: list[str]) -> list[float]:
    """x of each value on the plot: the number it is, or its index when not every value is a number."""
    try:
        return [float(v) for v in values]
    except ValueError:
        return [float(i) for i in range(len(values))]


def sweep_figure(task: TaskConfig, key: str, series: dict[str, list[SweepPoint]]):
    """Success (and, for clearance tasks, clear) rate in % against the swept value, one line per detector
    with its Wilson 95 % interval shaded."""
    panels = []
    for rate in ("success", "clear") if task.clearance else ("success",):
        lines = []
        for k, (det, points) in enumerate(series.items()):
            rates = [Rate.from_dict(p.summary["rates"][rate]) for p in points]
            lines.append(Line(det, _positions([p.value for p in points]), [100 * r.value for r in rates], color=k,
                              band=([100 * r.interval[0] for r in rates], [100 * r.interval[1] for r in rates])))
        panels.append(Panel(f"{task.name}: {rate} rate", key, f"{rate} rate (%)", lines))
    return line_panels(panels, suptitle=f"seed {task.seed}, Wilson 95 % bands")


def detector_sweep_markdown(task: TaskConfig, key: str, series: dict[str, list[SweepPoint]]) -> str:
    """One row per value, one column per detector (success; and clear for clearance tasks)."""
    rates = ("success", "clear") if task.clearance else ("success",)
    cols = [(det, r) for det in series for r in rates]
    lines = [f"# Sweep of {key}: {task.name} (seed {task.seed})", "",
             "Rates in % with Wilson 95 % intervals (k/n).", "",
             f"| {key} | " + " | ".join(f"{d} {r}" for d, r in cols) + " |", "|---|" + "---|" * len(cols)]
    values = [p.value for p in next(iter(series.values()))]
    for i, v in enumerate(values):
        lines.append(f"| {v} | " + " | ".join(_pct(series[d][i].summary["rates"][r]) for d, r in cols) + " |")
    return "\n".join(lines) + "\n"
