"""What the command handlers share: one-line errors and warnings, the pool backend of the cluster options,
output checks made before any work, and ``--set`` overrides."""

from __future__ import annotations

import sys
from pathlib import Path

from kgn_bench.errors import warn

__all__ = ["apply_settings", "check_workers", "fail", "make_backend", "setting_pairs", "warn", "writable",
           "writable_file"]


def fail(message: str) -> int:
    """Print ``kgn-bench: error: <message>`` as one line; returns the exit status of a user error, 2."""
    sys.stderr.write(f"kgn-bench: error: {message}\n")
    return 2


def make_backend(args):
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
    check_workers(args.workers, args.backend)
    return backend


def check_workers(workers: int, backend: str = "local") -> None:
    """Warn when more worker processes are asked for than there are cores (they would only queue); on Ray,
    ``--workers`` is the number of jobs in flight on the cluster, whose cores are not this machine's."""
    from kgn_bench.threads import available_cores

    if backend != "local":
        return
    cores = available_cores()
    if workers > cores:
        warn(f"--workers {workers} is more than the {cores} core(s) of this machine; trials will queue "
              f"and run slower than with --workers {cores}")


def writable(path: Path | None, what: str = "output folder") -> None:
    if path is not None:
        from kgn_bench.io import check_writable_dir

        check_writable_dir(path, what)


def writable_file(path: Path, what: str) -> None:
    """Check before any work that ``path`` can be written as a file (its folder exists or can be made)."""
    from kgn_bench.errors import OutputError

    if path.is_dir():
        raise OutputError(f"{what} {path} is a folder, not a file")
    writable(path.parent if str(path.parent) else Path("."), f"folder of {what}")


def setting_pairs(settings: list[str] | None, error: type[Exception] | None = None) -> list[tuple[str, str]]:
    """``(key, value)`` of each ``section.name=value`` given to ``--set``; ``error`` (default ``ConfigError``)
    for one without ``=``."""
    from kgn_bench.config import ConfigError

    pairs = []
    for setting in settings or ():
        key, sep, value = setting.partition("=")
        if not sep:
            raise (error or ConfigError)(f"--set {setting!r}: expected section.name=value")
        pairs.append((key.strip(), value.strip()))
    return pairs


def apply_settings(task, settings: list[str] | None):
    """``task`` with each ``section.name=value`` of ``--set`` applied (``ConfigError`` names a bad one)."""
    from kgn_bench.config import apply_overrides

    return apply_overrides(task, setting_pairs(settings))
