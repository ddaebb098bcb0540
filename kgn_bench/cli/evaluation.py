"""``kgn-bench eval``: detectors on datasets (vision metrics, error split, physics check,
drawings) and closed-loop attempts explained."""

from __future__ import annotations

from pathlib import Path

from .common import writable, writable_file
from .options import Parser, int_at_least, parent, quiet_option, split_options, weights_options

__all__ = ["add"]


def add(sub) -> None:
    """The ``eval`` command group."""
    ev = sub.add_parser("eval", help="evaluate detectors")
    esub = ev.add_subparsers(dest="eval_command", required=True, parser_class=Parser)
    for add_command in (_add_vision, _add_errors, _add_physics, _add_show, _add_trial, _add_failures):
        add_command(esub)


def _add_vision(esub) -> None:
    """``kgn-bench eval vision``: its arguments."""
    vis = esub.add_parser("vision", help="GSR / GCR / OSR on a PS dataset split",
                          parents=[parent(weights_options, split_options, quiet_option)])
    vis.add_argument("--out", type=Path, help="folder for vision.json and vision.md")
    vis.set_defaults(func=_cmd_eval_vision)


def _cmd_eval_vision(args) -> int:
    import json

    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.vision import evaluate_dataset
    from kgn_bench.io import atomic_write_text

    writable(args.out)
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


def _add_errors(esub) -> None:
    """``kgn-bench eval errors``: its arguments."""
    err = esub.add_parser("errors", help="split each prediction's error into centre, ray distance, rotation, width",
                          parents=[parent(weights_options, split_options, quiet_option)])
    err.add_argument("--out", type=Path, help="folder for errors.json, errors.md and errors.png (CDF plots)")
    err.set_defaults(func=_cmd_eval_errors)


def _cmd_eval_errors(args) -> int:
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.errors import decompose_dataset, markdown, write_errors

    writable(args.out)
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


def _add_physics(esub) -> None:
    """``kgn-bench eval physics``: its arguments."""
    phy = esub.add_parser("physics", help="share of the top predictions that hold the object in the physics check",
                          parents=[parent(weights_options, split_options, quiet_option)])
    phy.add_argument("--top", type=int_at_least(1), default=10, help="predictions per view checked (default 10)")
    phy.add_argument("--out", type=Path, help="folder for physics.json and physics.md")
    phy.set_defaults(func=_cmd_eval_physics)


def _cmd_eval_physics(args) -> int:
    import json

    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.physics_check import physics_success, to_markdown
    from kgn_bench.io import atomic_write_text

    writable(args.out)
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


def _add_show(esub) -> None:
    """``kgn-bench eval show``: its arguments."""
    shw = esub.add_parser("show", help="draw a detector's keypoint boxes beside the ground truth of one view",
                          parents=[parent(weights_options)])
    shw.add_argument("--data", type=Path, required=True)
    shw.add_argument("--scene", type=int_at_least(0), required=True)
    shw.add_argument("--view", type=int_at_least(0), default=0)
    shw.add_argument("--out", type=Path, required=True, help="PNG to write")
    shw.set_defaults(func=_cmd_eval_show)


def _cmd_eval_show(args) -> int:
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.viz.draw import show_predictions
    from kgn_bench.viz.images import save_png

    writable_file(args.out, "image")
    detector = KGNDetector(args.variant, args.weights)
    save_png(args.out, show_predictions(detector, args.data, args.scene, args.view))
    print(f"wrote {args.out}")
    return 0


def _add_trial(esub) -> None:
    """``kgn-bench eval trial``: its arguments."""
    etr = esub.add_parser("trial", help="why a closed-loop attempt went as it did: its capture re-created, the "
                          "chosen grasp's error against the true grasps (centre, ray distance, rotation, width)")
    etr.add_argument("run", type=Path, help="a run folder (with run.json and trials.jsonl)")
    etr.add_argument("--trial", type=int_at_least(0), required=True, help="the trial's index")
    etr.add_argument("--attempt", type=int_at_least(1), default=1,
                     help="which attempt of a clearance round (default 1; the earlier ones are executed again)")
    etr.add_argument("--out", type=Path, help="folder for explain.json, explain.md and explain.png "
                     "(default RUN/explain/trial_NNNNN_attempt_K)")
    etr.add_argument("--detector", help="required for a run of a module:attribute detector, and must be the one it "
                                        "ran (a run folder names no code to import by itself)")
    etr.set_defaults(func=_cmd_eval_trial)


def _cmd_eval_trial(args) -> int:
    from kgn_bench.eval.explain import explain_trial, markdown, write_explanation

    out = args.out or args.run / "explain" / f"trial_{args.trial:05d}_attempt_{args.attempt}"
    writable(out, "explanation folder")
    x = explain_trial(args.run, args.trial, args.attempt, detector=args.detector)
    paths = write_explanation(x, out)
    print(markdown(x))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def _add_failures(esub) -> None:
    """``kgn-bench eval failures``: its arguments."""
    efl = esub.add_parser("failures", help="every failed attempt of a run explained like `eval trial`, counted by "
                          "what failed (rotation, scale, centre, width, the selector, the execution)",
                          parents=[parent(quiet_option)])
    efl.add_argument("run", type=Path, help="a run folder (with run.json and trials.jsonl)")
    efl.add_argument("--out", type=Path, help="folder for failures.json and failures.md (default RUN/explain)")
    efl.add_argument("--detector", help="required for a run of a module:attribute detector, and must be the one it "
                                        "ran (a run folder names no code to import by itself)")
    efl.set_defaults(func=_cmd_eval_failures)


def _cmd_eval_failures(args) -> int:
    from kgn_bench.eval.explain import explain_failures, failures_markdown, write_failures

    out = args.out or args.run / "explain"
    writable(out, "explanation folder")
    study = explain_failures(args.run, progress=not args.quiet, detector=args.detector)
    paths = write_failures(study, out)
    print(failures_markdown(study))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0
