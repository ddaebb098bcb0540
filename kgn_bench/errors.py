"""The one exception base of the project.

Every error that a user can cause (a bad file, a bad setting, an unusable folder, a corrupt checkpoint)
is a ``KGNBenchError``, or a subclass of it defined next to the code that raises it (``InputError`` where
that module has none). Its message is one line that names the problem; the command line prints
``kgn-bench: error: <message>`` and exits with 2. Every other exception is a defect of the project: the
command line lets it through with its traceback. A bare ``ValueError`` therefore means a bug (a function
called with arguments its caller should never have passed), never a user's mistake.
"""

from __future__ import annotations

import sys

__all__ = ["InputError", "KGNBenchError", "OutputError", "warn"]


def warn(message: str) -> None:
    """Print ``kgn-bench: warning: <message>`` as one line on stderr: something the user should know that does
    not stop the command (the error's counterpart, for any layer)."""
    sys.stderr.write(f"kgn-bench: warning: {message}\n")


class KGNBenchError(Exception):
    """Base of every error the project raises on purpose; ``str(e)`` is one line naming the problem."""


class OutputError(KGNBenchError, OSError):
    """A file or folder that cannot be written (read-only, not a folder, disk full). Also an ``OSError``, so
    that code written against the operating system's error (``except OSError``) still sees it."""


class InputError(KGNBenchError, ValueError):
    """A bad value the user gave (a command-line option, a setting, a name that names nothing) where the module
    that refuses it has no error class of its own. Also a ``ValueError``: callers that re-word the
    ``ValueError`` of a function they call with their own context (``config.parse_section``, the checkpoint
    and training-config readers, the benchmark plan) keep doing so."""
