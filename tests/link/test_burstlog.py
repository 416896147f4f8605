"""Bursts of problems: the first few logged, the rest counted and summarised."""

from __future__ import annotations

import logging

import pytest

from adaproj_edge.link.burstlog import BurstLog

LOG = logging.getLogger("tests.burst")


def warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


def test_a_long_burst_is_summarised_as_it_goes(caplog: pytest.LogCaptureFixture) -> None:
    burst = BurstLog(LOG, "bad things", first=2, every=10)
    with caplog.at_level(logging.DEBUG, logger="tests.burst"):
        for i in range(25):
            burst.bad("odd" if i % 2 else "even", "bad thing %d", i)
        burst.ok()
    assert warnings(caplog) == [
        "bad thing 0",
        "bad thing 1 (more of these are summarised)",
        "10 bad things so far, and going on: even 5, odd 5",
        "20 bad things so far, and going on: even 10, odd 10",
        "25 bad things before this good one: even 13, odd 12",
    ]
    debug = [r for r in caplog.records if r.levelno == logging.DEBUG]
    assert len(debug) == 23  # every one is still there at DEBUG


def test_a_short_burst_needs_no_summary(caplog: pytest.LogCaptureFixture) -> None:
    burst = BurstLog(LOG, "bad things", first=3)
    with caplog.at_level(logging.WARNING, logger="tests.burst"):
        burst.bad("x", "one")
        burst.ok()
        burst.ok()
        burst.bad("x", "two")
    assert warnings(caplog) == ["one", "two"]


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError):
        BurstLog(LOG, "x", first=0)


def test_distinct_reasons_keep_memory_lines_and_time_bounded(
    caplog: pytest.LogCaptureFixture,
) -> None:
    burst = BurstLog(logging.getLogger("test.burst"), "requests refused")
    with caplog.at_level(logging.WARNING, logger="test.burst"):
        for i in range(30_000):
            burst.bad(f"{i % 65536}/{i // 256} rc 8", "refused %s: %s", i, "x" * 5000)
            assert len(burst.reasons) <= burst.kinds + 1
        burst.ok()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3 + 30 + 1  # the first three, one every 1000, the end
    assert max(map(len, lines)) < 1000 and sum(map(len, lines)) < 30_000
    assert lines[-1].startswith("30000 requests refused before this good one")
    assert "other 29992" in lines[-1]  # the first 8 reasons one by one
