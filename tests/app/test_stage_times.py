"""The runtime's stage times read the clock they are given (benchmarks: CPU time)."""

from __future__ import annotations

from adaproj_edge.app.telemetry import StageTimes


def test_stage_times_read_the_given_clock() -> None:
    ticks = iter([1.0, 1.25, 2.0, 2.5])  # seconds on a fake clock
    times = StageTimes(clock=lambda: next(ticks))
    with times.timer("solve"):
        pass
    t0 = times.now()
    times.add("update", times.now() - t0)
    summary = times.summary()
    # exact: each sample is the difference of two readings a quarter/half apart (binary)
    assert summary["solve"]["median_ms"] == 250.0
    assert summary["update"]["median_ms"] == 500.0
