"""Logging for problems that come in bursts: a noisy line, a client sending garbage.

A burst is a run of problems with no success in between. The first few of a burst are
logged at WARNING, the rest at DEBUG and counted; when the next success ends the
burst, one line summarises it (how many, by reason), and a burst that goes on is
summarised every ``every`` problems. Counting, not a clock, decides what is logged, so
a replay logs the same lines as the live run. Whatever a host sends, a burst holds a
few counters (at most ``kinds`` reasons one by one), takes constant time per problem,
and logs lines of bounded length.
"""

from __future__ import annotations

import logging
from collections import Counter

KINDS = 8
"""Reasons a burst counts one by one; the rest are counted together as "other"."""
REASON_CHARS = 80
"""Longest reason kept (a reason is a short key: "bad CRC", "8/0 rc 3")."""
LINE_CHARS = 300
"""Longest problem line logged (the message of one problem, cut)."""
OTHER = "other"


class BurstLog:
    """Rate-limited, summarised warnings for one kind of problem.

    Memory and time per problem are bounded whatever comes: at most ``kinds`` reasons
    are counted one by one (later reasons go to :data:`OTHER`), a running total is
    kept, and every line is cut to :data:`LINE_CHARS`.

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
    kinds : int
        Reasons counted one by one.

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
        self,
        log: logging.Logger,
        what: str,
        *,
        first: int = 3,
        every: int = 1000,
        kinds: int = KINDS,
    ) -> None:
        if first < 1 or every < 1 or kinds < 1:
            raise ValueError("first, every and kinds must be at least 1")
        self.log = log
        self.what = what
        self.first = first
        self.every = every
        self.kinds = kinds
        self.reasons: Counter[str] = Counter()
        self.count = 0

    def bad(self, reason: str, message: str, *args: object) -> None:
        """One problem: logged at WARNING if among the burst's first, else at DEBUG."""
        reason = reason[:REASON_CHARS]
        if reason not in self.reasons and len(self.reasons) >= self.kinds:
            reason = OTHER
        self.reasons[reason] += 1
        self.count += 1
        n = self.count
        if n < self.first:
            self.log.warning("%s", _line(message, args))
        elif n == self.first:
            self.log.warning("%s (more of these are summarised)", _line(message, args))
        elif self.log.isEnabledFor(logging.DEBUG):
            self.log.debug("%s", _line(message, args))
        if n % self.every == 0:
            self.log.warning("%d %s so far, and going on: %s", n, self.what, self._by_reason())

    def ok(self) -> None:
        """A success: ends the burst, with a summary if some of it was not logged."""
        if self.count > self.first:
            self.log.warning(
                "%d %s before this good one: %s", self.count, self.what, self._by_reason()
            )
        self.reasons.clear()
        self.count = 0

    def _by_reason(self) -> str:
        return ", ".join(f"{reason} {k}" for reason, k in self.reasons.most_common())


def _line(message: str, args: tuple[object, ...]) -> str:
    text = message % args if args else message
    return text if len(text) <= LINE_CHARS else text[: LINE_CHARS - 3] + "..."
