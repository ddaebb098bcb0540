"""``kgn-bench benchmark``, ``report``, ``export`` and ``check``: a plan's runs and its
report, results bundles, and the regression check against a baseline."""

from __future__ import annotations

from pathlib import Path

from .common import apply_settings, make_backend, warn, writable, writable_file
from .options import cluster_options, parent, quiet_option, settings_option, workers_option

__all__ = ["add"]


def add(sub) -> None:
    """The ``benchmark``, ``report``, ``export`` and ``check`` commands."""
    for add_command in (_add_benchmark, _add_report, _add_export, _add_check):
        add_command(sub)


def run_folders(paths: list[Path]) -> list[Path]:
    """Run folders and results bundles: each path is one, or a folder holding some (e.g. runs/benchmark, or a
    leaderboard's folder of bundles)."""
    folders = []
    for path in paths:
        if (path / "summary.json").is_file() or (path / "bundle.json").is_file():
            folders.append(path)
            continue
        found = sorted({p.parent for pattern in ("summary.json", "bundle.json") for p in path.rglob(pattern)})
        folders += found or [path]
    return folders


def print_report(text: str, warnings: list[str], out: Path) -> None:
    print(text)
    for w in warnings:
        warn(w)
    print(f"wrote {out}/benchmark.md, benchmark.json, benchmark.png, benchmark.html")


def _add_benchmark(sub) -> None:
    """``kgn-bench benchmark``: its arguments."""
    bm = sub.add_parser("benchmark", help="run every task x detector of a plan, then write the report",
                        parents=[parent(workers_option(2, cluster=True), settings_option("every task"), cluster_options,
                                        quiet_option)])
    bm.add_argument("plan", type=Path, nargs="?", default=Path("benchmark"),
                    help="plan file, or a bundled plan's name (default: the bundled benchmark plan)")
    bm.add_argument("--tasks", nargs="+", help="only these tasks of the plan")
    bm.add_argument("--detectors", nargs="+", help="only these detectors of the plan")
    bm.add_argument("--runs", type=Path, default=Path("runs/benchmark"), help="run folders (default runs/benchmark)")
    bm.add_argument("--out", type=Path, help="report folder (default: the runs folder)")
    bm.add_argument("--no-viewpoints", action="store_true",
                    help="skip the plan's viewpoint studies (camera sweeps; RUNS/viewpoints)")
    bm.set_defaults(func=_cmd_benchmark)


def _cmd_benchmark(args) -> int:
    from dataclasses import replace

    from kgn_bench.bench.benchmark import load_plan, run_plan
    from kgn_bench.bench.report import build_report, environment_warnings, load_summaries

    plan = load_plan(args.plan, tasks=args.tasks, detectors=args.detectors)
    plan = replace(plan, tasks=tuple(apply_settings(t, args.set) for t in plan.tasks),
                   viewpoints=() if args.no_viewpoints else tuple(
                       replace(v, task=apply_settings(v.task, args.set)) for v in plan.viewpoints))
    backend = make_backend(args)
    writable(args.runs, "runs folder")
    writable(args.out, "report folder")
    folders, studies = run_plan(plan, args.runs, workers=args.workers, progress=not args.quiet, backend=backend)
    summaries = load_summaries(folders)
    text, _ = build_report(summaries, args.out or args.runs, studies)
    print_report(text, environment_warnings(summaries), args.out or args.runs)
    return 0


def _add_report(sub) -> None:
    """``kgn-bench report``: its arguments."""
    rep = sub.add_parser("report", help="the benchmark table, failure reasons and bar chart from run folders "
                         "or results bundles (Markdown, JSON, PNG and an HTML page)")
    rep.add_argument("runs", type=Path, nargs="+",
                     help="run folders or results bundles, or folders holding them")
    rep.add_argument("--out", type=Path, default=Path("results"), help="report folder (default results)")
    rep.set_defaults(func=_cmd_report)


def _cmd_report(args) -> int:
    from kgn_bench.bench.report import build_report, environment_warnings, load_summaries

    writable(args.out, "report folder")
    summaries = load_summaries(run_folders(args.runs))
    text, _ = build_report(summaries, args.out)
    print_report(text, environment_warnings(summaries), args.out)
    return 0


def _add_export(sub) -> None:
    """``kgn-bench export``: its arguments."""
    exp = sub.add_parser("export", help="results bundles to publish: one folder per detector (summaries, a CSV of "
                         "every attempt, task configs and their hashes, the environment, the detector's card)")
    exp.add_argument("runs", type=Path, nargs="+", help="finished run folders, or folders holding them")
    exp.add_argument("--out", type=Path, required=True, help="folder to write the bundles into")
    exp.add_argument("--overwrite", action="store_true", help="replace bundles of the same detectors")
    exp.set_defaults(func=_cmd_export)


def _cmd_export(args) -> int:
    from kgn_bench.bench.bundle import export_bundles

    writable(args.out, "bundle folder")
    for folder in export_bundles(run_folders(args.runs), args.out, overwrite=args.overwrite):
        print(f"wrote {folder}")
    return 0


def _add_check(sub) -> None:
    """``kgn-bench check``: its arguments."""
    check = sub.add_parser("check", help="fail (exit 1) when a run's rates dropped below a baseline's")
    check.add_argument("run", type=Path, help="run folder holding summary.json")
    check.add_argument("--baseline", type=Path, required=True, help="baseline JSON")
    check.add_argument("--update-baseline", action="store_true",
                       help="write the run's rates and fingerprint as its detector's baseline")
    check.add_argument("--against", metavar="DETECTOR",
                       help="compare with this detector's baseline instead of the run's own (statistical test)")
    check.set_defaults(func=_cmd_check)


def _cmd_check(args) -> int:
    from kgn_bench.bench.check import (
        CheckError,
        baseline_for,
        check,
        format_check,
        read_baseline,
        read_run,
        write_baseline,
    )

    run = read_run(args.run)
    if args.update_baseline:
        if args.against:
            raise CheckError("--against and --update-baseline do not go together: a baseline is the run's own "
                             "detector's")
        writable_file(args.baseline, "baseline")
        write_baseline(run, args.baseline)
        print(f"wrote baseline {args.baseline} ({run.summary['detector']}: rates and the fingerprint of "
              f"{len(run.fingerprint.trials)} trials)")
        return 0
    detector = args.against or run.summary["detector"]
    result = check(run, baseline_for(read_baseline(args.baseline), detector, args.baseline), args.against)
    print(format_check(result, run))
    return 1 if result.regressed else 0
