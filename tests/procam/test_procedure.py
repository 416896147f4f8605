"""The procedure's pieces: replayed patterns, a silent IMU, depth averaging, the checks
on captures, the motion check during a capture."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from adaproj_edge.errors import CalibrationError
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample, ReplayImu
from adaproj_edge.procam.procedure import (
    ImuLog,
    ProcedureSettings,
    ReplayShow,
    _average_depth,
    _capture_turn_deg,
    _check,
)
from adaproj_edge.procam.result import CalibrationResult
from adaproj_edge.session.codec import Record
from adaproj_edge.session.records import PatternShown


class Recorder:
    def __init__(self) -> None:
        self.records: list[Record] = []

    def say(self, event: str, message: str) -> None:
        pass

    def record(self, rec: Record) -> None:
        self.records.append(rec)


def test_replayed_patterns_set_the_clock_and_must_match() -> None:
    clock = VirtualClock()
    shown = iter([PatternShown(50, 0, 0, "black"), PatternShown(90, 0, 1, "white")])
    show = ReplayShow(shown, clock)
    frame = np.zeros((2, 2, 3), np.uint8)
    assert show.show(0, 0, "black", frame) == 50 and clock.now_ns() == 50
    with pytest.raises(CalibrationError, match="differs from the recording"):
        show.show(0, 2, "x0", frame)
    with pytest.raises(CalibrationError, match="ends before pattern"):
        show.show(0, 3, "x0-inv", frame)


def _samples(rates: list[float], t0: int = 0) -> list[ImuSample]:
    return [
        ImuSample(t0 + i * 4_807_692, t0 + i * 4_807_692 + 1, (0.0, -9.81, 0.0), (0.0, r, 0.0))
        for i, r in enumerate(rates)
    ]


def test_a_silent_imu_ends_the_procedure() -> None:
    clock = VirtualClock()
    rec = Recorder()
    log = ImuLog(ReplayImu(_samples([0.0] * 3), clock), clock, rec, 2_000_000)
    log.until(2 * 4_807_692)
    assert len(log.samples) == 3 and rec.records == log.samples
    with pytest.raises(CalibrationError, match="IMU sends nothing"):
        log.next()


def test_a_turn_during_a_capture_is_seen() -> None:
    clock = VirtualClock()
    still = _samples([0.002] * 600)
    turn = _samples([0.002] * 300 + [0.05] * 20 + [0.002] * 280)  # ~0.27 deg
    for samples, moved in ((still, False), (turn, True)):
        log = ImuLog(ReplayImu(samples, clock), clock, Recorder(), 1)
        log.until(samples[-1].sensor_ns)
        deg = _capture_turn_deg(log, 0, samples[-1].sensor_ns)
        assert (deg > ProcedureSettings().max_capture_turn_deg) == moved


def test_depth_is_the_median_where_most_frames_have_one() -> None:
    mm = np.array([[[1000, 0], [1500, 0]], [[1002, 0], [0, 900]], [[1010, 700], [1490, 0]]])
    frames = [DepthFrame(i, i, i, m.astype(np.uint16)) for i, m in enumerate(mm)]
    z = _average_depth(frames)
    assert z[0, 0] == pytest.approx(1.002) and z[1, 0] == pytest.approx(1.495)
    assert np.isnan(z[0, 1]) and np.isnan(z[1, 1])


def test_captures_that_cannot_work_are_refused(
    fixture_result: tuple[CalibrationResult, list[str]],
) -> None:
    dec = fixture_result[0].run.poses[0].decoded
    s = ProcedureSettings()
    assert _check(dec, s, 0) == ""
    with pytest.raises(CalibrationError, match="pose 3: nothing decodes"):
        _check(replace(dec, lit=np.zeros_like(dec.lit), signal=0.0), s, 2)
    assert "pose 3: the captures are saturated (60 %" in _check(
        replace(dec, saturated_fraction=0.6), s, 2
    )
    assert "too much ambient light" in _check(replace(dec, ambient_ratio=0.9), s, 2)
