"""What the runtime reports about itself: stage times, counters and a bounded history
(events, states, updates, motion-to-frame and motion-to-photon latencies) for status,
replays and benchmarks.

Stage times are wall-clock (``time.perf_counter``; benchmarks on a loaded machine read
the process's CPU time instead, :attr:`StageTimes.clock`) and only reported: no decision
depends on them, so a replay makes the same decisions whatever the machine's speed.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any

import numpy as np

from adaproj_edge.warp.warpmap import Warp

COUNTERS = (
    "content_free",
    "content_aware",
    "cache_hits",
    "cache_misses",
    "cache_rejected",
    "re_placed",
    "estimates",
    "skipped_frames",
    "frames_shown",
    "refreshes",
    "refresh_misses",
    "clip_frames",
    "clip_skipped",
    "clip_late",
    "clip_errors",
    # updates that went down the warp chain (adaproj_edge.warp.fallback), by the step
    # they ended at; last-good: nothing could be made, the last picture stayed
    "fallback_content-free",
    "fallback_repaired",
    "fallback_keystone",
    "fallback_last-good",
)


@dataclass
class StageTimes:
    """Seconds per stage: the last ``keep`` samples of each stage, read on ``clock``
    (wall-clock by default; ``time.process_time``: CPU seconds, what a stage costs on a
    core of its own whatever else runs on the machine)."""

    keep: int = 20000
    samples: dict[str, deque[float]] = field(default_factory=dict)
    clock: Callable[[], float] = time.perf_counter

    def now(self) -> float:
        """The stage clock's reading (seconds)."""
        return self.clock()

    def add(self, stage: str, seconds: float) -> None:
        """Record one sample of ``stage``."""
        if stage not in self.samples:
            self.samples[stage] = deque(maxlen=self.keep)
        self.samples[stage].append(seconds)

    def timer(self, stage: str) -> Timer:
        """A context manager that records the time spent inside it under ``stage``."""
        return Timer(self, stage)

    def summary(self) -> dict[str, dict[str, float]]:
        """Per stage: sample count, median and 95th percentile (milliseconds)."""
        out = {}
        for stage, xs in sorted(self.samples.items()):
            a = np.asarray(xs) * 1e3
            out[stage] = {
                "n": int(a.size),
                "median_ms": round(float(np.median(a)), 3),
                "p95_ms": round(float(np.percentile(a, 95)), 3),
            }
        return out


class Timer:
    """Times a ``with`` block into a :class:`StageTimes`."""

    def __init__(self, times: StageTimes, stage: str) -> None:
        self.times, self.stage = times, stage
        self.t0 = 0.0

    def __enter__(self) -> None:
        self.t0 = self.times.now()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.times.add(self.stage, self.times.now() - self.t0)


class Telemetry:
    """The runtime's counters, stage times and recent history (bounded: the device runs
    for days; ``history`` entries of each kind are kept)."""

    def __init__(self, history: int) -> None:
        self.times = StageTimes(history)
        self.counters: dict[str, int] = dict.fromkeys(COUNTERS, 0)
        self.events: deque[dict[str, Any]] = deque(maxlen=history)
        self.states: deque[tuple[int, str]] = deque(maxlen=history)
        self.updates: deque[dict[str, Any]] = deque(maxlen=history)
        self.latencies_ms: deque[float] = deque(maxlen=history)
        self.photon_ms: deque[float] = deque(maxlen=history)  # IMU sample -> display
        self.update_count = 0

    def count(self, name: str, n: int = 1) -> None:
        """Add ``n`` to counter ``name``."""
        self.counters[name] += n

    def event(self, t_ns: int, name: str, **detail: Any) -> None:
        """Record an event (gesture, fault, motion change, content) at ``t_ns``."""
        self.events.append({"t_ns": t_ns, "event": name, **detail})

    def update(self, t_ns: int, **detail: Any) -> None:
        """Record a warp update shown at ``t_ns``."""
        self.update_count += 1
        self.updates.append({"t_ns": t_ns, **detail})


def probes(warp: Warp) -> list[list[float] | None]:
    """``image_xy`` at five vertices (corners and centre), rounded; None where unknown."""
    r, c = warp.image_xy.shape[:2]
    out: list[list[float] | None] = []
    for i, j in ((0, 0), (0, c - 1), (r // 2, c // 2), (r - 1, 0), (r - 1, c - 1)):
        v = warp.image_xy[i, j]
        out.append(
            None if not np.isfinite(v).all() else [round(float(v[0]), 2), round(float(v[1]), 2)]
        )
    return out
