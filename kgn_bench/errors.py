"""The one exception base of the project.

Every error that a user can cause (a bad file, a bad setting, an unusable folder, a corrupt checkpoint)
is a ``KGNBenchError``, or a subclass of it defined next to the code that raises it. Its message is one
line that names the problem; the command line prints ``kgn-bench: error: <message>`` and exits with 2.
"""

from __future__ import annotations

__all__ = ["KGNBenchError", "OutputError"]


class KGNBenchError(Exception):
    """Base of every error the project raises on purpose; ``str(e)`` is one line naming the problem."""


class OutputError(KGNBenchError, OSError):
    """A file or folder that cannot be written (read-only, not a folder, disk full)."""
