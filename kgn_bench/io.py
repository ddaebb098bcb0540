"""Files: atomic writes, output-folder checks and one-line messages for operating-system errors.

Every result the project writes goes through ``atomic_write``: the bytes go to a temporary file beside
the target, are fsynced, and the temporary file is renamed over the target, so a reader (or a rerun after
a kill) sees the old file or the whole new one, never a part; a stop signal (Ctrl-C, SIGTERM, SIGHUP) that
comes during the write takes effect right after it (``lifecycle.deferred_stop``). ``OSError`` from the
operating system (a read-only folder, a full disk) becomes an ``OutputError`` whose one-line message names
the path.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from kgn_bench.errors import OutputError
from kgn_bench.lifecycle import deferred_stop

__all__ = ["atomic_write", "atomic_write_text", "check_writable_dir", "describe_os_error"]


def describe_os_error(e: OSError, path: str | os.PathLike[str] | None = None) -> str:
    """One line for ``e``: the path it concerns and the reason (``disk full`` for ENOSPC)."""
    where = path if path is not None else (e.filename or "a file")
    reason = "disk full" if e.errno == errno.ENOSPC else (e.strerror or type(e).__name__)
    return f"cannot write {where}: {reason}"


def atomic_write(path: str | os.PathLike[str], write: Callable[[BinaryIO], None]) -> None:
    """Call ``write`` on a temporary file beside ``path``, fsync it and rename it into place (mode 0644,
    like a plain ``open``). ``OutputError`` naming ``path`` if the operating system refuses; the target is
    then untouched and no temporary file is left."""
    path = Path(path)
    with deferred_stop():
        _write_and_rename(path, write)


def _write_and_rename(path: Path, write: Callable[[BinaryIO], None]) -> None:
    tmp: str | None = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp creates 0600
        os.replace(tmp, path)
        tmp = None
    except OSError as e:
        raise OutputError(describe_os_error(e, path)) from None
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (``atomic_write``)."""
    atomic_write(path, lambda f: f.write(text.encode()))


def check_writable_dir(path: str | os.PathLike[str], what: str = "output folder") -> Path:
    """Check, before any work is done and without creating anything, that the folder ``path`` exists or
    can be created and that files can be written in it: the nearest existing folder on its way is probed
    with a temporary file (removed at once). ``OutputError`` with one line if ``path`` (or a folder on its
    way) is a file, or is not writable."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{what} {path} is a file, not a folder")
    existing = path.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise OutputError(f"{what} {path}: {existing} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".kgn-bench-probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        reason = "disk full" if e.errno == errno.ENOSPC else (e.strerror or type(e).__name__)
        raise OutputError(f"{what} {path} is not writable: {reason}") from None
    return path
