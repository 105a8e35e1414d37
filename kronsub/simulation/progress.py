"""The progress bar of a run on standard error."""
from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


class Progress:
    """A progress bar on stderr for runs longer than a second, only on a terminal."""

    def __init__(self, total: float, enabled: bool | None = None):
        self.total = total
        self.start = time.perf_counter()
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False

    def update(self, t: float) -> None:
        if not self.enabled or time.perf_counter() - self.start < 1.0:
            return
        frac = min(1.0, t / self.total) if self.total > 0 else 1.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r[{bar:<30}] t = {t:.4g} / {self.total:.4g}")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")
