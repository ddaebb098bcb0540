"""The ``kgn-bench`` command: the top parser built from the command groups, and ``main``."""

from __future__ import annotations

import argparse
import sys

from . import benchmark, data, evaluation, objects, perf, replay, run, studies, train
from .common import fail
from .options import Parser

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The ``kgn-bench`` parser: one function per group of commands."""
    p = Parser(prog="kgn-bench", description="KGNv2 grasp detection: dataset, training and closed-loop benchmark.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    for group in (data, objects, perf, run, benchmark, replay, train, evaluation, studies):
        group.add(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run one command. SIGTERM and SIGHUP stop it as Ctrl-C does (exit 128 + the signal, 130 for Ctrl-C),
    with its workers (``kgn_bench.lifecycle``). Every error a user can cause is a ``KGNBenchError``
    (``kgn_bench.errors``) and ends here as one line and exit status 2; any other exception is a defect of
    the project and goes through with its traceback (exit status 1, Python's). Status 1 is also ``check``'s
    regression."""
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
        return fail(str(e).splitlines()[0] if str(e) else type(e).__name__)
    finally:
        if "kgn_bench.cluster" in sys.modules:  # leave Ray now: its exit hook would first wait 0.5 s for logs
            sys.modules["kgn_bench.cluster"].shutdown()
