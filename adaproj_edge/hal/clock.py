"""Injected clocks: the real monotonic clock on the device, a virtual one in replay.

Everything that needs the time takes a :class:`Clock`; nothing reads the wall clock
directly, so a replay is deterministic and runs as fast as the pipeline consumes it.
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """A monotonic time source in integer nanoseconds."""

    def now_ns(self) -> int:
        """The current time in ns."""
        ...

    def sleep_until(self, t_ns: int) -> None:
        """Return once :meth:`now_ns` has reached ``t_ns``."""
        ...


class MonotonicClock:
    """The real clock: ``time.monotonic_ns`` (CLOCK_MONOTONIC, as input events use)."""

    def now_ns(self) -> int:
        """The current ``CLOCK_MONOTONIC`` time in ns."""
        return time.monotonic_ns()

    def sleep_until(self, t_ns: int) -> None:
        """Sleep until ``time.monotonic_ns()`` reaches ``t_ns``."""
        delay = t_ns - time.monotonic_ns()
        if delay > 0:
            time.sleep(delay / 1e9)


class VirtualClock:
    """A clock that only moves when told to; never goes backwards."""

    def __init__(self, start_ns: int = 0) -> None:
        self._t = int(start_ns)

    def now_ns(self) -> int:
        """The time the clock was last moved to (``start_ns`` until then), in ns."""
        return self._t

    def advance_to(self, t_ns: int) -> None:
        """Move to ``t_ns`` (no-op when it lies in the past)."""
        self._t = max(self._t, int(t_ns))

    def sleep_until(self, t_ns: int) -> None:
        """Move to ``t_ns`` at once (no-op when it lies in the past)."""
        self.advance_to(t_ns)
