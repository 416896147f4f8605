"""Progress lines for work that takes more than a few seconds.

A :class:`Progress` logs "WHAT: k of n (p %)" at most every few seconds of the wall
clock, and nothing at all for work that ends sooner: fast runs stay quiet, long ones
show they are moving. It only reports; what is computed never depends on it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable


class Progress:
    """Reports ``done`` of ``total`` steps to a logger, at most every ``every_s``.

    Parameters
    ----------
    what : str
        What is counted ("depth frames simulated").
    total : int
        Steps in all.
    log : logging.Logger
        Where the lines go (level INFO).
    every_s : float
        Least wall-clock time between two lines; the first comes after it too.
    clock : callable, optional
        Seconds, monotonic (default :func:`time.monotonic`).
    """

    def __init__(
        self,
        what: str,
        total: int,
        log: logging.Logger,
        every_s: float = 3.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.what = what
        self.total = total
        self.log = log
        self.every_s = every_s
        self.clock = clock
        self._next = clock() + every_s

    def step(self, done: int) -> None:
        """Record that ``done`` steps are finished; log a line when one is due."""
        now = self.clock()
        if now >= self._next and self.total > 0:
            self._next = now + self.every_s
            pct = 100.0 * done / self.total
            self.log.info("%s: %d of %d (%.0f %%)", self.what, done, self.total, pct)
