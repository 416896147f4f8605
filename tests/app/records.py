"""Feeding a list of simulated records to a runtime on a virtual clock, as a replay does."""

from __future__ import annotations

from adaproj_edge.app.inputs import RECORDED, feed
from adaproj_edge.app.runtime import Runtime
from adaproj_edge.hal.clock import VirtualClock


def feed_records(rt: Runtime, clock: VirtualClock, records: list[object]) -> None:
    """Each sensor record at its receive time, the runtime ticked before it."""
    for r in records:
        if isinstance(r, RECORDED):
            clock.advance_to(r.receive_ns)
            rt.tick()
            feed(rt, r)
