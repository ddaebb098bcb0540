"""Progress bars: tqdm on stderr, with the running rates as its postfix.

On a terminal the bar redraws in place; when stderr is a file or a pipe (a log, CI) tqdm's redraws become
one line every ``LOG_INTERVAL`` seconds instead of carriage returns, so a log stays readable. A disabled bar
(``--quiet``) prints nothing.
"""

from __future__ import annotations

import sys
from typing import TextIO

from tqdm import tqdm

__all__ = ["LOG_INTERVAL", "Progress"]

LOG_INTERVAL = 10.0
"""Seconds between progress lines when stderr is not a terminal."""


class _Lines:
    """A stream for tqdm that turns each redraw (``\\r`` + status) into a line of its own."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace("\r", "")
        if text.strip():
            self.stream.write(text.rstrip("\n") + "\n")

    def flush(self) -> None:
        self.stream.flush()


class Progress:
    """A bar over ``total`` items; ``update(n, extra)`` after each finished item (``extra``: the running
    rates, shown as tqdm's postfix); ``close()`` (or the last item) ends it."""

    def __init__(self, total: int, label: str, unit: str = "it", stream: TextIO | None = None,
                 enabled: bool = True) -> None:
        stream = stream or sys.stderr
        tty = bool(getattr(stream, "isatty", lambda: False)())
        self.total = total
        self._bar = tqdm(total=total, desc=label, unit=unit, disable=not enabled or total <= 0,
                         file=stream if tty else _Lines(stream), mininterval=0.2 if tty else LOG_INTERVAL,
                         dynamic_ncols=tty, ncols=None if tty else 120, leave=True)
        self.done = 0

    def update(self, n: int = 1, extra: str = "") -> None:
        self.done += n
        if extra:
            self._bar.set_postfix_str(extra, refresh=False)
        self._bar.update(n)
        if self.done >= self.total:
            self.close()

    def close(self) -> None:
        self._bar.close()
