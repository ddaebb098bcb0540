"""Argument parsing pieces every command group shares: the one-line-error parser, integer bounds and the
parent parsers that hold the options several commands have in common."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["Parser", "cluster_options", "int_at_least", "override_options", "parent", "quiet_option", "settings_option",
           "split_options", "task_argument", "weights_options", "workers_option"]


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit 2."""

    def error(self, message: str):  # type: ignore[override]
        sys.stderr.write(f"kgn-bench: error: {message}\n")
        sys.exit(2)


def int_at_least(lo: int, hi: int | None = None):
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


def parent(*adders) -> argparse.ArgumentParser:
    parent = Parser(add_help=False)
    for add in adders:
        add(parent)
    return parent


def workers_option(default: int, cluster: bool = False):
    def add(p):
        if not cluster:
            p.add_argument("--workers", type=int_at_least(1), default=default,
                           help=f"worker processes (default {default})")
            return
        p.add_argument("--workers", type=int_at_least(1),
                       help=f"worker processes (default {default}); with --backend ray the jobs in flight on the "
                            "cluster (default: as many as its CPUs run at once)")
        p.set_defaults(local_workers=default)
    return add


def cluster_options(p):
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where jobs run: this machine's worker processes (default) or a Ray cluster "
                        "(pip install 'kgn-bench[ray]'; docs/cluster.md)")
    p.add_argument("--address", help="with --backend ray: the cluster to join, e.g. 10.0.0.1:6379 (default "
                                     "RAY_ADDRESS, else a local Ray on this machine's cores)")
    p.add_argument("--num-gpus", type=float, default=0.0,
                   help="with --backend ray: GPUs per job, e.g. 0.25 for four trials of a GPU detector per GPU "
                        "(default 0: CPU only)")


def quiet_option(p):
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def task_argument(p):
    p.add_argument("task", type=Path, help="task file, or a bundled task's name (single_object, ...)")


def override_options(p):
    p.add_argument("--trials", type=int_at_least(1),
                   help="override the task's [task] trials: per object for single_object tasks (6 objects x "
                        "N trials), scenes for multi_object tasks")
    p.add_argument("--seed", type=int_at_least(0), help="override the task's seed")


def settings_option(what: str):
    def add(p):
        p.add_argument("--set", action="append", metavar="SECTION.NAME=VALUE",
                       help=f"override one setting of {what}, e.g. camera.depth_noise=1 (repeatable)")
    return add


def weights_options(p):
    p.add_argument("--weights", required=True, help="weights file, or a name under assets/weights")
    p.add_argument("--variant", help="decoding variant (kgnv2, kgnv2_sbranch, kgn, kgn_depth; default: the "
                                     "variant the weights were trained as)")


def split_options(p):
    p.add_argument("--data", type=Path, required=True, help="dataset folder")
    p.add_argument("--split", default="test", choices=("train", "test"))
    p.add_argument("--views", type=int_at_least(1), help="evaluate only the first N views")
