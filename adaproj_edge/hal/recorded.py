"""A replayed stream of records: the common core of every replay device."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Generic, Protocol, TypeVar

from adaproj_edge.hal.clock import VirtualClock


class Received(Protocol):
    """A record that knows when it was received."""

    @property
    def receive_ns(self) -> int:
        """When the record was received (ns, the receiver's monotonic clock)."""
        ...


R = TypeVar("R", bound=Received)


class ReplayStream(Generic[R]):
    """Hands out recorded records in order, moving a virtual clock to each one's
    receive time. Nothing waits on wall-clock time: the next record is there as soon
    as the consumer asks for it.
    """

    def __init__(self, records: Iterable[R], clock: VirtualClock) -> None:
        self._it: Iterator[R] = iter(records)
        self.clock = clock

    def next(self) -> R | None:
        """The next record, or None at the end of the recording."""
        rec = next(self._it, None)
        if rec is not None:
            self.clock.advance_to(rec.receive_ns)
        return rec
