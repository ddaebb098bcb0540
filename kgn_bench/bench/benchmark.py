"""The whole benchmark in one command: every (task, detector) of a plan run into its own folder, then the report.

A plan file (``tasks/benchmark.toml``)::

    [benchmark]
    tasks = ["single_object", "single_household", "multi_object", "multi_household"]   # tasks/<name>.toml
    detectors = ["kgnv2", "kgn", "kgn_depth", "antipodal", "random", "oracle"]

A plan may add viewpoint studies, each a camera sweep (``bench.sweep``) of one task for every detector::

    [[benchmark.viewpoints]]
    task = "single_object"
    param = "camera.elevation_deg"        # or camera.azimuth_deg, camera.distance
    values = [35, 45, 60, 75, 90]
    set = {"camera.azimuth_deg" = 0, "camera.distance" = 1.0}   # optional: the rest of the camera
    trials = 3                            # optional: the task's [task] trials

run into ``RUNS/viewpoints/<name>`` (``name``: ``<task>_<param's last part>`` unless given), on the same pool as
the tasks; restricting the plan to some tasks keeps the studies of those tasks only.

A plan may repeat every (task, detector) over several seeds, as GIGA reports 5 seeds of 100 rounds::

    seeds = [0, 1, 2, 3, 4]               # optional: each task's own seed when absent

Each seed's run then goes to ``RUNS/<task>/<detector>/seed<k>`` and the report merges them into one cell
(``report.merge_seeds``: the pooled rate with its Wilson interval, and the per-seed mean ± std).

A plan may keep a detector to some of its tasks, where the others are outside what it is made for (``vgn``
grasps with an 8 cm hand inside GIGA's 30 cm cube)::

    only = {vgn = ["giga_packed", "giga_pile"]}   # plan entries, as in tasks; the report shows "—" elsewhere

A detector that ``only`` restricts runs in no viewpoint study unless the study's task is one of its tasks.

A plan is named by its path or its bundled name (``benchmark``); its task names are looked up beside the
plan file, then among the bundled tasks. A task named ``name@mode`` is task ``name`` with ``selector.mode`` set
to ``mode`` (``raw`` or ``assisted``), run and reported as ``name_mode``: one task file gives both the
detector-only and the assisted row. Runs go to ``RUNS/<task>/<detector>`` and resume like any run;
all detectors see the same scenes because a trial's scene depends only on the task's seed and the trial index.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from kgn_bench.config import (
    SELECTOR_MODES,
    ConfigError,
    TaskConfig,
    apply_override,
    apply_overrides,
    load_task,
    read_toml,
    resolve_task,
)
from kgn_bench.pool import LOCAL, Backend

from .runner import run_many
from .sweep import DetectorSweep, SweepPoint

__all__ = ["BenchmarkPlan", "Viewpoints", "load_plan", "run_plan"]

VIEWPOINT_KEYS = ("task", "param", "values", "set", "trials", "name")


@dataclass(frozen=True)
class Viewpoints:
    """One viewpoint study of a plan: ``task`` (its other settings applied) swept over camera setting ``param``
    at ``values``, reported as ``name``."""

    name: str
    task: TaskConfig
    param: str
    values: tuple[str, ...]


@dataclass(frozen=True)
class BenchmarkPlan:
    """Tasks (loaded), detector names and viewpoint studies, in report order."""

    tasks: tuple[TaskConfig, ...]
    detectors: tuple[str, ...]
    viewpoints: tuple[Viewpoints, ...] = ()
    seeds: tuple[int, ...] = ()
    """The seeds every (task, detector) runs with (module docstring); empty: each task's own."""
    only: tuple[tuple[str, tuple[str, ...]], ...] = ()
    """(detector, the names of the tasks it runs) for the detectors the plan restricts (module docstring)."""

    def detectors_of(self, task: str) -> tuple[str, ...]:
        """The plan's detectors that run on the task named ``task``, in plan order (``only`` applied)."""
        kept = dict(self.only)
        return tuple(d for d in self.detectors if d not in kept or task in kept[d])


def load_plan(path: Path, tasks: list[str] | None = None, detectors: list[str] | None = None) -> BenchmarkPlan:
    """Read a plan; ``tasks`` / ``detectors`` (if given) restrict it. ``ConfigError`` names the problem."""
    from kgn_bench.detectors import detector_factory

    path = resolve_task(path)
    raw = read_toml(path, "plan file")
    section = raw.get("benchmark")
    if not isinstance(section, dict) or set(raw) != {"benchmark"}:
        raise ConfigError(f"{path}: a plan has exactly one [benchmark] table")
    unknown = set(section) - {"tasks", "detectors", "viewpoints", "seeds", "only"}
    if unknown:
        raise ConfigError(f"{path}: [benchmark] unknown key {sorted(unknown)[0]!r} (known: tasks, detectors, "
                          "viewpoints, seeds, only)")
    seeds = section.get("seeds", [])
    if not isinstance(seeds, list) or not all(isinstance(k, int) and not isinstance(k, bool) and k >= 0
                                              for k in seeds) or len(set(seeds)) < len(seeds):
        raise ConfigError(f"{path}: [benchmark] seeds must be a list of distinct integers ≥ 0")
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
    studies = section.get("viewpoints", [])
    if not isinstance(studies, list) or not all(isinstance(v, dict) for v in studies):
        raise ConfigError(f"{path}: [benchmark] viewpoints must be a list of tables ([[benchmark.viewpoints]])")
    viewpoints = tuple(_viewpoints(path, k, v) for k, v in enumerate(studies)
                       if not tasks or v.get("task") in tasks)  # --tasks: the studies of those tasks only
    if len({v.name for v in viewpoints}) < len(viewpoints):
        raise ConfigError(f"{path}: two viewpoint studies have the same name; give one a name = ...")
    only = _only(path, section.get("only", {}), names, dets)
    names = [n for n in names if not tasks or n in tasks]
    dets = [d for d in dets if not detectors or d in detectors]
    return BenchmarkPlan(tuple(_plan_task(path, n) for n in names), tuple(dets), viewpoints, tuple(seeds), only)


def _only(plan: Path, raw: object, names: list[str], dets: list[str]) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """The plan's ``only`` table (module docstring) as (detector, task names), every entry checked."""
    if not isinstance(raw, dict):
        raise ConfigError(f"{plan}: [benchmark] only must be a table of detector = [tasks]")
    out = []
    for det, entries in raw.items():
        if det not in dets:
            raise ConfigError(f"{plan}: [benchmark] only names detector {det!r}, which is not in detectors")
        if not isinstance(entries, list) or not entries or not all(isinstance(e, str) for e in entries):
            raise ConfigError(f"{plan}: [benchmark] only.{det} must be a non-empty list of the plan's tasks")
        for e in entries:
            if e not in names:
                raise ConfigError(f"{plan}: [benchmark] only.{det} names task {e!r}, which is not in tasks")
        out.append((det, tuple(_plan_task(plan, e).name for e in entries)))
    return tuple(out)


def _viewpoints(plan: Path, k: int, raw: dict) -> Viewpoints:
    """The ``k``-th ``[[benchmark.viewpoints]]`` table (module docstring), every value checked."""
    where = f"{plan}: viewpoint study {k + 1}"
    unknown = set(raw) - set(VIEWPOINT_KEYS)
    if unknown:
        raise ConfigError(f"{where}: unknown key {sorted(unknown)[0]!r} (known: {', '.join(VIEWPOINT_KEYS)})")
    param, values, settings = raw.get("param"), raw.get("values"), raw.get("set", {})
    if not isinstance(param, str) or not param.startswith("camera."):
        raise ConfigError(f"{where}: param must be a camera setting, e.g. \"camera.elevation_deg\"")
    if not isinstance(values, list) or not values or not all(isinstance(v, (int, float)) for v in values):
        raise ConfigError(f"{where}: values must be a non-empty list of numbers")
    if not isinstance(settings, dict):
        raise ConfigError(f"{where}: set must be a table of setting = value")
    trials = raw.get("trials")
    if trials is not None and (not isinstance(trials, int) or isinstance(trials, bool) or trials < 1):
        raise ConfigError(f"{where}: trials must be a positive integer")
    task = _plan_task(plan, str(raw.get("task", "")))
    task = task.with_overrides(trials=trials, seed=None) if trials else task
    task = apply_overrides(task, [(key, str(value)) for key, value in settings.items()])
    texts = tuple(str(v) for v in values)
    for v in texts:
        apply_override(task, param, v)  # a bad value fails here, before any trial runs
    name = raw.get("name", f"{task.name}_{param.partition('.')[2]}")
    if not isinstance(name, str) or not name or "/" in name:
        raise ConfigError(f"{where}: name must be a folder name")
    return Viewpoints(name, task, param, texts)


def _plan_task(plan: Path, entry: str) -> TaskConfig:
    """The task of a plan entry ``name`` or ``name@mode`` (module docstring)."""
    name, _, mode = entry.partition("@")
    task = load_task(plan.parent / f"{name}.toml" if (plan.parent / f"{name}.toml").is_file() else name)
    if not mode:
        return task
    if mode not in SELECTOR_MODES:
        raise ConfigError(f"{plan}: task {entry!r}: mode must be one of {', '.join(SELECTOR_MODES)}")
    return replace(apply_override(task, "selector.mode", mode), name=f"{task.name}_{mode}")


def run_plan(plan: BenchmarkPlan, runs: Path, workers: int = 1, progress: bool = True, backend: Backend = LOCAL
             ) -> tuple[list[Path], dict[str, tuple[Viewpoints, dict[str, list[SweepPoint]]]]]:
    """Run every (task, detector) of ``plan`` into ``runs``/task/detector and every viewpoint study for every
    detector into ``runs``/viewpoints/name (with its sweep table and plot, ``sweep.DetectorSweep``), on
    ``backend``. All of these runs go to one pool (``runner.run_many``: the same records as one run after
    another, no idle workers between runs, every check made before anything is written). Returns the task
    runs' folders and, per study name, (study, points per detector). With ``plan.seeds`` every (task,
    detector) runs once per seed into ``runs``/task/detector/seed<k>."""
    if plan.seeds:
        specs = [(task.with_overrides(seed=k), det, Path(runs) / task.name / det / f"seed{k}")
                 for task in plan.tasks for det in plan.detectors_of(task.name) for k in plan.seeds]
    else:
        specs = [(task, det, Path(runs) / task.name / det) for task in plan.tasks
                 for det in plan.detectors_of(task.name)]
    sweeps = [(v, DetectorSweep(v.task, plan.detectors_of(v.task.name), v.param, v.values,
                                Path(runs) / "viewpoints" / v.name))
              for v in plan.viewpoints]
    sweep_runs = [sweep.runs() for _, sweep in sweeps]
    results = run_many(specs + [r for rs in sweep_runs for r in rs], workers=workers, progress=progress,
                       backend=backend)
    studies, k = {}, len(specs)
    for (study, sweep), rs in zip(sweeps, sweep_runs):
        studies[study.name] = (study, sweep.write(results[k:k + len(rs)]))
        k += len(rs)
    return [folder for _, _, folder in specs], studies
