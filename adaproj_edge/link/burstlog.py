"""Logging for problems that come in bursts: a noisy line, a client sending garbage.

A burst is a run of problems with no success in between. The first few of a burst are
logged at WARNING, the rest at DEBUG and counted; when the next success ends the
burst, one line summarises it (how many, by reason), and a burst that goes on is
summarised every ``every`` problems. Counting, not a clock, decides what is logged, so
a replay logs the same lines as the live run.
"""

from __future__ import annotations

import logging
from collections import Counter


class BurstLog:
    """Rate-limited, summarised warnings for one kind of problem.

    Parameters
    ----------
    log : logging.Logger
        Where the lines go.
    what : str
        The problem in the plural, for summaries (``"bad SMP frames dropped"``).
    first : int
        Problems of a burst logged one by one at WARNING.
    every : int
        A burst still going on is summarised every ``every`` problems.

    Examples
    --------
    >>> burst = BurstLog(logging.getLogger("demo"), "bad frames dropped", first=1)
    >>> for _ in range(5):
    ...     burst.bad("bad CRC", "dropped a frame: bad CRC")
    >>> burst.reasons
    Counter({'bad CRC': 5})
    >>> burst.ok()
    >>> burst.reasons
    Counter()
    """

    def __init__(
        self, log: logging.Logger, what: str, *, first: int = 3, every: int = 1000
    ) -> None:
        if first < 1 or every < 1:
            raise ValueError("first and every must be at least 1")
        self.log = log
        self.what = what
        self.first = first
        self.every = every
        self.reasons: Counter[str] = Counter()

    def bad(self, reason: str, message: str, *args: object) -> None:
        """One problem: logged at WARNING if among the burst's first, else at DEBUG."""
        self.reasons[reason] += 1
        n = self.reasons.total()
        if n < self.first:
            self.log.warning(message, *args)
        elif n == self.first:
            self.log.warning(message + " (more of these are summarised)", *args)
        else:
            self.log.debug(message, *args)
        if n % self.every == 0:
            self.log.warning("%d %s so far, and going on: %s", n, self.what, self._by_reason())

    def ok(self) -> None:
        """A success: ends the burst, with a summary if some of it was not logged."""
        n = self.reasons.total()
        if n > self.first:
            self.log.warning("%d %s before this good one: %s", n, self.what, self._by_reason())
        self.reasons.clear()

    def _by_reason(self) -> str:
        return ", ".join(f"{reason} {k}" for reason, k in self.reasons.most_common())
