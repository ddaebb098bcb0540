"""``kgn-bench run`` and ``kgn-bench sweep``: one closed-loop task, or one task at several
values of a setting."""

from __future__ import annotations

from pathlib import Path

from .common import apply_settings, make_backend, writable
from .options import (
    cluster_options,
    override_options,
    parent,
    quiet_option,
    settings_option,
    task_argument,
    workers_option,
)

__all__ = ["DETECTOR_HELP", "add"]


DETECTOR_HELP = "kgnv2, kgn, kgn_depth, antipodal, random, oracle, ... or module:attribute for your own"
"""The help of ``--detector``."""


def add(sub) -> None:
    """The ``run`` and ``sweep`` commands."""
    for add_command in (_add_run, _add_sweep):
        add_command(sub)


def _one_task():
    """The parent parser of the commands that run one task."""
    return parent(task_argument, override_options, workers_option(1, cluster=True), settings_option("the task"),
                  cluster_options, quiet_option)


def _add_run(sub) -> None:
    """``kgn-bench run``: its arguments."""
    run = sub.add_parser("run", help="run a closed-loop benchmark task (resumes an interrupted run)",
                         parents=[_one_task()])
    run.add_argument("--detector", required=True, help=DETECTOR_HELP)
    run.add_argument("--record", action="store_true", help="write a rerun recording (recording.rrd)")
    run.add_argument("--out", type=Path, help="run folder (default runs/<task>_<detector>_seed<seed>)")
    run.set_defaults(func=_cmd_run)


def _cmd_run(args) -> int:
    from kgn_bench.bench.runner import run_benchmark
    from kgn_bench.bench.stats import summary_markdown
    from kgn_bench.config import load_task, validate

    task = load_task(args.task).with_overrides(trials=args.trials, seed=args.seed)
    validate(task, str(args.task))
    task = apply_settings(task, args.set)
    out = args.out or Path("runs") / f"{task.name}_{args.detector.replace(':', '.')}_seed{task.seed}"
    backend = make_backend(args)
    writable(out, "run folder")
    result = run_benchmark(task, args.detector, out, workers=args.workers, record=args.record,
                           progress=not args.quiet, backend=backend)
    print(summary_markdown(result.summary))
    t = result.timing
    if result.ran:
        rate = t["trials_per_minute"]
        where = "workers" if args.backend == "local" else "in flight on Ray"
        print(f"{result.ran} trials in {t['wall_s']:.1f} s ({rate} trials/min, {args.workers} {where})")
    print(f"wrote {out}/summary.json, summary.md" + (", recording.rrd" if args.record else ""))
    return 0


def _add_sweep(sub) -> None:
    """``kgn-bench sweep``: its arguments."""
    sw = sub.add_parser("sweep", help="run one task at several values of one setting (e.g. depth noise)",
                        parents=[_one_task()])
    sw.add_argument("--detector", required=True, nargs="+",
                    help=DETECTOR_HELP + "; several give one sweep each, side by side (a viewpoint study with a "
                                         "camera.* setting)")
    sw.add_argument("--param", required=True, help="setting to sweep, e.g. camera.depth_noise or camera.elevation_deg")
    sw.add_argument("--values", nargs="+", required=True, help="values, e.g. 0 0.5 1 2")
    sw.add_argument("--out", type=Path, help="sweep folder (default runs/sweep_<task>_<detector>_<param>)")
    sw.set_defaults(func=_cmd_sweep)


def _cmd_sweep(args) -> int:
    from kgn_bench.bench.sweep import detector_sweep_markdown, run_detector_sweep, run_sweep, sweep_markdown
    from kgn_bench.config import load_task, validate

    task = apply_settings(load_task(args.task).with_overrides(trials=args.trials, seed=args.seed), args.set)
    validate(task, str(args.task))
    detectors = list(dict.fromkeys(args.detector))
    name = detectors[0] if len(detectors) == 1 else "detectors"
    out = args.out or Path("runs") / f"sweep_{task.name}_{name}_{args.param}"
    backend = make_backend(args)
    writable(out, "sweep folder")
    if len(detectors) == 1:
        points = run_sweep(task, detectors[0], args.param, args.values, out, workers=args.workers,
                           progress=not args.quiet, backend=backend)
        print(sweep_markdown(task, detectors[0], args.param, points))
        print(f"wrote {out}/sweep.json, sweep.md, sweep.png and one run folder per value")
        return 0
    series = run_detector_sweep(task, detectors, args.param, args.values, out, workers=args.workers,
                                progress=not args.quiet, backend=backend)
    print(detector_sweep_markdown(task, args.param, series))
    print(f"wrote {out}/sweep.json, sweep.md, sweep.png and one sweep folder per detector")
    return 0
