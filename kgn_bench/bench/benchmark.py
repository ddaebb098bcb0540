"""The whole benchmark in one command: every (task, detector) of a plan run into its own folder, then the report.

A plan file (``tasks/benchmark.toml``)::

    [benchmark]
    tasks = ["single_object", "single_household", "multi_object", "multi_household"]   # tasks/<name>.toml
    detectors = ["kgnv2", "kgn", "kgn_depth", "antipodal", "random", "oracle"]

A plan is named by its path or its bundled name (``benchmark``); its task names are looked up beside the
plan file, then among the bundled tasks. A task named ``name@mode`` is task ``name`` with ``selector.mode`` set
to ``mode`` (``raw`` or ``assisted``), run and reported as ``name_mode``: one task file gives both the
detector-only and the assisted row. Runs go to ``RUNS/<task>/<detector>`` and resume like any run;
all detectors see the same scenes because a trial's scene depends only on the task's seed and the trial index.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from kgn_bench.config import SELECTOR_MODES, ConfigError, TaskConfig, apply_override, load_task, read_toml, resolve_task
from kgn_bench.pool import LOCAL, Backend

from .runner import run_benchmark

__all__ = ["BenchmarkPlan", "load_plan", "run_plan"]


@dataclass(frozen=True)
class BenchmarkPlan:
    """Tasks (loaded) and detector names, in report order."""

    tasks: tuple[TaskConfig, ...]
    detectors: tuple[str, ...]


def load_plan(path: Path, tasks: list[str] | None = None, detectors: list[str] | None = None) -> BenchmarkPlan:
    """Read a plan; ``tasks`` / ``detectors`` (if given) restrict it. ``ConfigError`` names the problem."""
    from kgn_bench.detectors import detector_factory

    path = resolve_task(path)
    raw = read_toml(path, "plan file")
    section = raw.get("benchmark")
    if not isinstance(section, dict) or set(raw) != {"benchmark"}:
        raise ConfigError(f"{path}: a plan has exactly one [benchmark] table")
    unknown = set(section) - {"tasks", "detectors"}
    if unknown:
        raise ConfigError(f"{path}: [benchmark] unknown key {sorted(unknown)[0]!r} (known: tasks, detectors)")
    names = section.get("tasks")
    dets = section.get("detectors")
    for key, value in (("tasks", names), ("detectors", dets)):
        if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{path}: [benchmark] {key} must be a non-empty list of names")
    for chosen, available, what in ((tasks, names, "task"), (detectors, dets, "detector")):
        for c in chosen or ():
            if c not in available:
                raise ConfigError(f"{what} {c!r} is not in {path} (plan: {', '.join(available)})")
    for d in dets:
        try:
            detector_factory(d)
        except ValueError as e:
            raise ConfigError(f"{path}: {e}") from None
    names = [n for n in names if not tasks or n in tasks]
    dets = [d for d in dets if not detectors or d in detectors]
    return BenchmarkPlan(tuple(_plan_task(path, n) for n in names), tuple(dets))


def _plan_task(plan: Path, entry: str) -> TaskConfig:
    """The task of a plan entry ``name`` or ``name@mode`` (module docstring)."""
    name, _, mode = entry.partition("@")
    task = load_task(plan.parent / f"{name}.toml" if (plan.parent / f"{name}.toml").is_file() else name)
    if not mode:
        return task
    if mode not in SELECTOR_MODES:
        raise ConfigError(f"{plan}: task {entry!r}: mode must be one of {', '.join(SELECTOR_MODES)}")
    return replace(apply_override(task, "selector.mode", mode), name=f"{task.name}_{mode}")


def run_plan(plan: BenchmarkPlan, runs: Path, workers: int = 1, progress: bool = True,
             backend: Backend = LOCAL) -> list[Path]:
    """Run every (task, detector) of ``plan`` into ``runs``/task/detector (on ``backend``); returns the run
    folders."""
    folders = []
    for task in plan.tasks:
        for det in plan.detectors:
            folder = Path(runs) / task.name / det
            run_benchmark(task, det, folder, workers=workers, progress=progress, backend=backend)
            folders.append(folder)
    return folders
