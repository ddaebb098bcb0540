"""The benchmark report: detectors × tasks from run folders, beside the paper's physical experiments.

A run folder (``kgn-bench run``) holds ``summary.json`` with its task name, protocol, detector and rates. The
report puts one row per detector and one column per (task, rate): single-object success on primitives and
on household objects, multi-object success and clear rate, each as ``rate [Wilson 95 %] (k/n)``; then the
failure reasons per detector summed over its runs, the per-object rates of each task, and the paper's
real-robot figures (KGNv2 Tab. III and IV) in the columns that correspond to them. Runs of the clutter
protocols (``pile``, ``packed``) form the hard tier, a table of its own: GSR (successes / attempts) and DR
(clear rate: removed / on the table) per task, detector-only (``raw``) and assisted rows side by side, the
objects that fell off the table, and GIGA's published simulation figures as context. Runs of GIGA's own
protocols (``giga_pile``, ``giga_packed``: ``kgn_bench.giga``) form a third table, GIGA's protocol
(calibration): GSR and DR per task with GIGA's published Table I (mean ± std over seeds) in the same columns,
a like-for-like comparison up to what ``GIGA_CALIBRATION_NOTE`` lists. Which table a run goes to is its
protocol's ``report_tier``. Writes ``benchmark.md``, ``benchmark.json``, ``benchmark.png`` (a grouped bar
chart with interval whiskers, one group per column of every table) and ``benchmark.html`` (``html_report``:
the same tables, the chart and links to replays, for a browser). Run folders and results bundles
(``bundle``) are read alike.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write, atomic_write_text
from kgn_bench.protocols import PROTOCOLS, protocol

from .attempt import FAILURE_REASONS
from .html_report import write_html
from .stats import Rate, SeededRate, per_object_meaning, rate_from_dict

__all__ = ["COLUMNS", "DETECTOR_ORDER", "GIGA", "GIGA_FAMILY", "GIGA_PROTOCOLS", "GIGA_TABLE_I", "HARD_PROTOCOLS",
           "PAPER", "Column", "ReportError", "build_report", "environment_warnings", "load_summaries"]


class ReportError(KGNBenchError, RuntimeError):
    """A run folder or bundle that cannot be reported (missing or unreadable summary, two runs for one cell)."""


@dataclass(frozen=True)
class Column:
    """One column: ``rate`` (``success`` or ``clear``) of the runs of task ``task``."""

    task: str
    rate: str
    label: str


COLUMNS = (
    Column("single_object", "success", "single, primitives"),
    Column("single_household", "success", "single, household"),
    Column("multi_object", "success", "multi success"),
    Column("multi_object", "clear", "multi clear"),
    Column("multi_household", "success", "multi (household mix) success"),
    Column("multi_household", "clear", "multi (household mix) clear"),
    Column("single_real", "success", "single, real objects"),
    Column("multi_real", "success", "multi (real objects) success"),
    Column("multi_real", "clear", "multi (real objects) clear"),
)
"""Known columns in display order; runs of other tasks get columns named after the task."""

HARD_PROTOCOLS = tuple(name for name, p in PROTOCOLS.items() if p.report_tier == "hard")
"""Protocols reported in the hard tier (``Protocol.report_tier``)."""

GIGA_PROTOCOLS = tuple(name for name, p in PROTOCOLS.items() if p.report_tier == "giga")
"""Protocols reported in GIGA's protocol (calibration) table: GIGA's own rounds (``Protocol.giga``)."""

GIGA_TABLE_I: dict[str, dict[str, tuple[tuple[float, float], tuple[float, float]]]] = {
    "packed": {"SHAF": ((56.6, 2.0), (58.0, 3.0)), "GPD": ((35.4, 1.9), (30.7, 2.0)),
               "VGN": ((74.5, 1.3), (79.2, 2.3)), "GIGA-Aff": ((77.2, 2.3), (78.9, 1.7)),
               "GIGA": ((83.5, 2.4), (84.3, 2.2)), "GIGA (HR)": ((87.9, 3.0), (86.0, 3.2))},
    "pile": {"SHAF": ((50.7, 1.7), (42.6, 2.8)), "GPD": ((17.7, 2.3), (9.2, 1.3)),
             "VGN": ((60.7, 4.2), (44.0, 4.9)), "GIGA-Aff": ((67.8, 3.0), (49.7, 1.9)),
             "GIGA": ((69.3, 3.3), (49.8, 3.9)), "GIGA (HR)": ((69.8, 3.2), (51.1, 2.8))},
}
"""GIGA (Jiang et al. 2021) Table I, single view, 5 objects a round: ((GSR %, std), (DR %, std)) per scene and
method in the paper's row order, mean and standard deviation over 5 seeds of 100 rounds each."""

GIGA = {scene: {m: (rows[m][0][0], rows[m][1][0]) for m in ("GPD", "VGN", "GIGA")}
        for scene, rows in GIGA_TABLE_I.items()}
"""The rows of ``GIGA_TABLE_I`` the hard tier shows as context: (GSR %, DR %) per scene and method."""

GIGA_FAMILY = {"GPD": "antipodal", "VGN": "vgn"}
"""Published method → this harness's detector of its family (not the method itself)."""

GIGA_CALIBRATION_NOTE = (
    "These rounds follow GIGA's protocol (a floating Panda hand, GIGA's camera and depth noise, placement and "
    "object sizes), so Table I is a like-for-like reference up to what still differs: MuJoCo instead of PyBullet "
    "(contact model, friction); our 43 real test objects (pybullet_data's procedural random_urdfs plus duck, mug "
    "and teddy) instead of GIGA's 40 test meshes, which are not available offline; ours give the pooled rate "
    "with its Wilson 95 % interval, and with several seeds also the mean ± population std over them, GIGA's "
    "figure; and the methods correspond by "
    "family only: GPD ↔ `antipodal` (a GPD-style sampler, not GPD itself), VGN ↔ `vgn` (VGN's network trained "
    "on this simulator's data); SHAF, GIGA-Aff, GIGA and GIGA (HR) have no counterpart here."
)

GIGA_NOTE = (
    "GIGA's figures are context, not a comparison: they come from PyBullet with a free-floating hand (no arm, "
    "no IK, no reach limit) on VGN's object meshes, where ours come from MuJoCo with a 7-DoF arm executing every "
    "grasp through IK on our primitives and household objects."
)

CAMERA_LABELS = {"distance": ("distance", " m"), "elevation_deg": ("elevation", "°"), "azimuth_deg": ("azimuth", "°")}
"""How the viewpoint study names the camera settings it holds fixed: label and unit."""

DETECTOR_ORDER = ("kgnv2", "kgnv2_sbranch", "kgn", "kgn_depth", "vgn", "antipodal", "random", "oracle")

PAPER: dict[str, dict[tuple[str, str], tuple[float, float, int]]] = {
    "kgnv2": {("single_household", "success"): (92.5, 6.7, 40),
              ("multi_household", "success"): (80.0, 10.1, 0),
              ("multi_household", "clear"): (96.0, 7.4, 50)},
    "kgn": {("single_household", "success"): (87.5, 9.6, 40)},
}
"""The paper's real-robot figures: rate %, ± half-width of its 95 % interval, and trials (0 = not stated).
Single-object (Tab. III): 8 household objects × 5 trials; multi-object (Tab. IV): 10 scenes × 5 objects."""

PAPER_NOTE = (
    "Paper rows: KGNv2 Tab. III / IV, a real 7-DoF arm with a RealSense D435 and eight household objects "
    "(5 trials each; 10 cleared scenes of 5). Ours: simulated MuJoCo arm and gripper, primitive and "
    "primitive-built household objects, more trials, the same detector weights for every task. The paper's "
    "intervals are ± half-widths as printed; ours are Wilson 95 % intervals."
)


def _paper_cell(figure: tuple[float, float, int] | None) -> str:
    if figure is None:
        return "—"
    v, h, n = figure
    return f"{v:.1f} ± {h:.1f}" + (f" (n={n})" if n else "")


def load_summaries(folders: list[Path]) -> list[dict[str, Any]]:
    """The ``summary.json`` of each run folder, with ``run`` set to the folder, and the summaries of each
    results bundle (``bundle.read_bundle``) among ``folders``."""
    from .bundle import is_bundle, read_bundle

    out = []
    for folder in folders:
        if is_bundle(folder):
            out += read_bundle(folder)
            continue
        path = Path(folder) / "summary.json"
        if not path.is_file():
            raise ReportError(f"{folder}: no summary.json (run `kgn-bench run` into it first)")
        try:
            summary = json.loads(path.read_text())
        except json.JSONDecodeError as e:
            raise ReportError(f"{path}: not valid JSON ({e})") from None
        missing = [k for k in ("task", "detector", "rates", "failures") if k not in summary]
        if missing:
            raise ReportError(f"{path}: not a run summary (no {', '.join(missing)})")
        summary["run"] = str(folder)
        summary["environment"] = _run_environment(Path(folder))
        out.append(summary)
    return out


def _run_environment(folder: Path) -> dict[str, Any] | None:
    """The package versions ``run.json`` recorded (None for runs made before they were recorded)."""
    try:
        return json.loads((folder / "run.json").read_text()).get("environment")
    except (OSError, json.JSONDecodeError, AttributeError):
        return None


def environment_warnings(summaries: list[dict[str, Any]]) -> list[str]:
    """One line per run whose environment differs from the first run's (or that recorded none), naming
    what differs: mixing environments can change outcomes, so such a table compares unlike with unlike."""
    from kgn_bench.environment import environment_differences

    recorded = [s for s in summaries if s.get("environment")]
    out = [f"{s['run']} records no package versions (made before they were recorded)"
           for s in summaries if not s.get("environment")]
    if recorded:
        first = recorded[0]
        for s in recorded[1:]:
            diff = environment_differences(first["environment"], s["environment"])
            if diff:
                out.append(f"runs from different environments: {s['run']} differs from {first['run']} in "
                           + ", ".join(diff))
    return out


def _environment_line(summaries: list[dict[str, Any]]) -> str:
    envs = [s["environment"] for s in summaries if s.get("environment")]
    if not envs:
        return "Environment: not recorded."
    from kgn_bench.environment import environment_differences

    if any(environment_differences(envs[0], e) for e in envs[1:]) or len(envs) < len(summaries):
        return "Environment: MIXED (see the warnings of `kgn-bench report`)."
    from kgn_bench.environment import portable

    e = envs[0]
    if portable(e):
        where = (f" with the portable {e['kernels']['set']} kernels (any x86-64 CPU with AVX2 gives the same records; "
                 f"measured on {e.get('cpu') or 'an unrecorded CPU'})")
    else:
        where = f" ({e['cpu']}, native kernels: another CPU may flip borderline trials)" if e.get("cpu") else ""
    return (f"Environment: Python {e['python']} on {e['machine']}{where}, "
            + ", ".join(f"{k} {v}" for k, v in e["packages"].items()) + ".")


def _columns(summaries: list[dict[str, Any]]) -> list[Column]:
    present = {(s["task"], r) for s in summaries for r in s["rates"]}
    cols = [c for c in COLUMNS if (c.task, c.rate) in present]
    known = {c.task for c in COLUMNS}
    for task in sorted({s["task"] for s in summaries} - known):
        rates = ("success", "clear") if any(s["task"] == task and "clear" in s["rates"] for s in summaries) \
            else ("success",)
        cols += [Column(task, r, f"{task} {r}") for r in rates]
    return cols


def _detectors(summaries: list[dict[str, Any]]) -> list[str]:
    names = {s["detector"] for s in summaries}
    return [d for d in DETECTOR_ORDER if d in names] + sorted(names - set(DETECTOR_ORDER))


def _tier(summary: dict[str, Any]) -> str:
    """The table a run goes to: its protocol's ``report_tier`` (``main``, ``hard`` or ``giga``)."""
    return protocol(summary.get("protocol")).report_tier


def _cells(summaries: list[dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
    """The runs by (detector, task), the runs of several seeds of one cell merged (``merge_seeds``);
    ``ReportError`` for two runs of one cell with the same seed."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for s in summaries:
        groups.setdefault((s["detector"], s["task"]), []).append(s)
    return {key: runs[0] if len(runs) == 1 else merge_seeds(runs) for key, runs in groups.items()}


def merge_seeds(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """One summary for the runs of one (detector, task) with different seeds (GIGA reports 5 seeds of 100
    rounds): every rate a ``SeededRate`` (successes and attempts summed, and each seed's rate), failure
    counts, attempts, trials and the objects that left summed, ``seeds`` the seeds in order and ``run`` the
    folders joined. ``ReportError`` when two runs share a seed."""
    runs = sorted(runs, key=lambda r: r.get("seed", 0))
    seeds = [r.get("seed") for r in runs]
    if len(set(seeds)) < len(seeds):
        first = runs[0]
        raise ReportError(f"two runs of {first['task']} with {first['detector']} and the same seed: "
                          + ", ".join(r["run"] for r in runs))
    out = dict(runs[0])
    rates = {}
    for name in runs[0]["rates"]:
        parts = [Rate.from_dict(r["rates"][name]) for r in runs if name in r["rates"]]
        rates[name] = SeededRate(sum(p.k for p in parts), sum(p.n for p in parts),
                                 tuple(p.value for p in parts)).to_dict()
    objects: dict[str, Rate] = {}
    for r in runs:
        for name, d in r.get("per_object", {}).items():
            before = objects.get(name, Rate(0, 0))
            objects[name] = Rate(before.k + int(d["k"]), before.n + int(d["n"]))
    out.update(rates=rates, seeds=seeds, run=", ".join(r["run"] for r in runs),
               per_object={name: rate.to_dict() for name, rate in objects.items()},
               **{key: _sum_counts([r.get(key, {}) for r in runs]) for key in ("failures", "selector_rejections")},
               **{key: sum(r.get(key, 0) for r in runs) for key in ("attempts", "trials", "fell_at_setup", "fallen")})
    return out


def _sum_counts(counts: list[dict[str, int]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for c in counts:
        for key, value in c.items():
            out[key] = out.get(key, 0) + int(value)
    return out


@dataclass(frozen=True)
class _Layout:
    """What the report shows: the runs by (detector, task), the hard-tier and GIGA-protocol runs, the columns of
    the main table, the hard tier and GIGA's protocol, and the detectors in display order (all of them, and those
    with a run outside GIGA's protocol: the main table's rows, as before GIGA's protocol had a table)."""

    cells: dict[tuple[str, str], dict[str, Any]]
    hard: list[dict[str, Any]]
    columns: list[Column]
    hard_columns: list[Column]
    detectors: list[str]
    giga: list[dict[str, Any]]
    giga_columns: list[Column]
    main_detectors: list[str]

    @property
    def every(self) -> list[Column]:
        """The columns of all three tables in report order."""
        return self.columns + self.hard_columns + self.giga_columns

    def tier(self, col: Column) -> str:
        """The table column ``col`` belongs to: ``main``, ``hard`` or ``giga``."""
        return "giga" if col in self.giga_columns else "hard" if col in self.hard_columns else "main"

    def rate(self, det: str, col: Column) -> Rate | None:
        """The rate of column ``col`` of ``det``'s run (None if there is no such run or rate)."""
        s = self.cells.get((det, col.task))
        return rate_from_dict(s["rates"][col.rate]) if s and col.rate in s["rates"] else None


def _layout(summaries: list[dict[str, Any]]) -> _Layout:
    cells = _cells(summaries)
    tiers = {t: [s for s in summaries if _tier(s) == t] for t in ("main", "hard", "giga")}
    return _Layout(cells, tiers["hard"], _columns(tiers["main"]), _columns(tiers["hard"]), _detectors(summaries),
                   tiers["giga"], _columns(tiers["giga"]), _detectors(tiers["main"] + tiers["hard"]))


def _main_lines(layout: _Layout) -> list[str]:
    """The title and the main table: detectors × columns, the paper's rows under it and their note."""
    columns, rate = layout.columns, layout.rate
    lines = ["# KGN-Bench closed-loop benchmark", "",
             "Rates in % with Wilson 95 % intervals and (successes / attempts; for clear: removed / placed)."]
    if columns:  # a report of hard-tier or GIGA-protocol runs only has no main table
        lines += ["", "| detector | " + " | ".join(c.label for c in columns) + " |", "|---|" + "---|" * len(columns)]
        for det in layout.main_detectors:
            lines.append(f"| {det} | " + " | ".join(str(r).replace(" %", "") if (r := rate(det, c)) else "—"
                                                   for c in columns) + " |")
    for det, figures in PAPER.items():
        shown = [figures.get((c.task, c.rate)) for c in columns]
        if any(shown):
            lines.append(f"| {det} (paper, real robot) | " + " | ".join(_paper_cell(f) for f in shown) + " |")
    if any(figures.get((c.task, c.rate)) for figures in PAPER.values() for c in columns):
        lines += ["", PAPER_NOTE]
    return lines


def _failure_lines(summaries: list[dict[str, Any]], detectors: list[str]) -> tuple[list[str], dict[str, Any]]:
    """The failure-reason table (attempts per reason, summed over each detector's runs) and its counts."""
    lines = ["", "## Failure reasons (attempts, all tasks)", "",
             "| detector | attempts | " + " | ".join(FAILURE_REASONS) + " |",
             "|---|---:|" + "---:|" * len(FAILURE_REASONS)]
    failures = {}
    for det in detectors:
        runs = [s for s in summaries if s["detector"] == det]
        counts = {r: sum(s["failures"].get(r, 0) for s in runs) for r in FAILURE_REASONS}
        failures[det] = counts
        attempts = sum(s.get("attempts", 0) for s in runs)
        lines.append(f"| {det} | {attempts} | " + " | ".join(str(counts[r]) for r in FAILURE_REASONS) + " |")
    return lines, failures


def _payload(summaries: list[dict[str, Any]], layout: _Layout, failures: dict[str, Any],
             per_object: dict[str, Any], viewpoints: dict[str, tuple[Any, dict[str, list[Any]]]] | None
             ) -> dict[str, Any]:
    """``benchmark.json``: every column's rate per detector (each column names its ``tier``: ``main``, ``hard``
    or ``giga``), the clutter runs' fallen objects, GIGA's published figures (``giga``: the hard tier's context
    rows; ``giga_table_i``: all of Table I with its standard deviations, and ``giga_family``: which of our
    detectors stands for which published method), the paper's figures, failures, per-object rates, the runs, and
    the viewpoint studies' success rates."""
    every, rate = layout.every, layout.rate
    payload = {
        "columns": [{"task": c.task, "rate": c.rate, "label": c.label, "tier": layout.tier(c)} for c in every],
        "detectors": {det: {c.label: (rate(det, c).to_dict() if rate(det, c) else None) for c in every}
                      for det in layout.detectors},
        "fallen": {f"{s['detector']}/{s['task']}": {k: s.get(k, 0) for k in ("fell_at_setup", "fallen")}
                   for s in layout.hard + layout.giga},
        "giga": GIGA,
        "giga_table_i": {scene: {m: {"gsr": {"mean": gsr[0], "std": gsr[1]}, "dr": {"mean": dr[0], "std": dr[1]}}
                                 for m, (gsr, dr) in rows.items()} for scene, rows in GIGA_TABLE_I.items()},
        "giga_family": GIGA_FAMILY,
        "failures": failures,
        "per_object": per_object,
        "paper": {det: {f"{t}/{r}": {"rate": v, "half_width": h, "trials": n} for (t, r), (v, h, n) in f.items()}
                  for det, f in PAPER.items()},
        "runs": [s["run"] for s in summaries],
        "environment_warnings": environment_warnings(summaries),
    }
    if viewpoints:
        payload["viewpoints"] = {
            name: {"task": study.task.name, "param": study.param, "values": list(study.values),
                   "detectors": {det: [p.summary["rates"]["success"] for p in points]
                                 for det, points in series.items()}}
            for name, (study, series) in viewpoints.items()}
    return payload


def _write_report(out: Path, text: str, payload: dict[str, Any], layout: _Layout, summaries: list[dict[str, Any]],
                  viewpoints: dict[str, tuple[Any, dict[str, list[Any]]]] | None) -> None:
    """out/benchmark.{md,json,png,html}, and each viewpoint study's plot copied to out/viewpoints_<name>.png."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name, (_, series) in (viewpoints or {}).items():
        plot = next(iter(series.values()))[0].out.parent.parent / "sweep.png"  # <study>/<detector>/<value>
        if plot.is_file():
            data = plot.read_bytes()
            atomic_write(out / f"viewpoints_{name}.png", lambda f, data=data: f.write(data))
    atomic_write_text(out / "benchmark.md", text)
    atomic_write_text(out / "benchmark.json", json.dumps(payload, indent=1) + "\n")
    _chart(layout.detectors, layout.every, layout.rate, out / "benchmark.png")
    write_html(text, summaries, out)


def build_report(summaries: list[dict[str, Any]], out: Path | None = None,
                 viewpoints: dict[str, tuple[Any, dict[str, list[Any]]]] | None = None) -> tuple[str, dict[str, Any]]:
    """Markdown and JSON of the report; with ``out`` also writes out/benchmark.{md,json,png,html}. ``viewpoints``
    (``benchmark.run_plan``: name → (study, sweep points per detector)) adds the viewpoint study: its
    tables, and its plots copied to out/viewpoints_<name>.png. Runs go to the main table, the hard tier or GIGA's
    protocol (calibration) by their protocol's ``report_tier``. The runs of one (detector, task) with different
    seeds are reported as one (``merge_seeds``)."""
    if not summaries:
        raise ReportError("no runs to report")
    summaries = list(_cells(summaries).values())
    layout = _layout(summaries)
    lines = _main_lines(layout)
    if layout.hard:
        lines += _hard_lines(layout.hard, layout.hard_columns, layout.detectors, layout.rate)
    if layout.giga:
        lines += _giga_lines(layout.giga, layout.giga_columns, layout.detectors, layout.rate)
    if viewpoints:
        lines += _viewpoint_lines(viewpoints)
    failure_lines, failures = _failure_lines(summaries, layout.detectors)
    lines += failure_lines
    tasks = list(dict.fromkeys(c.task for c in layout.every))
    per_object = _per_object(summaries, tasks, layout.detectors)
    lines += _per_object_lines(per_object, {s["task"]: s.get("protocol") for s in summaries})
    lines += ["", "Runs: " + ", ".join(f"`{s['run']}`" for s in summaries), "", _environment_line(summaries)]
    text = "\n".join(lines) + "\n"
    payload = _payload(summaries, layout, failures, per_object, viewpoints)
    if out is not None:
        _write_report(out, text, payload, layout, summaries, viewpoints)
    return text, payload


def _viewpoint_lines(viewpoints: dict[str, tuple[Any, dict[str, list[Any]]]]) -> list[str]:
    """The viewpoint study: per camera sweep, success in % per value and detector, and its plot."""
    lines = ["", "## Viewpoint study", "",
             "Success rate in % with Wilson 95 % intervals (k/n) against one camera setting; the rest of the camera "
             "as stated. Every cell is the same scenes from another camera."]
    for name, (study, series) in viewpoints.items():
        cam = study.task.camera
        fixed = ", ".join(f"{label} {_camera_text(getattr(cam, k))}{unit}" for k, (label, unit) in CAMERA_LABELS.items()
                          if k != study.param.partition(".")[2])
        dets = list(series)
        lines += ["", f"### {name}: {study.task.name}, {study.param} ({fixed})", "",
                  f"| {study.param} | " + " | ".join(dets) + " |", "|---|" + "---|" * len(dets)]
        for i, value in enumerate(study.values):
            lines.append(f"| {value} | " + " | ".join(str(Rate.from_dict(series[d][i].summary["rates"]["success"]))
                                                    .replace(" %", "") for d in dets) + " |")
        lines += ["", f"![{name}](viewpoints_{name}.png)"]
    return lines


def _camera_text(value: Any) -> str:
    """A camera setting as the task holds it: a number, or a range ``[lo, hi]`` drawn per trial."""
    if isinstance(value, (tuple, list)):
        return f"U[{value[0]:g}, {value[1]:g}]" if len(value) == 2 else str(value)
    return f"{value:g}"


def _hard_lines(hard: list[dict[str, Any]], columns: list[Column], detectors: list[str], rate) -> list[str]:
    """The hard tier: detectors × (task, GSR / DR), the objects that fell, and GIGA's figures as context."""
    lines = ["", "## Hard tier: pile and packed clutter", "",
             "GSR = successes / executed grasps, DR = objects removed / objects on the table at the start of the "
             "round, in % with Wilson 95 % intervals. `raw`: the detector's grasp executed as predicted (the paper's "
             "checks only); `assisted`: with the selector's repairs (pose search, centring, levelling, bite).", "",
             *_clutter_rows(columns, detectors, rate)]
    lines += _fell_lines(hard, "Objects off the table")
    lines += ["", "GIGA Table I (simulation, single view, 5 objects), GSR / DR %:", "",
              "| method | " + " | ".join(f"{p} GSR | {p} DR" for p in GIGA) + " |",
              "|---|" + "---:|---:|" * len(GIGA)]
    for method in next(iter(GIGA.values())):
        lines.append(f"| {method} (published) | "
                     + " | ".join(f"{GIGA[p][method][0]:.1f} | {GIGA[p][method][1]:.1f}" for p in GIGA) + " |")
    return [*lines, "", GIGA_NOTE]


def _clutter_rows(columns: list[Column], detectors: list[str], rate) -> list[str]:
    """A clutter table's header (task GSR / DR) and one row per detector that has a run in it."""
    label = {"success": "GSR", "clear": "DR"}
    lines = ["| detector | " + " | ".join(f"{c.task} {label.get(c.rate, c.rate)}" for c in columns) + " |",
             "|---|" + "---|" * len(columns)]
    for det in detectors:
        cells = [str(r).replace(" %", "") if (r := rate(det, c)) else "—" for c in columns]
        if any(cell != "—" for cell in cells):
            lines.append(f"| {det} | " + " | ".join(cells) + " |")
    return lines


def _fell_lines(runs: list[dict[str, Any]], what: str) -> list[str]:
    """The runs' objects that left the table while the round was built and during it (none: no line)."""
    fell = [(s["detector"], s["task"], s.get("fell_at_setup", 0), s.get("fallen", 0)) for s in runs]
    if not any(a or b for _, _, a, b in fell):
        return []
    return ["", f"{what}: " + "; ".join(f"{d} {t}: {a} while building, {b} during the rounds"
                                        for d, t, a, b in fell if a or b) + "."]


def _giga_lines(giga: list[dict[str, Any]], columns: list[Column], detectors: list[str], rate) -> list[str]:
    """GIGA's protocol (calibration): detectors × (task, GSR / DR), GIGA's Table I in the same columns (each
    task's scene, ``giga_pile`` → pile), the objects that left, and what still differs from GIGA's setting."""
    scene = {s["task"]: str(s.get("protocol")).removeprefix("giga_") for s in giga}
    lines = ["", "## GIGA's protocol (calibration)", "",
             "GIGA's clutter rounds in GIGA's own setting (`kgn_bench.giga`). GSR = successes / executed grasps, "
             "DR = objects removed / objects in the round, in % with Wilson 95 % intervals (k/n). The published rows "
             "are GIGA's Table I (Jiang et al. 2021, single view, 5 objects a round): mean ± std over 5 seeds of "
             "100 rounds, in the column of the same scene.", "",
             *_clutter_rows(columns, detectors, rate)]
    which = {"success": 0, "clear": 1}  # GSR, DR
    for method in next(iter(GIGA_TABLE_I.values())):
        figures = [GIGA_TABLE_I.get(scene.get(c.task), {}).get(method) for c in columns]
        lines.append(f"| {method} (published) | " + " | ".join(
            "{:.1f} ± {:.1f}".format(*f[which[c.rate]]) if f and c.rate in which else "—"
            for c, f in zip(columns, figures)) + " |")
    lines += _fell_lines(giga, "Objects that left the round")
    return [*lines, "", GIGA_CALIBRATION_NOTE]


def _per_object(summaries: list[dict[str, Any]], tasks: list[str],
                detectors: list[str]) -> dict[str, dict[str, dict[str, Any]]]:
    """``{task: {detector: {object: rate dict}}}`` in report order (whatever order the runs came in), for
    the runs whose summary has per-object rates."""
    found = {(s["task"], s["detector"]): s["per_object"] for s in summaries if s.get("per_object")}
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for task in tasks:
        for det in detectors:
            if (task, det) in found:
                out.setdefault(task, {})[det] = found[(task, det)]
    return out


def _per_object_lines(per_object: dict[str, dict[str, dict[str, Any]]], protocols: dict[str, Any]) -> list[str]:
    """One table per task: detectors × object types, each cell ``rate % (k/n)``."""
    if not per_object:
        return []
    lines = ["", "## Per object", "",
             "Single-object tasks: successes / attempts on the object. Multi-object tasks: objects of the type put in "
             "the bin / placed."]
    for task, rows in per_object.items():
        names = sorted({name for row in rows.values() for name in row})
        lines += ["", f"**{task}** ({per_object_meaning(protocols.get(task))})", "",
                  "| detector | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
        for det, row in rows.items():
            cells = []
            for name in names:
                r = Rate.from_dict(row[name]) if name in row else None
                cells.append(f"{100 * r.value:.0f} ({r.k}/{r.n})" if r and r.n else "—")
            lines.append(f"| {det} | " + " | ".join(cells) + " |")
    return lines


def _chart(detectors: list[str], columns: list[Column], rate, path: Path) -> None:
    """The grouped bar chart: one group per column, one bar per detector, Wilson 95 % whiskers."""
    import numpy as np

    from kgn_bench.viz.figures import bar_chart, save_figure

    shape = (len(columns), len(detectors))
    values, lows, highs = np.full(shape, np.nan), np.full(shape, np.nan), np.full(shape, np.nan)
    for g, c in enumerate(columns):
        for j, det in enumerate(detectors):
            r = rate(det, c)
            if r is not None and r.n:
                values[g, j], (lows[g, j], highs[g, j]) = 100 * r.value, (100 * x for x in r.interval)
    fig = bar_chart([c.label for c in columns], detectors, values, lows, highs,
                    title="KGN-Bench closed loop: success / clear rate with Wilson 95 % intervals", ylabel="rate (%)")
    save_figure(fig, path)
