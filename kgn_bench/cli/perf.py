"""``kgn-bench perf``: speed measurements."""

from __future__ import annotations

from pathlib import Path

from .options import Parser, int_at_least, parent, task_argument, workers_option

__all__ = ["add"]


def add(sub) -> None:
    """The ``perf`` command group."""
    perf = sub.add_parser("perf", help="speed measurements")
    psub = perf.add_subparsers(dest="perf_command", required=True, parser_class=Parser)
    for add_command in (_add_data, _add_run, _add_detector, _add_train, _add_import, _add_backends, _add_kernels):
        add_command(psub)


def _add_data(psub) -> None:
    """``kgn-bench perf data``: its arguments."""
    pdata = psub.add_parser("data", help="dataset generation views/s and its split",
                            parents=[parent(workers_option(2))])
    pdata.add_argument("--scenes", type=int_at_least(1), default=20)
    pdata.add_argument("--mode", choices=("single", "multi"), default="multi")
    pdata.set_defaults(func=_cmd_perf_data)


def _cmd_perf_data(args) -> int:
    from kgn_bench.bench.perf import perf_data

    print(perf_data(scenes=args.scenes, workers=args.workers, mode=args.mode))
    return 0


def _add_run(psub) -> None:
    """``kgn-bench perf run``: its arguments."""
    prun = psub.add_parser("run", help="benchmark trials/min and the split (render, detect, select, simulate)",
                           parents=[parent(task_argument, workers_option(2))])
    prun.add_argument("--detector", default="oracle")
    prun.add_argument("--trials", type=int_at_least(1), default=2, help="trials per object (default 2)")
    prun.set_defaults(func=_cmd_perf_run)


def _cmd_perf_run(args) -> int:
    from kgn_bench.bench.perf import perf_run

    print(perf_run(args.task, detector=args.detector, trials=args.trials, workers=args.workers))
    return 0


def _add_detector(psub) -> None:
    """``kgn-bench perf detector``: its arguments."""
    pdet = psub.add_parser("detector", help="detector frames/s at 640×480 (learned ones: and the split)")
    pdet.add_argument("--variant", default="kgnv2", help="a learned variant or another detector, e.g. antipodal")
    pdet.add_argument("--weights", help="weights file or name under assets/weights (default: the shipped one)")
    pdet.add_argument("--frames", type=int_at_least(1), default=20)
    pdet.add_argument("--threads", type=int_at_least(1), default=2, help="torch threads (default 2)")
    pdet.add_argument("--data", type=Path, help="dataset whose test views to use (default: 4 generated scenes)")
    pdet.set_defaults(func=_cmd_perf_detector)


def _cmd_perf_detector(args) -> int:
    from kgn_bench.bench.perf import perf_detector

    print(perf_detector(args.variant, args.weights, frames=args.frames, threads=args.threads, data=args.data))
    return 0


def _add_train(psub) -> None:
    """``kgn-bench perf train``: its arguments."""
    ptrain = psub.add_parser("train", help="a KGN training step: batch preparation and the step, per output "
                                           "stride and forward precision (samples/s)")
    ptrain.add_argument("--data", type=Path, required=True, help="a PS dataset (its train split)")
    ptrain.add_argument("--variant", default="kgnv2")
    ptrain.add_argument("--strides", type=int, nargs="+", default=[4, 2], choices=(2, 4))
    ptrain.add_argument("--precisions", nargs="+", default=["float32", "bfloat16"], choices=("float32", "bfloat16"))
    ptrain.add_argument("--batches", type=int_at_least(2), default=6)
    ptrain.add_argument("--threads", type=int_at_least(1), default=1, help="torch threads (default 1)")
    ptrain.add_argument("--layouts", nargs="+", default=["contiguous", "channels-last"],
                        choices=("contiguous", "channels-last"), help="memory layouts to time (default both)")
    ptrain.set_defaults(func=_cmd_perf_train)


def _cmd_perf_train(args) -> int:
    from kgn_bench.bench.perf import perf_train

    print(perf_train(args.data, args.variant, tuple(args.strides), tuple(args.precisions), batches=args.batches,
                     threads=args.threads, layouts=tuple(layout == "channels-last" for layout in args.layouts)))
    return 0


def _add_import(psub) -> None:
    """``kgn-bench perf import``: its arguments."""
    pimp = psub.add_parser("import", help="seconds to import one mesh (objects add), and the split")
    pimp.add_argument("--mesh", type=Path, help="mesh file (default: a generated torus of --faces triangles)")
    pimp.add_argument("--faces", type=int_at_least(100), default=20_000)
    pimp.add_argument("--verify", type=int_at_least(8), default=160, help="grasps checked in physics (160)")
    pimp.set_defaults(func=_cmd_perf_import)


def _cmd_perf_import(args) -> int:
    from kgn_bench.bench.perf import perf_import

    print(perf_import(args.mesh, faces=args.faces, verify=args.verify))
    return 0


def _add_backends(psub) -> None:
    """``kgn-bench perf backends``: its arguments."""
    pback = psub.add_parser("backends", help="Ray's overhead against the local pool: `run` start to exit on each, "
                            "in turn", parents=[parent(task_argument, workers_option(2))])
    pback.add_argument("--detector", default="kgnv2")
    pback.add_argument("--rounds", type=int_at_least(1), default=3)
    pback.add_argument("--address", help="a running Ray head to time as well, e.g. 127.0.0.1:6411")
    pback.add_argument("--trials", type=int_at_least(1), help="trials per object (default: the task's)")
    pback.set_defaults(func=_cmd_perf_backends)


def _cmd_perf_backends(args) -> int:
    from kgn_bench.bench.perf import perf_backends

    print(perf_backends(args.task, detector=args.detector, workers=args.workers, rounds=args.rounds,
                        address=args.address, trials=args.trials))
    return 0


def _add_kernels(psub) -> None:
    """``kgn-bench perf kernels``: its arguments."""
    pker = psub.add_parser("kernels", help="which library's CPU dispatch changes images, detections and records, "
                           "and the portable kernel set's cost (one process a variant)")
    pker.add_argument("--records", action="store_true",
                      help="also compare the records of the CI regression tasks (about 1 min a variant)")
    pker.set_defaults(func=_cmd_perf_kernels)


def _cmd_perf_kernels(args) -> int:
    from kgn_bench.bench.kernel_study import study

    print(study(records=args.records))
    return 0
