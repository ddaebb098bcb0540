"""A minimal progress line on stderr (a carriage-return bar on a terminal, sparse lines otherwise)."""

from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


class Progress:
    """``done/total``, rate and ETA for a loop; ``update(n, extra)`` after each finished item."""

    def __init__(self, total: int, label: str, unit: str = "it", stream=None, enabled: bool = True) -> None:
        self.total, self.label, self.unit = total, label, unit
        self.stream = stream or sys.stderr
        self.enabled = enabled and total > 0
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = 0
        self.start = time.perf_counter()
        self._last_print = 0.0

    def update(self, n: int = 1, extra: str = "") -> None:
        self.done += n
        if not self.enabled:
            return
        now = time.perf_counter()
        final = self.done >= self.total
        if not final and now - self._last_print < (0.2 if self.tty else 10.0):
            return
        self._last_print = now
        elapsed = now - self.start
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        width = 24
        filled = int(width * self.done / self.total)
        bar = "#" * filled + "-" * (width - filled)
        line = (f"{self.label} [{bar}] {self.done}/{self.total} {rate:.2f} {self.unit}/s "
                f"elapsed {elapsed:.0f}s eta {eta:.0f}s {extra}")
        if self.tty:
            self.stream.write("\r" + line + ("\n" if final else ""))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()
