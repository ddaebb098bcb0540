"""The ``kgn-bench`` command. Parses arguments and calls library functions; no logic of its own.

Errors in arguments or inputs print one line ``kgn-bench: error: ...`` and exit with status 2.
"""

from __future__ import annotations

import argparse
import errno
import sys
import time
from pathlib import Path

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit 2."""

    def error(self, message: str):  # type: ignore[override]
        sys.stderr.write(f"kgn-bench: error: {message}\n")
        sys.exit(2)


def _int_at_least(lo: int, hi: int | None = None):
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"must be ≥ {lo}, got {v}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"must be ≤ {hi}, got {v}")
        return v

    return parse


def _fail(message: str) -> int:
    sys.stderr.write(f"kgn-bench: error: {message}\n")
    return 2


def _warn(message: str) -> None:
    sys.stderr.write(f"kgn-bench: warning: {message}\n")


def _backend(args):
    """The ``pool.Backend`` of ``--backend``, ``--address`` and ``--num-gpus``; sets ``args.workers`` when it was
    not given (the command's default locally, the jobs the cluster runs at once on Ray) and warns when more
    local workers are asked for than there are cores."""
    from kgn_bench.pool import Backend

    backend = Backend(args.backend, address=args.address, num_gpus=args.num_gpus)
    if args.workers is None and backend.kind == "ray":
        from kgn_bench.cluster import job_slots

        args.workers = job_slots(backend.address, backend.num_cpus, backend.num_gpus)
    elif args.workers is None:
        args.workers = args.local_workers
    _check_workers(args.workers, args.backend)
    return backend


def _check_workers(workers: int, backend: str = "local") -> None:
    """Warn when more worker processes are asked for than there are cores (they would only queue); on Ray,
    ``--workers`` is the number of jobs in flight on the cluster, whose cores are not this machine's."""
    from kgn_bench.threads import available_cores

    if backend != "local":
        return
    cores = available_cores()
    if workers > cores:
        _warn(f"--workers {workers} is more than the {cores} core(s) of this machine; trials will queue "
              f"and run slower than with --workers {cores}")


def _writable(path: Path | None, what: str = "output folder") -> None:
    if path is not None:
        from kgn_bench.io import check_writable_dir

        check_writable_dir(path, what)


def _writable_file(path: Path, what: str) -> None:
    """Check before any work that ``path`` can be written as a file (its folder exists or can be made)."""
    from kgn_bench.errors import OutputError

    if path.is_dir():
        raise OutputError(f"{what} {path} is a folder, not a file")
    _writable(path.parent if str(path.parent) else Path("."), f"folder of {what}")


def _object_names(items: list[str]) -> list[str]:
    """Object names from the command line, a packaged set's name (``pybullet_test``) expanded to its objects;
    the packaged ones the library lacks are imported first."""
    from kgn_bench.objects.pybullet_set import ensure_objects
    from kgn_bench.shapes import is_known
    from kgn_bench.shapes.library import OBJECT_SETS, packaged, set_names

    names: list[str] = []
    for item in items:
        names += set_names(item) if item in OBJECT_SETS else [item]
    for n in names:
        if not (is_known(n) or packaged(n)):
            raise ValueError(f"unknown object {n!r}: neither built in, imported nor in a packaged set "
                             "(kgn-bench objects list)")
    ensure_objects(names)
    return list(dict.fromkeys(names))


def _cmd_data_generate(args) -> int:
    from kgn_bench.data.generate import GenerateConfig, generate_dataset
    from kgn_bench.sim.scene import PhysicsError

    backend = _backend(args)
    _writable(args.out)
    objects = _object_names(args.objects or [])
    config = GenerateConfig(mode=args.mode, scenes=args.scenes, views=args.views, seed=args.seed,
                            objects=tuple(objects))
    try:
        stats = generate_dataset(config, args.out, workers=args.workers, overwrite=args.overwrite,
                                 progress=not args.quiet, backend=backend)
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
    from kgn_bench.viz.draw import show_view
    from kgn_bench.viz.images import save_png

    _writable_file(args.out, "image")
    save_png(args.out, show_view(args.dir, args.scene, args.view, box=args.box))
    print(f"wrote {args.out}")
    return 0


def _cmd_perf_data(args) -> int:
    from kgn_bench.bench.perf import perf_data

    print(perf_data(scenes=args.scenes, workers=args.workers, mode=args.mode))
    return 0


def _cmd_perf_import(args) -> int:
    from kgn_bench.bench.perf import perf_import

    print(perf_import(args.mesh, faces=args.faces, verify=args.verify))
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
    from kgn_bench.bench.runner import run_benchmark
    from kgn_bench.bench.stats import summary_markdown
    from kgn_bench.config import load_task, validate

    task = load_task(args.task).with_overrides(trials=args.trials, seed=args.seed)
    validate(task, str(args.task))
    task = _apply_settings(task, args.set)
    out = args.out or Path("runs") / f"{task.name}_{args.detector.replace(':', '.')}_seed{task.seed}"
    backend = _backend(args)
    _writable(out, "run folder")
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


def _cmd_sweep(args) -> int:
    from kgn_bench.bench.sweep import detector_sweep_markdown, run_detector_sweep, run_sweep, sweep_markdown
    from kgn_bench.config import load_task, validate

    task = _apply_settings(load_task(args.task).with_overrides(trials=args.trials, seed=args.seed), args.set)
    validate(task, str(args.task))
    detectors = list(dict.fromkeys(args.detector))
    name = detectors[0] if len(detectors) == 1 else "detectors"
    out = args.out or Path("runs") / f"sweep_{task.name}_{name}_{args.param}"
    backend = _backend(args)
    _writable(out, "sweep folder")
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


def _run_folders(paths: list[Path]) -> list[Path]:
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


def _print_report(text: str, warnings: list[str], out: Path) -> None:
    print(text)
    for w in warnings:
        _warn(w)
    print(f"wrote {out}/benchmark.md, benchmark.json, benchmark.png, benchmark.html")


def _cmd_report(args) -> int:
    from kgn_bench.bench.report import build_report, environment_warnings, load_summaries

    _writable(args.out, "report folder")
    summaries = load_summaries(_run_folders(args.runs))
    text, _ = build_report(summaries, args.out)
    _print_report(text, environment_warnings(summaries), args.out)
    return 0


def _cmd_benchmark(args) -> int:
    from dataclasses import replace

    from kgn_bench.bench.benchmark import load_plan, run_plan
    from kgn_bench.bench.report import build_report, environment_warnings, load_summaries

    plan = load_plan(args.plan, tasks=args.tasks, detectors=args.detectors)
    plan = replace(plan, tasks=tuple(_apply_settings(t, args.set) for t in plan.tasks),
                   viewpoints=() if args.no_viewpoints else tuple(
                       replace(v, task=_apply_settings(v.task, args.set)) for v in plan.viewpoints))
    backend = _backend(args)
    _writable(args.runs, "runs folder")
    _writable(args.out, "report folder")
    folders, studies = run_plan(plan, args.runs, workers=args.workers, progress=not args.quiet, backend=backend)
    summaries = load_summaries(folders)
    text, _ = build_report(summaries, args.out or args.runs, studies)
    _print_report(text, environment_warnings(summaries), args.out or args.runs)
    return 0


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
        _writable_file(args.baseline, "baseline")
        write_baseline(run, args.baseline)
        print(f"wrote baseline {args.baseline} ({run.summary['detector']}: rates and the fingerprint of "
              f"{len(run.fingerprint.trials)} trials)")
        return 0
    detector = args.against or run.summary["detector"]
    result = check(run, baseline_for(read_baseline(args.baseline), detector, args.baseline), args.against)
    print(format_check(result, run))
    return 1 if result.regressed else 0


def _cmd_replay(args) -> int:
    from kgn_bench.viz.recording import RecordingError
    from kgn_bench.viz.rerun_viewer import copy_recording, open_viewer, serve_web

    path = args.run / "recording.rrd" if args.run.is_dir() else args.run
    if not path.is_file():
        raise RecordingError(f"{path} not found: run with --record first")
    for out, what in ((args.still, "still"), (args.save, "recording copy")):
        if out:
            _writable_file(out, what)  # before any work, as every command checks its outputs
    with open(path, "rb") as f:
        if f.read(3) != b"RRF":  # rerun's file magic (RRF2 today)
            raise RecordingError(f"{path} is not a rerun recording (.rrd)")
    if args.still:
        from kgn_bench.viz.still import save_still

        obs = save_still(path, args.still, trial=args.trial, attempt=args.attempt)
        print(f"wrote {args.still} (trial {args.trial}, attempt {args.attempt}, {len(obs.candidates) // 4} "
              f"candidates drawn)")
        return 0
    if args.save:
        copy_recording(path, args.save)
        print(f"wrote {args.save}")
        return 0
    if args.web:
        serve_web(path, port=args.port)
        return 0
    open_viewer(path)
    return 0


def _cmd_perf_run(args) -> int:
    from kgn_bench.bench.perf import perf_run

    print(perf_run(args.task, detector=args.detector, trials=args.trials, workers=args.workers))
    return 0


def _cmd_perf_backends(args) -> int:
    from kgn_bench.bench.perf import perf_backends

    print(perf_backends(args.task, detector=args.detector, workers=args.workers, rounds=args.rounds,
                        address=args.address, trials=args.trials))
    return 0


def _cmd_train(args) -> int:
    from kgn_bench.eval.vision import held_out_evaluator
    from kgn_bench.training.train import load_train_config, train

    cfg = load_train_config(args.config)
    _writable(Path(cfg.train.out), "training run folder")
    final = train(cfg, progress=not args.quiet, device=args.device, threads=args.threads, evaluate=held_out_evaluator)
    print(f"wrote {final}")
    return 0


def _cmd_eval_vision(args) -> int:
    import json

    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.vision import evaluate_dataset
    from kgn_bench.io import atomic_write_text

    _writable(args.out)
    detector = KGNDetector(args.variant, args.weights)
    metrics = evaluate_dataset(detector, args.data, split=args.split, views=args.views, progress=not args.quiet)
    summary = metrics.summarise()
    summary.update({"variant": detector.name, "weights": str(args.weights), "data": str(args.data),
                    "split": args.split})
    text = metrics.to_markdown()
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out / "vision.json", json.dumps(summary, indent=1) + "\n")
        atomic_write_text(args.out / "vision.md", text + "\n")
        print(f"wrote {args.out}/vision.json, vision.md")
    return 0


def _cmd_eval_errors(args) -> int:
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.errors import decompose_dataset, markdown, write_errors

    _writable(args.out)
    detector = KGNDetector(args.variant, args.weights)
    table = decompose_dataset(detector, args.data, split=args.split, views=args.views, progress=not args.quiet)
    title = f"Error decomposition: {args.weights} ({detector.name}) on {args.data} {args.split}"
    print(markdown(table.summary(), title))
    if args.out:
        meta = {"weights": str(args.weights), "variant": detector.name, "data": str(args.data), "split": args.split,
                "views": args.views}
        paths = write_errors(table, args.out, title, meta)
        print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_eval_physics(args) -> int:
    import json

    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.physics_check import physics_success, to_markdown
    from kgn_bench.io import atomic_write_text

    _writable(args.out)
    detector = KGNDetector(args.variant, args.weights)
    counts = physics_success(detector, args.data, split=args.split, views=args.views, top_k=args.top,
                             progress=not args.quiet)
    text = to_markdown(counts, f"{args.weights} ({detector.name}) on {args.data} {args.split}")
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out / "physics.json", json.dumps(counts, indent=1) + "\n")
        atomic_write_text(args.out / "physics.md", text)
        print(f"wrote {args.out}/physics.json, physics.md")
    return 0


def _cmd_perf_kernels(args) -> int:
    from kgn_bench.bench.kernel_study import study

    print(study(records=args.records))
    return 0


def _cmd_perf_detector(args) -> int:
    from kgn_bench.bench.perf import perf_detector

    print(perf_detector(args.variant, args.weights, frames=args.frames, threads=args.threads, data=args.data))
    return 0


def _cmd_eval_show(args) -> int:
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.viz.draw import show_predictions
    from kgn_bench.viz.images import save_png

    _writable_file(args.out, "image")
    detector = KGNDetector(args.variant, args.weights)
    save_png(args.out, show_predictions(detector, args.data, args.scene, args.view))
    print(f"wrote {args.out}")
    return 0


def _cmd_eval_trial(args) -> int:
    from kgn_bench.eval.explain import explain_trial, markdown, write_explanation

    out = args.out or args.run / "explain" / f"trial_{args.trial:05d}_attempt_{args.attempt}"
    _writable(out, "explanation folder")
    x = explain_trial(args.run, args.trial, args.attempt, detector=args.detector)
    paths = write_explanation(x, out)
    print(markdown(x))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def _cmd_eval_failures(args) -> int:
    from kgn_bench.eval.explain import explain_failures, failures_markdown, write_failures

    out = args.out or args.run / "explain"
    _writable(out, "explanation folder")
    study = explain_failures(args.run, progress=not args.quiet, detector=args.detector)
    paths = write_failures(study, out)
    print(failures_markdown(study))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def _cmd_export(args) -> int:
    from kgn_bench.bench.bundle import export_bundles

    _writable(args.out, "bundle folder")
    for folder in export_bundles(_run_folders(args.runs), args.out, overwrite=args.overwrite):
        print(f"wrote {folder}")
    return 0


def _cmd_ship(args) -> int:
    from kgn_bench.model.checkpoint import export_weights
    from kgn_bench.viz.figures import save_training_curves

    _writable(args.out, "weights folder")
    weights, card = export_weights(args.checkpoint, args.name, args.out)
    save_training_curves(weights)
    print(f"wrote {weights} ({weights.stat().st_size / 1e6:.1f} MB) and {card}")
    return 0


def _cmd_study_pnp_noise(args) -> int:
    from kgn_bench.eval.pnp_noise import PnpNoiseConfig, run_pnp_noise, write_pnp_noise

    config = PnpNoiseConfig(samples=args.samples, seed=args.seed, sigmas=tuple(args.sigmas))
    _writable(args.out.parent if str(args.out.parent) else Path("."), "study folder")
    rows = run_pnp_noise(config)
    print(f"{'box':<17} {'sigma':>5} {'d (m)':>6} {'rot mean':>9} {'rot med':>8} {'t mean':>8} {'t med':>7}  (deg, cm)")
    for r in rows:
        print(f"{r.box:<17} {r.sigma_px:>5g} {r.distance_m:>6.2f} {r.rot_mean_deg:>9.2f} {r.rot_median_deg:>8.2f} "
              f"{r.trans_mean_cm:>8.2f} {r.trans_median_cm:>7.2f}")
    paths = write_pnp_noise(rows, args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _cmd_experiment(args) -> int:
    from kgn_bench.eval.experiments import build_table1, build_table2

    build = {"table1": build_table1, "table2": build_table2}[args.table]
    data_dirs = {"single": args.single, "multi": args.multi}
    _writable(args.out, "results folder")
    text, _ = build(data_dirs, args.out, views=args.views, partial=args.partial, force=args.force)
    print(text)
    print(f"wrote {args.out}/vision_{args.table}.md, .json (per-model evaluations in {args.out}/vision/)")
    return 0


def _cmd_objects_add(args) -> int:
    from kgn_bench.objects.importer import ImportConfig, import_mesh
    from kgn_bench.shapes.library import packaged
    from kgn_bench.shapes.mesh_object import MeshObject

    config = ImportConfig(scale=args.scale, size=args.size, density=args.density, mass=args.mass,
                          color=tuple(args.color), hulls=args.hulls, seed=args.seed, verify=args.verify,
                          licence=args.licence)
    started = time.perf_counter()

    def progress(stage: str) -> None:
        sys.stderr.write(f"{args.name}: {stage} ({time.perf_counter() - started:.0f} s)\n")

    folder = import_mesh(args.mesh, args.name, config, root=args.root, overwrite=args.overwrite, progress=progress)
    if packaged(args.name):
        _warn(f"{args.name} now shadows the packaged object of that name in every task that names it "
              "(remove the folder to undo)")
    m = MeshObject(folder).manifest
    g, t = m["grasps"], m["timing_s"]
    print(f"{m['name']}: {folder} ({m['faces']} faces, {m['hulls']} hulls, {m['mass'] * 1000:.0f} g, "
          f"{g['held']} of {g['checked']} checked grasps held, {t['total']:.1f} s)")
    return 0


def _cmd_objects_list(args) -> int:
    from kgn_bench.shapes import OBJECTS
    from kgn_bench.shapes.library import library_roots, list_objects
    from kgn_bench.shapes.mesh_object import MeshObject, ObjectError, check_object

    print("built-in: " + ", ".join(OBJECTS))
    found = list_objects()
    print(f"imported ({len(found)}; searched {', '.join(map(str, library_roots()))}):")
    broken = 0
    for name, folder in found.items():
        try:
            check_object(folder)
            m = MeshObject(folder).manifest
            ext = " x ".join(f"{e * 100:.1f}" for e in m["extents_m"])
            print(f"  {name:<16} {ext} cm  {m['mass'] * 1000:6.0f} g  {m['grasps']['held']:4d} grasps  {folder}")
        except (ObjectError, KeyError, TypeError) as e:  # one bad entry is marked, the others are listed
            broken += 1
            reason = str(e).splitlines()[0] if isinstance(e, ObjectError) else f"manifest lacks {e}"
            print(f"  {name:<16} BROKEN: {reason}")
    if broken:
        _warn(f"{broken} imported object(s) are broken; import them again (kgn-bench objects add … --overwrite)")
    return 0


def _cmd_objects_show(args) -> int:
    import numpy as np

    from kgn_bench.shapes import sample_shape
    from kgn_bench.viz.objects import draw_object

    _writable_file(args.out, "image")
    shape = sample_shape(args.name, np.random.default_rng(args.seed))
    draw_object(shape, args.out, max_grasps=args.grasps)
    print(f"wrote {args.out}")
    return 0


def _cmd_objects_import_set(args) -> int:
    from kgn_bench.objects.pybullet_set import import_set, set_items

    failed = import_set(args.split, workers=args.workers, progress=not args.quiet)
    items = set_items(args.split)
    for name, error in failed.items():
        _warn(f"{name} refused: {error}")
    print(f"pybullet {args.split}: {len(items) - len(failed)} of {len(items)} objects in the library"
          + (f", {len(failed)} refused" if failed else ""))
    return 0


def _cmd_objects_check_labeller(args) -> int:
    import json

    from kgn_bench.io import atomic_write_text, check_writable_dir
    from kgn_bench.objects.labeller_check import check_labeller, format_table, to_json

    check_writable_dir(args.out)
    results = check_labeller(args.shapes, seed=args.seed, verify=args.verify, control=args.control, out=args.out)
    table = format_table(results)
    atomic_write_text(args.out / "agreement.md", table)
    atomic_write_text(args.out / "agreement.json", json.dumps(to_json(results), indent=1) + "\n")
    print(table)
    print(f"wrote {args.out}/agreement.md, agreement.json and one PNG per shape")
    return 0


# -- the parser: parent parsers hold the options several commands share ------------------------------------
def _parent(*adders) -> argparse.ArgumentParser:
    parent = _Parser(add_help=False)
    for add in adders:
        add(parent)
    return parent


def _workers(default: int, cluster: bool = False):
    def add(p):
        if not cluster:
            p.add_argument("--workers", type=_int_at_least(1), default=default,
                           help=f"worker processes (default {default})")
            return
        p.add_argument("--workers", type=_int_at_least(1),
                       help=f"worker processes (default {default}); with --backend ray the jobs in flight on the "
                            "cluster (default: as many as its CPUs run at once)")
        p.set_defaults(local_workers=default)
    return add


def _cluster(p):
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where jobs run: this machine's worker processes (default) or a Ray cluster "
                        "(pip install 'kgn-bench[ray]'; docs/cluster.md)")
    p.add_argument("--address", help="with --backend ray: the cluster to join, e.g. 10.0.0.1:6379 (default "
                                     "RAY_ADDRESS, else a local Ray on this machine's cores)")
    p.add_argument("--num-gpus", type=float, default=0.0,
                   help="with --backend ray: GPUs per job, e.g. 0.25 for four trials of a GPU detector per GPU "
                        "(default 0: CPU only)")


def _quiet(p):
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _task(p):
    p.add_argument("task", type=Path, help="task file, or a bundled task's name (single_object, ...)")


def _overrides(p):
    p.add_argument("--trials", type=_int_at_least(1),
                   help="override the task's [task] trials: per object for single_object tasks (6 objects x "
                        "N trials), scenes for multi_object tasks")
    p.add_argument("--seed", type=_int_at_least(0), help="override the task's seed")


def _settings(what: str):
    def add(p):
        p.add_argument("--set", action="append", metavar="SECTION.NAME=VALUE",
                       help=f"override one setting of {what}, e.g. camera.depth_noise=1 (repeatable)")
    return add


def _weights(p):
    p.add_argument("--weights", required=True, help="weights file, or a name under assets/weights")
    p.add_argument("--variant", help="decoding variant (kgnv2, kgnv2_sbranch, kgn, kgn_depth; default: the "
                                     "variant the weights were trained as)")


def _split(p):
    p.add_argument("--data", type=Path, required=True, help="dataset folder")
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--views", type=_int_at_least(1), help="evaluate only the first N views")


def _add_data(sub) -> None:
    data = sub.add_parser("data", help="the Primitive Shape dataset")
    dsub = data.add_subparsers(dest="data_command", required=True, parser_class=_Parser)
    gen = dsub.add_parser("generate", help="generate a PS dataset (resumes an interrupted run)",
                          parents=[_parent(_workers(1, cluster=True), _cluster, _quiet)])
    gen.add_argument("--mode", choices=("single", "multi"), required=True,
                     help="single: one random shape per scene; multi: one of each of the six shapes")
    gen.add_argument("--scenes", type=_int_at_least(1), default=1000, help="number of scenes (default 1000)")
    gen.add_argument("--views", type=_int_at_least(1), default=5, help="camera views per scene (default 5)")
    gen.add_argument("--seed", type=_int_at_least(0), default=0, help="dataset seed (default 0)")
    gen.add_argument("--out", type=Path, required=True, help="output folder")
    gen.add_argument("--overwrite", action="store_true", help="replace a dataset with other settings in --out")
    gen.add_argument("--objects", nargs="+", metavar="NAME",
                     help="object types or a set (pybullet_test) to draw from instead of the six primitives; "
                          "multi mode puts six of them in each scene")
    gen.set_defaults(func=_cmd_data_generate)
    show = dsub.add_parser("show", help="draw a view's collision-free ground-truth grasps and its depth")
    show.add_argument("dir", type=Path, help="dataset folder")
    show.add_argument("--scene", type=_int_at_least(0), required=True)
    show.add_argument("--view", type=_int_at_least(0), default=0)
    show.add_argument("--box", choices=("width", "fixed"), default="width",
                      help="keypoint box side: the grasp width (default) or the fixed 0.1 m training box")
    show.add_argument("--out", type=Path, required=True, help="PNG to write")
    show.set_defaults(func=_cmd_data_show)


def _add_perf(sub) -> None:
    perf = sub.add_parser("perf", help="speed measurements")
    psub = perf.add_subparsers(dest="perf_command", required=True, parser_class=_Parser)
    pdata = psub.add_parser("data", help="dataset generation views/s and its split", parents=[_parent(_workers(2))])
    pdata.add_argument("--scenes", type=_int_at_least(1), default=20)
    pdata.add_argument("--mode", choices=("single", "multi"), default="multi")
    pdata.set_defaults(func=_cmd_perf_data)
    prun = psub.add_parser("run", help="benchmark trials/min and the split (render, detect, select, simulate)",
                           parents=[_parent(_task, _workers(2))])
    prun.add_argument("--detector", default="oracle")
    prun.add_argument("--trials", type=_int_at_least(1), default=2, help="trials per object (default 2)")
    prun.set_defaults(func=_cmd_perf_run)
    pdet = psub.add_parser("detector", help="detector frames/s at 640×480 (learned ones: and the split)")
    pdet.add_argument("--variant", default="kgnv2", help="a learned variant or another detector, e.g. antipodal")
    pdet.add_argument("--weights", help="weights file or name under assets/weights (default: the shipped one)")
    pdet.add_argument("--frames", type=_int_at_least(1), default=20)
    pdet.add_argument("--threads", type=_int_at_least(1), default=2, help="torch threads (default 2)")
    pdet.add_argument("--data", type=Path, help="dataset whose test views to use (default: 4 generated scenes)")
    pdet.set_defaults(func=_cmd_perf_detector)
    pimp = psub.add_parser("import", help="seconds to import one mesh (objects add), and the split")
    pimp.add_argument("--mesh", type=Path, help="mesh file (default: a generated torus of --faces triangles)")
    pimp.add_argument("--faces", type=_int_at_least(100), default=20_000)
    pimp.add_argument("--verify", type=_int_at_least(8), default=160, help="grasps checked in physics (160)")
    pimp.set_defaults(func=_cmd_perf_import)
    pback = psub.add_parser("backends", help="Ray's overhead against the local pool: `run` start to exit on each, "
                            "in turn", parents=[_parent(_task, _workers(2))])
    pback.add_argument("--detector", default="kgnv2")
    pback.add_argument("--rounds", type=_int_at_least(1), default=3)
    pback.add_argument("--address", help="a running Ray head to time as well, e.g. 127.0.0.1:6411")
    pback.add_argument("--trials", type=_int_at_least(1), help="trials per object (default: the task's)")
    pback.set_defaults(func=_cmd_perf_backends)
    pker = psub.add_parser("kernels", help="which library's CPU dispatch changes images, detections and records, "
                           "and the portable kernel set's cost (one process a variant)")
    pker.add_argument("--records", action="store_true",
                      help="also compare the records of the CI regression tasks (about 1 min a variant)")
    pker.set_defaults(func=_cmd_perf_kernels)


def _add_closed_loop(sub) -> None:
    detector_help = "kgnv2, kgn, kgn_depth, antipodal, random, oracle, ... or module:attribute for your own"
    one_task = _parent(_task, _overrides, _workers(1, cluster=True), _settings("the task"), _cluster, _quiet)
    run = sub.add_parser("run", help="run a closed-loop benchmark task (resumes an interrupted run)",
                         parents=[one_task])
    run.add_argument("--detector", required=True, help=detector_help)
    run.add_argument("--record", action="store_true", help="write a rerun recording (recording.rrd)")
    run.add_argument("--out", type=Path, help="run folder (default runs/<task>_<detector>_seed<seed>)")
    run.set_defaults(func=_cmd_run)
    sw = sub.add_parser("sweep", help="run one task at several values of one setting (e.g. depth noise)",
                        parents=[one_task])
    sw.add_argument("--detector", required=True, nargs="+",
                    help=detector_help + "; several give one sweep each, side by side (a viewpoint study with a "
                                         "camera.* setting)")
    sw.add_argument("--param", required=True, help="setting to sweep, e.g. camera.depth_noise or camera.elevation_deg")
    sw.add_argument("--values", nargs="+", required=True, help="values, e.g. 0 0.5 1 2")
    sw.add_argument("--out", type=Path, help="sweep folder (default runs/sweep_<task>_<detector>_<param>)")
    sw.set_defaults(func=_cmd_sweep)
    bm = sub.add_parser("benchmark", help="run every task x detector of a plan, then write the report",
                        parents=[_parent(_workers(2, cluster=True), _settings("every task"), _cluster, _quiet)])
    bm.add_argument("plan", type=Path, nargs="?", default=Path("benchmark"),
                    help="plan file, or a bundled plan's name (default: the bundled benchmark plan)")
    bm.add_argument("--tasks", nargs="+", help="only these tasks of the plan")
    bm.add_argument("--detectors", nargs="+", help="only these detectors of the plan")
    bm.add_argument("--runs", type=Path, default=Path("runs/benchmark"), help="run folders (default runs/benchmark)")
    bm.add_argument("--out", type=Path, help="report folder (default: the runs folder)")
    bm.add_argument("--no-viewpoints", action="store_true",
                    help="skip the plan's viewpoint studies (camera sweeps; RUNS/viewpoints)")
    bm.set_defaults(func=_cmd_benchmark)
    rep = sub.add_parser("report", help="the benchmark table, failure reasons and bar chart from run folders "
                         "or results bundles (Markdown, JSON, PNG and an HTML page)")
    rep.add_argument("runs", type=Path, nargs="+",
                     help="run folders or results bundles, or folders holding them")
    rep.add_argument("--out", type=Path, default=Path("results"), help="report folder (default results)")
    rep.set_defaults(func=_cmd_report)
    exp = sub.add_parser("export", help="results bundles to publish: one folder per detector (summaries, a CSV of "
                         "every attempt, task configs and their hashes, the environment, the detector's card)")
    exp.add_argument("runs", type=Path, nargs="+", help="finished run folders, or folders holding them")
    exp.add_argument("--out", type=Path, required=True, help="folder to write the bundles into")
    exp.add_argument("--overwrite", action="store_true", help="replace bundles of the same detectors")
    exp.set_defaults(func=_cmd_export)
    check = sub.add_parser("check", help="fail (exit 1) when a run's rates dropped below a baseline's")
    check.add_argument("run", type=Path, help="run folder holding summary.json")
    check.add_argument("--baseline", type=Path, required=True, help="baseline JSON")
    check.add_argument("--update-baseline", action="store_true",
                       help="write the run's rates and fingerprint as its detector's baseline")
    check.add_argument("--against", metavar="DETECTOR",
                       help="compare with this detector's baseline instead of the run's own (statistical test)")
    check.set_defaults(func=_cmd_check)
    replay = sub.add_parser("replay", help="open a run's rerun recording, serve it to a browser, or save a copy")
    replay.add_argument("run", type=Path, help="run folder or .rrd file")
    replay.add_argument("--save", type=Path, help="copy the recording here instead of opening the viewer")
    replay.add_argument("--still", type=Path, metavar="PNG",
                        help="write one attempt's camera image with its candidates and executed grasp drawn on it "
                             "(no viewer needed)")
    replay.add_argument("--trial", type=_int_at_least(0), default=0, help="with --still: the trial (default 0)")
    replay.add_argument("--attempt", type=_int_at_least(1), default=1,
                        help="with --still: the attempt, counted from 1 (default 1)")
    replay.add_argument("--web", action="store_true",
                        help="serve the recording and rerun's web viewer on localhost (for a headless server: "
                             "open the printed URL, e.g. through SSH port forwarding); Ctrl-C stops it")
    replay.add_argument("--port", type=_int_at_least(1, 65534), default=9090,
                        help="web viewer port (default 9090; the recording is served on the next port)")
    replay.set_defaults(func=_cmd_replay)


def _add_learning(sub) -> None:
    tr = sub.add_parser("train", help="train a KGN / KGNv2 model from a config (resumes an interrupted run)",
                        parents=[_parent(_quiet)])
    tr.add_argument("config", type=Path, help="training config (tasks/train_*.toml, or its bundled name)")
    tr.add_argument("--device", help="torch device (default: cuda when present, else cpu)")
    tr.add_argument("--threads", type=_int_at_least(1), help="CPU threads for torch (default: all cores)")
    tr.set_defaults(func=_cmd_train)
    ex = sub.add_parser("ship", help="ship a trained checkpoint as weights with a model card")
    ex.add_argument("checkpoint", type=Path, help="a training run's final.pt (or last.pt)")
    ex.add_argument("--name", required=True, help="weights name (kgnv2, kgn, ...)")
    ex.add_argument("--out", type=Path, default=Path("assets/weights"),
                    help="folder (default assets/weights: the shipped weights, run from the repository)")
    ex.set_defaults(func=_cmd_ship)
    ev = sub.add_parser("eval", help="evaluate detectors")
    esub = ev.add_subparsers(dest="eval_command", required=True, parser_class=_Parser)
    vis = esub.add_parser("vision", help="GSR / GCR / OSR on a PS dataset split",
                          parents=[_parent(_weights, _split, _quiet)])
    vis.add_argument("--out", type=Path, help="folder for vision.json and vision.md")
    vis.set_defaults(func=_cmd_eval_vision)
    err = esub.add_parser("errors", help="split each prediction's error into centre, ray distance, rotation, width",
                          parents=[_parent(_weights, _split, _quiet)])
    err.add_argument("--out", type=Path, help="folder for errors.json, errors.md and errors.png (CDF plots)")
    err.set_defaults(func=_cmd_eval_errors)
    phy = esub.add_parser("physics", help="share of the top predictions that hold the object in the physics check",
                          parents=[_parent(_weights, _split, _quiet)])
    phy.add_argument("--top", type=_int_at_least(1), default=10, help="predictions per view checked (default 10)")
    phy.add_argument("--out", type=Path, help="folder for physics.json and physics.md")
    phy.set_defaults(func=_cmd_eval_physics)
    shw = esub.add_parser("show", help="draw a detector's keypoint boxes beside the ground truth of one view",
                          parents=[_parent(_weights)])
    shw.add_argument("--data", type=Path, required=True)
    shw.add_argument("--scene", type=_int_at_least(0), required=True)
    shw.add_argument("--view", type=_int_at_least(0), default=0)
    shw.add_argument("--out", type=Path, required=True, help="PNG to write")
    shw.set_defaults(func=_cmd_eval_show)
    etr = esub.add_parser("trial", help="why a closed-loop attempt went as it did: its capture re-created, the "
                          "chosen grasp's error against the true grasps (centre, ray distance, rotation, width)")
    etr.add_argument("run", type=Path, help="a run folder (with run.json and trials.jsonl)")
    etr.add_argument("--trial", type=_int_at_least(0), required=True, help="the trial's index")
    etr.add_argument("--attempt", type=_int_at_least(1), default=1,
                     help="which attempt of a clearance round (default 1; the earlier ones are executed again)")
    etr.add_argument("--out", type=Path, help="folder for explain.json, explain.md and explain.png "
                     "(default RUN/explain/trial_NNNNN_attempt_K)")
    etr.add_argument("--detector", help="required for a run of a module:attribute detector, and must be the one it "
                                        "ran (a run folder names no code to import by itself)")
    etr.set_defaults(func=_cmd_eval_trial)
    efl = esub.add_parser("failures", help="every failed attempt of a run explained like `eval trial`, counted by "
                          "what failed (rotation, scale, centre, width, the selector, the execution)",
                          parents=[_parent(_quiet)])
    efl.add_argument("run", type=Path, help="a run folder (with run.json and trials.jsonl)")
    efl.add_argument("--out", type=Path, help="folder for failures.json and failures.md (default RUN/explain)")
    efl.add_argument("--detector", help="required for a run of a module:attribute detector, and must be the one it "
                                        "ran (a run folder names no code to import by itself)")
    efl.set_defaults(func=_cmd_eval_failures)


def _add_studies(sub) -> None:
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


def _add_objects(sub) -> None:
    obj = sub.add_parser("objects", help="import meshes as benchmark objects, list and draw them")
    osub = obj.add_subparsers(dest="objects_command", required=True, parser_class=_Parser)
    add = osub.add_parser("add", help="import a mesh (OBJ, STL, PLY, GLB): repair, CoACD hulls, verified grasps")
    add.add_argument("mesh", type=Path, help="mesh file")
    add.add_argument("--name", required=True, help="object name used by task files (lower case, digits, _ -)")
    add.add_argument("--scale", type=float, help="multiply the coordinates by this (e.g. 0.001 for mm)")
    add.add_argument("--size", type=float, help="scale so that the largest extent is this many metres")
    add.add_argument("--density", type=float, default=700.0, help="kg/m³ for the mass (default 700, as VGN)")
    add.add_argument("--mass", type=float, help="mass in kg (instead of density × volume)")
    add.add_argument("--color", type=float, nargs=3, default=(0.7, 0.55, 0.35), metavar=("R", "G", "B"))
    add.add_argument("--hulls", type=_int_at_least(1), default=8, help="most convex pieces (CoACD; default 8)")
    add.add_argument("--verify", type=_int_at_least(8), default=160,
                     help="grasp candidates checked in physics (default 160)")
    add.add_argument("--seed", type=_int_at_least(0), default=0)
    add.add_argument("--licence", default="unknown", help="the mesh's licence, kept in the manifest")
    add.add_argument("--root", type=Path, help="object library to write to (default $KGN_BENCH_OBJECTS or "
                                               "~/.local/share/kgn-bench/objects)")
    add.add_argument("--overwrite", action="store_true", help="replace an object of the same name")
    add.set_defaults(func=_cmd_objects_add)
    ls = osub.add_parser("list", help="the built-in object types and the imported objects")
    ls.set_defaults(func=_cmd_objects_list)
    show = osub.add_parser("show", help="a PNG of an object with its grasps")
    show.add_argument("name")
    show.add_argument("--out", type=Path, required=True, help="PNG to write")
    show.add_argument("--grasps", type=_int_at_least(1), default=30, help="grasps drawn (default 30)")
    show.add_argument("--seed", type=_int_at_least(0), default=0, help="size draw of a built-in type")
    show.set_defaults(func=_cmd_objects_show)
    iset = osub.add_parser("import-set", help="import the real-object set from pybullet_data (cached)",
                           parents=[_parent(_workers(2), _quiet)])
    iset.add_argument("--split", choices=("test", "train"), default="test",
                      help="test: 40 of pybullet's test objects + duck, mug, teddy (default); train: 900")
    iset.set_defaults(func=_cmd_objects_import_set)
    chk = osub.add_parser("check-labeller", help="the mesh labeller against the primitives' closed-form grasps")
    chk.add_argument("--out", type=Path, default=Path("results/labeller"), help="folder for the table and PNGs")
    chk.add_argument("--shapes", nargs="+", help="primitives to check (default all)")
    chk.add_argument("--verify", type=_int_at_least(8), default=400, help="labeller candidates checked (400)")
    chk.add_argument("--control", type=_int_at_least(0), default=100, help="random control grasps (100)")
    chk.add_argument("--seed", type=_int_at_least(0), default=0)
    chk.set_defaults(func=_cmd_objects_check_labeller)


def build_parser() -> argparse.ArgumentParser:
    """The ``kgn-bench`` parser: one function per group of commands."""
    p = _Parser(prog="kgn-bench", description="KGNv2 grasp detection: dataset, training and closed-loop benchmark.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for add in (_add_data, _add_objects, _add_perf, _add_closed_loop, _add_learning, _add_studies):
        add(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one command. SIGTERM and SIGHUP stop it as Ctrl-C does (exit 128 + the signal, 130 for Ctrl-C),
    with its workers (``kgn_bench.lifecycle``). Every error a user can cause ends here as one line and exit
    status 2: the project's
    own (``KGNBenchError``), the operating system's (``OSError``: a path that cannot be read or written, a
    full disk) and bad argument values (``ValueError``). Status 1 is kept for ``check``'s regression."""
    from kgn_bench.errors import KGNBenchError
    from kgn_bench.lifecycle import Stopped, interrupts_as_keyboard

    args = build_parser().parse_args(argv)
    try:
        with interrupts_as_keyboard():  # SIGTERM and SIGHUP end a command as Ctrl-C does
            return int(args.func(args) or 0)
    except Stopped as e:
        sys.stderr.write(f"kgn-bench: {e}\n")
        return 128 + e.signum
    except KeyboardInterrupt:
        sys.stderr.write("kgn-bench: interrupted\n")
        return 130
    except KGNBenchError as e:
        return _fail(str(e).splitlines()[0] if str(e) else type(e).__name__)
    except OSError as e:
        reason = "disk full" if e.errno == errno.ENOSPC else (e.strerror or type(e).__name__)
        return _fail(f"{e.filename}: {reason}" if e.filename else reason)
    except ValueError as e:
        return _fail(str(e).splitlines()[0])
    finally:
        if "kgn_bench.cluster" in sys.modules:  # leave Ray now: its exit hook would first wait 0.5 s for logs
            sys.modules["kgn_bench.cluster"].shutdown()


if __name__ == "__main__":
    sys.exit(main())
