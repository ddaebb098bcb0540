"""The ``kgn-bench`` command. Parses arguments and calls library functions; no logic of its own.

Errors in arguments or inputs print one line ``kgn-bench: error: ...`` and exit with status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit 2."""

    def error(self, message: str):  # type: ignore[override]
        sys.stderr.write(f"kgn-bench: error: {message}\n")
        sys.exit(2)


def _int_at_least(lo: int):
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"must be ≥ {lo}, got {v}")
        return v

    return parse


def _fail(message: str) -> int:
    sys.stderr.write(f"kgn-bench: error: {message}\n")
    return 2


def _cmd_data_generate(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.data.generate import GenerateConfig, generate_dataset
    from kgn_bench.sim.scene import PhysicsError

    config = GenerateConfig(mode=args.mode, scenes=args.scenes, views=args.views, seed=args.seed)
    try:
        stats = generate_dataset(config, args.out, workers=args.workers, overwrite=args.overwrite,
                                 progress=not args.quiet)
    except DatasetError as e:
        return _fail(str(e))
    except PhysicsError as e:
        return _fail(f"{e}; finished scenes are kept, rerun the same command to resume")
    done = config.scenes - stats.scenes
    print(
        f"{args.out}: {config.scenes} scenes x {config.views} views ({stats.scenes} generated now"
        + (f", {done} already there" if done else "")
        + f") in {stats.wall:.1f} s, {stats.views_per_second:.1f} views/s"
    )
    return 0


def _cmd_data_show(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.viz.draw import show_view
    from kgn_bench.viz.plot import save_png

    try:
        image = show_view(args.dir, args.scene, args.view, box=args.box)
    except (DatasetError, ValueError) as e:
        return _fail(str(e))
    save_png(args.out, image)
    print(f"wrote {args.out}")
    return 0


def _cmd_perf_data(args) -> int:
    from kgn_bench.perf import perf_data

    print(perf_data(scenes=args.scenes, workers=args.workers, mode=args.mode))
    return 0


def _apply_settings(task, settings: list[str] | None):
    """``task`` with each ``section.name=value`` of ``--set`` applied (``ConfigError`` names a bad one)."""
    from kgn_bench.config import ConfigError, apply_override

    for setting in settings or ():
        key, sep, value = setting.partition("=")
        if not sep:
            raise ConfigError(f"--set {setting!r}: expected section.name=value")
        task = apply_override(task, key.strip(), value.strip())
    return task


def _cmd_run(args) -> int:
    from kgn_bench.bench.runner import RunError, run_benchmark
    from kgn_bench.config import ConfigError, load_task, validate

    try:
        task = load_task(args.task).with_overrides(trials=args.trials, seed=args.seed)
        validate(task, str(args.task))
        task = _apply_settings(task, args.set)
        out = args.out or Path("runs") / f"{task.name}_{args.detector.replace(':', '.')}_seed{task.seed}"
        result = run_benchmark(task, args.detector, out, workers=args.workers, record=args.record,
                               progress=not args.quiet)
    except (ConfigError, RunError, ValueError) as e:
        return _fail(str(e))
    from kgn_bench.bench.stats import summary_markdown

    print(summary_markdown(result.summary))
    t = result.timing
    if result.ran:
        rate = t["trials_per_minute"]
        print(f"{result.ran} trials in {t['wall_s']:.1f} s ({rate} trials/min, {args.workers} workers)")
    print(f"wrote {out}/summary.json, summary.md" + (", recording.rrd" if args.record else ""))
    return 0


def _cmd_sweep(args) -> int:
    from kgn_bench.bench.runner import RunError
    from kgn_bench.bench.sweep import run_sweep, sweep_markdown
    from kgn_bench.config import ConfigError, load_task, validate

    try:
        task = load_task(args.task).with_overrides(trials=args.trials, seed=args.seed)
        validate(task, str(args.task))
        out = args.out or Path("runs") / f"sweep_{task.name}_{args.detector}_{args.param}"
        points = run_sweep(task, args.detector, args.param, args.values, out, workers=args.workers,
                           progress=not args.quiet)
    except (ConfigError, RunError, ValueError) as e:
        return _fail(str(e))
    print(sweep_markdown(task, args.detector, args.param, points))
    print(f"wrote {out}/sweep.json, sweep.md and one run folder per value")
    return 0


def _cmd_report(args) -> int:
    from kgn_bench.bench.report import ReportError, build_report, load_summaries

    folders = []
    for path in args.runs:  # a run folder, or a folder of run folders (e.g. runs/benchmark)
        found = [path] if (path / "summary.json").is_file() else sorted(p.parent for p in path.rglob("summary.json"))
        folders += found or [path]
    try:
        text, _ = build_report(load_summaries(folders), args.out)
    except ReportError as e:
        return _fail(str(e))
    print(text)
    print(f"wrote {args.out}/benchmark.md, benchmark.json, benchmark.png")
    return 0


def _cmd_benchmark(args) -> int:
    from dataclasses import replace

    from kgn_bench.bench.benchmark import load_plan, run_plan
    from kgn_bench.bench.report import ReportError, build_report, load_summaries
    from kgn_bench.bench.runner import RunError
    from kgn_bench.config import ConfigError

    try:
        plan = load_plan(args.plan, tasks=args.tasks, detectors=args.detectors)
        plan = replace(plan, tasks=tuple(_apply_settings(t, args.set) for t in plan.tasks))
        folders = run_plan(plan, args.runs, workers=args.workers, progress=not args.quiet)
        text, _ = build_report(load_summaries(folders), args.out or args.runs)
    except (ConfigError, RunError, ReportError, ValueError) as e:
        return _fail(str(e))
    print(text)
    print(f"wrote {args.out or args.runs}/benchmark.md, benchmark.json, benchmark.png")
    return 0


def _cmd_check(args) -> int:
    import json

    from kgn_bench.bench.check import baseline_for, compare, format_check, write_baseline

    summary_path = args.run / "summary.json"
    if not summary_path.is_file():
        return _fail(f"{summary_path} not found: run the benchmark first")
    try:
        summary = json.loads(summary_path.read_text())
    except json.JSONDecodeError:
        return _fail(f"{summary_path} is not valid JSON")
    if args.update_baseline:
        write_baseline(summary, args.baseline)
        print(f"wrote baseline {args.baseline}")
        return 0
    if not args.baseline.is_file():
        return _fail(f"baseline {args.baseline} not found (write one with --update-baseline)")
    try:
        baseline = baseline_for(json.loads(args.baseline.read_text()), summary.get("detector", ""))
        rows = compare(summary, baseline)
    except (json.JSONDecodeError, KeyError, ValueError) as e:
        return _fail(f"baseline {args.baseline} unusable: {e}")
    print(format_check(rows, summary, baseline))
    return 1 if any(r.regressed for r in rows) else 0


def _cmd_replay(args) -> int:
    import shutil

    from kgn_bench.viz.recording import open_viewer

    path = args.run / "recording.rrd" if args.run.is_dir() else args.run
    if not path.is_file():
        return _fail(f"{path} not found: run with --record first")
    if args.save:
        shutil.copyfile(path, args.save)
        print(f"wrote {args.save}")
        return 0
    open_viewer(path)
    return 0


def _cmd_perf_run(args) -> int:
    from kgn_bench.perf import perf_run

    print(perf_run(args.task, detector=args.detector, trials=args.trials, workers=args.workers))
    return 0


def _cmd_train(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.model.checkpoint import CheckpointError
    from kgn_bench.model.train import TrainConfigError, load_train_config, train

    try:
        cfg = load_train_config(args.config)
        final = train(cfg, progress=not args.quiet, device=args.device)
    except (TrainConfigError, CheckpointError, DatasetError, FloatingPointError) as e:
        return _fail(str(e))
    print(f"wrote {final}")
    return 0


def _cmd_eval_vision(args) -> int:
    import json

    from kgn_bench.data.format import DatasetError, atomic_write_text
    from kgn_bench.detectors import DetectorError
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.vision import evaluate_dataset
    from kgn_bench.model.checkpoint import CheckpointError

    try:
        detector = KGNDetector(args.variant, args.weights)
        metrics = evaluate_dataset(detector, args.data, split=args.split, views=args.views, progress=not args.quiet)
    except (CheckpointError, DatasetError, DetectorError, ValueError) as e:
        return _fail(str(e))
    summary = metrics.summarise()
    summary.update({"variant": args.variant, "weights": str(args.weights), "data": str(args.data),
                    "split": args.split})
    text = metrics.to_markdown()
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out / "vision.json", json.dumps(summary, indent=1) + "\n")
        atomic_write_text(args.out / "vision.md", text + "\n")
        print(f"wrote {args.out}/vision.json, vision.md")
    return 0


def _cmd_perf_detector(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.model.checkpoint import CheckpointError
    from kgn_bench.perf import perf_detector

    try:
        print(perf_detector(args.variant, args.weights, frames=args.frames, threads=args.threads, data=args.data))
    except (CheckpointError, DatasetError, ValueError) as e:
        return _fail(str(e))
    return 0


def _cmd_eval_show(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.detectors import DetectorError
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.model.checkpoint import CheckpointError
    from kgn_bench.viz.draw import show_predictions
    from kgn_bench.viz.plot import save_png

    try:
        detector = KGNDetector(args.variant, args.weights)
        img = show_predictions(detector, args.data, args.scene, args.view)
    except (CheckpointError, DatasetError, DetectorError, ValueError) as e:
        return _fail(str(e))
    save_png(args.out, img)
    print(f"wrote {args.out}")
    return 0


def _cmd_export(args) -> int:
    from kgn_bench.detectors.kgn import WEIGHTS_DIR
    from kgn_bench.model.checkpoint import CheckpointError, export_weights

    try:
        weights, card = export_weights(args.checkpoint, args.name, args.out or WEIGHTS_DIR)
    except CheckpointError as e:
        return _fail(str(e))
    print(f"wrote {weights} ({weights.stat().st_size / 1e6:.1f} MB) and {card}")
    return 0


def _cmd_study_pnp_noise(args) -> int:
    from kgn_bench.eval.pnp_noise import PnpNoiseConfig, run_pnp_noise, write_pnp_noise

    try:
        config = PnpNoiseConfig(samples=args.samples, seed=args.seed, sigmas=tuple(args.sigmas))
    except ValueError as e:
        return _fail(str(e))
    rows = run_pnp_noise(config)
    print(f"{'box':<17} {'sigma':>5} {'d (m)':>6} {'rot mean':>9} {'rot med':>8} {'t mean':>8} {'t med':>7}  (deg, cm)")
    for r in rows:
        print(f"{r.box:<17} {r.sigma_px:>5g} {r.distance_m:>6.2f} {r.rot_mean_deg:>9.2f} {r.rot_median_deg:>8.2f} "
              f"{r.trans_mean_cm:>8.2f} {r.trans_median_cm:>7.2f}")
    paths = write_pnp_noise(rows, args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_experiment(args) -> int:
    from kgn_bench.data.format import DatasetError
    from kgn_bench.detectors import DetectorError
    from kgn_bench.eval.experiments import ExperimentError, build_table1, build_table2
    from kgn_bench.model.checkpoint import CheckpointError

    build = {"table1": build_table1, "table2": build_table2}[args.table]
    data_dirs = {"single": args.single, "multi": args.multi}
    try:
        text, _ = build(data_dirs, args.out, views=args.views, partial=args.partial, force=args.force)
    except (ExperimentError, CheckpointError, DatasetError, DetectorError, ValueError) as e:
        return _fail(str(e))
    print(text)
    print(f"wrote {args.out}/vision_{args.table}.md, .json (per-model evaluations in {args.out}/vision/)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="kgn-bench", description="KGNv2 grasp detection: dataset, training and closed-loop benchmark.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    data = sub.add_parser("data", help="the Primitive Shape dataset")
    dsub = data.add_subparsers(dest="data_command", required=True, parser_class=_Parser)

    gen = dsub.add_parser("generate", help="generate a PS dataset (resumes an interrupted run)")
    gen.add_argument("--mode", choices=("single", "multi"), required=True,
                     help="single: one random shape per scene; multi: one of each of the six shapes")
    gen.add_argument("--scenes", type=_int_at_least(1), default=1000, help="number of scenes (default 1000)")
    gen.add_argument("--views", type=_int_at_least(1), default=5, help="camera views per scene (default 5)")
    gen.add_argument("--seed", type=_int_at_least(0), default=0, help="dataset seed (default 0)")
    gen.add_argument("--out", type=Path, required=True, help="output folder")
    gen.add_argument("--workers", type=_int_at_least(1), default=1, help="worker processes (default 1)")
    gen.add_argument("--overwrite", action="store_true", help="replace a dataset with other settings in --out")
    gen.add_argument("--quiet", action="store_true", help="no progress bar")
    gen.set_defaults(func=_cmd_data_generate)

    show = dsub.add_parser("show", help="draw a view's collision-free ground-truth grasps and its depth")
    show.add_argument("dir", type=Path, help="dataset folder")
    show.add_argument("--scene", type=_int_at_least(0), required=True)
    show.add_argument("--view", type=_int_at_least(0), default=0)
    show.add_argument("--box", choices=("width", "fixed"), default="width",
                      help="keypoint box side: the grasp width (default) or the fixed 0.1 m training box")
    show.add_argument("--out", type=Path, required=True, help="PNG to write")
    show.set_defaults(func=_cmd_data_show)

    perf = sub.add_parser("perf", help="speed measurements")
    psub = perf.add_subparsers(dest="perf_command", required=True, parser_class=_Parser)
    pdata = psub.add_parser("data", help="dataset generation views/s and its split")
    pdata.add_argument("--scenes", type=_int_at_least(1), default=20)
    pdata.add_argument("--workers", type=_int_at_least(1), default=2)
    pdata.add_argument("--mode", choices=("single", "multi"), default="multi")
    pdata.set_defaults(func=_cmd_perf_data)
    prun = psub.add_parser("run", help="benchmark trials/min and the split (render, detect, select, simulate)")
    prun.add_argument("task", type=Path)
    prun.add_argument("--detector", default="oracle")
    prun.add_argument("--trials", type=_int_at_least(1), default=2, help="trials per object (default 2)")
    prun.add_argument("--workers", type=_int_at_least(1), default=2)
    prun.set_defaults(func=_cmd_perf_run)

    pdet = psub.add_parser("detector", help="detector frames/s at 640×480 (learned ones: and the split)")
    pdet.add_argument("--variant", default="kgnv2", help="a learned variant or another detector, e.g. antipodal")
    pdet.add_argument("--weights", help="weights file or name under assets/weights (default: the shipped one)")
    pdet.add_argument("--frames", type=_int_at_least(1), default=20)
    pdet.add_argument("--threads", type=_int_at_least(1), default=2, help="torch threads (default 2)")
    pdet.add_argument("--data", type=Path, help="dataset whose test views to use (default: 4 generated scenes)")
    pdet.set_defaults(func=_cmd_perf_detector)

    run = sub.add_parser("run", help="run a closed-loop benchmark task (resumes an interrupted run)")
    run.add_argument("task", type=Path, help="task file (tasks/*.toml)")
    run.add_argument("--detector", required=True,
                     help="kgnv2, kgn, kgn_depth, antipodal, random, oracle, ... or module:attribute for your own")
    run.add_argument("--trials", type=_int_at_least(1), help="override the task's trial count")
    run.add_argument("--seed", type=_int_at_least(0), help="override the task's seed")
    run.add_argument("--workers", type=_int_at_least(1), default=1)
    run.add_argument("--record", action="store_true", help="write a rerun recording (recording.rrd)")
    run.add_argument("--out", type=Path, help="run folder (default runs/<task>_<detector>_seed<seed>)")
    run.add_argument("--set", action="append", metavar="SECTION.NAME=VALUE",
                     help="override one task setting, e.g. camera.depth_noise=1 (repeatable)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    sw = sub.add_parser("sweep", help="run one task at several values of one setting (e.g. depth noise)")
    sw.add_argument("task", type=Path, help="task file (tasks/*.toml)")
    sw.add_argument("--detector", required=True)
    sw.add_argument("--param", required=True, help="setting to sweep, e.g. camera.depth_noise")
    sw.add_argument("--values", nargs="+", required=True, help="values, e.g. 0 0.5 1 2")
    sw.add_argument("--trials", type=_int_at_least(1), help="override the task's trial count")
    sw.add_argument("--seed", type=_int_at_least(0), help="override the task's seed")
    sw.add_argument("--workers", type=_int_at_least(1), default=1)
    sw.add_argument("--out", type=Path, help="sweep folder (default runs/sweep_<task>_<detector>_<param>)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(func=_cmd_sweep)

    bm = sub.add_parser("benchmark", help="run every task x detector of a plan, then write the report")
    bm.add_argument("plan", type=Path, nargs="?", default=Path("tasks/benchmark.toml"),
                    help="plan file (default tasks/benchmark.toml)")
    bm.add_argument("--tasks", nargs="+", help="only these tasks of the plan")
    bm.add_argument("--detectors", nargs="+", help="only these detectors of the plan")
    bm.add_argument("--workers", type=_int_at_least(1), default=2)
    bm.add_argument("--runs", type=Path, default=Path("runs/benchmark"), help="run folders (default runs/benchmark)")
    bm.add_argument("--out", type=Path, help="report folder (default: the runs folder)")
    bm.add_argument("--set", action="append", metavar="SECTION.NAME=VALUE",
                    help="override one setting of every task, e.g. selector.palm_margin=0.01 (repeatable)")
    bm.add_argument("--quiet", action="store_true", help="no progress bars")
    bm.set_defaults(func=_cmd_benchmark)

    rep = sub.add_parser("report", help="the benchmark table, failure reasons and bar chart from run folders")
    rep.add_argument("runs", type=Path, nargs="+", help="run folders, or folders holding run folders")
    rep.add_argument("--out", type=Path, default=Path("results"), help="report folder (default results)")
    rep.set_defaults(func=_cmd_report)

    check = sub.add_parser("check", help="fail (exit 1) when a run's rates dropped below a baseline's")
    check.add_argument("run", type=Path, help="run folder holding summary.json")
    check.add_argument("--baseline", type=Path, required=True, help="baseline JSON")
    check.add_argument("--update-baseline", action="store_true", help="write the run's rates as the baseline")
    check.set_defaults(func=_cmd_check)

    replay = sub.add_parser("replay", help="open a run's rerun recording (or save a copy)")
    replay.add_argument("run", type=Path, help="run folder or .rrd file")
    replay.add_argument("--save", type=Path, help="copy the recording here instead of opening the viewer")
    replay.set_defaults(func=_cmd_replay)

    tr = sub.add_parser("train", help="train a KGN / KGNv2 model from a config (resumes an interrupted run)")
    tr.add_argument("config", type=Path, help="training config (tasks/train_*.toml)")
    tr.add_argument("--device", help="torch device (default: cuda when present, else cpu)")
    tr.add_argument("--quiet", action="store_true", help="no progress bar")
    tr.set_defaults(func=_cmd_train)

    ex = sub.add_parser("export", help="ship a trained checkpoint as weights with a model card")
    ex.add_argument("checkpoint", type=Path, help="a training run's final.pt (or last.pt)")
    ex.add_argument("--name", required=True, help="weights name (kgnv2, kgn, ...)")
    ex.add_argument("--out", type=Path, help="folder (default assets/weights)")
    ex.set_defaults(func=_cmd_export)

    ev = sub.add_parser("eval", help="evaluate detectors")
    esub = ev.add_subparsers(dest="eval_command", required=True, parser_class=_Parser)
    vis = esub.add_parser("vision", help="GSR / GCR / OSR on a PS dataset split")
    vis.add_argument("--weights", required=True, help="weights file, or a name under assets/weights")
    vis.add_argument("--variant", default="kgnv2", help="decoding variant (kgnv2, kgnv2_sbranch, kgn, kgn_depth)")
    vis.add_argument("--data", type=Path, required=True, help="dataset folder")
    vis.add_argument("--split", default="test", choices=("train", "test"))
    vis.add_argument("--views", type=_int_at_least(1), help="evaluate only the first N views")
    vis.add_argument("--out", type=Path, help="folder for vision.json and vision.md")
    vis.add_argument("--quiet", action="store_true", help="no progress bar")
    vis.set_defaults(func=_cmd_eval_vision)
    shw = esub.add_parser("show", help="draw a detector's keypoint boxes beside the ground truth of one view")
    shw.add_argument("--weights", required=True, help="weights file, or a name under assets/weights")
    shw.add_argument("--variant", default="kgnv2")
    shw.add_argument("--data", type=Path, required=True)
    shw.add_argument("--scene", type=_int_at_least(0), required=True)
    shw.add_argument("--view", type=_int_at_least(0), default=0)
    shw.add_argument("--out", type=Path, required=True, help="PNG to write")
    shw.set_defaults(func=_cmd_eval_show)

    st = sub.add_parser("study", help="synthetic studies")
    ssub = st.add_subparsers(dest="study_command", required=True, parser_class=_Parser)
    pn = ssub.add_parser("pnp-noise", help="the paper's Fig. 2: IPPE pose error vs distance under keypoint noise")
    pn.add_argument("--samples", type=_int_at_least(1), default=2000, help="orientations per cell (default 2000)")
    pn.add_argument("--sigmas", type=float, nargs="+", default=[1.0, 2.0, 4.0], help="noise levels px (default 1 2 4)")
    pn.add_argument("--seed", type=_int_at_least(0), default=0)
    pn.add_argument("--out", type=Path, default=Path("results/pnp_noise"), help="writes OUT.csv and OUT.png")
    pn.set_defaults(func=_cmd_study_pnp_noise)

    exp = sub.add_parser("experiment", help="the paper's dataset tables from trained weights (no retraining)")
    exp.add_argument("table", choices=("table1", "table2"),
                     help="table1: KGN vs KGNv2, single/multi x single/multi; table2: the ablation")
    exp.add_argument("--single", type=Path, default=Path("data/ps_single"), help="single-object PS dataset")
    exp.add_argument("--multi", type=Path, default=Path("data/ps_multi"), help="multi-object PS dataset")
    exp.add_argument("--views", type=_int_at_least(1), help="evaluate only the first N test views (default all)")
    exp.add_argument("--out", type=Path, default=Path("results"), help="results folder (default results)")
    exp.add_argument("--partial", action="store_true", help="build the table from the models that exist")
    exp.add_argument("--force", action="store_true", help="re-evaluate even when a cached evaluation matches")
    exp.set_defaults(func=_cmd_experiment)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        sys.stderr.write("kgn-bench: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
