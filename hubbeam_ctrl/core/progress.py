"""A minimal progress line on stderr for sweeps, batches and long runs."""

from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


class Progress:
    """Print ``label: k/total (pct) elapsed`` on stderr, at most every ``every_s`` seconds.

    Parameters
    ----------
    total : int
        Number of work units.
    label : str
    enabled : bool
        Print nothing when False.
    every_s : float
        Minimum time between two lines [s].
    """

    def __init__(self, total: int, label: str, enabled: bool = True, every_s: float = 1.0):
        self.total, self.label, self.enabled, self.every_s = max(int(total), 1), label, enabled, every_s
        self.start = time.perf_counter()
        self._last = -1e9
        self.done = 0

    def update(self, done: int) -> None:
        """Record that ``done`` units are finished."""
        self.done = done
        now = time.perf_counter()
        if self.enabled and (now - self._last >= self.every_s or done >= self.total):
            self._last = now
            pct = 100.0 * done / self.total
            print(f"{self.label}: {done}/{self.total} ({pct:.0f} %) {now - self.start:.1f} s",
                  file=sys.stderr, flush=True)

    def close(self) -> None:
        """Finish (prints the final line if it was not printed)."""
        if self.enabled and self.done < self.total:
            print(f"{self.label}: stopped at {self.done}/{self.total}", file=sys.stderr, flush=True)
