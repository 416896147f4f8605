"""The recorder: several sources and serial traffic into one session."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from adaproj_edge.errors import DeviceError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.clock import MonotonicClock
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session.codec import Record
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.recorder import Recorder
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.writer import SessionWriter


def source(items: list[Record], rec_done: list[bool]) -> Iterator[Record | None]:
    yield from items
    rec_done.append(True)
    while True:
        yield None


def test_records_from_every_source_end_up_in_the_session(tmp_path: Path) -> None:
    imu = [ImuSample(i, i + 1, (0.0, -9.8, 0.0), (0.0, 0.0, 0.0)) for i in range(50)]
    btn = [ButtonEvent(7, 8, 28, True), ButtonEvent(9, 10, 28, False)]
    w = SessionWriter(tmp_path / "r.mcap", Calibration.default())
    rec = Recorder(w, MonotonicClock(), flush_every_s=0.0)
    done: list[bool] = []
    its = [source(list(imu), done), source(list(btn), done)]

    def make(it: Iterator[Record | None]) -> object:
        def read() -> Record | None:
            r = next(it)
            if len(done) == 2:
                rec.stop()
            return r

        return read

    rec.serial("rx", b"\x01\x02")
    n = rec.run({"imu": make(its[0]), "button": make(its[1])})  # type: ignore[dict-item]
    s = read_session(tmp_path / "r.mcap")
    assert n == len(s.records) == 53
    assert sorted(s.imu, key=lambda x: x.sensor_ns) == imu
    assert s.button == btn
    assert len(s.serial) == 1 and isinstance(s.serial[0], SerialTraffic)
    assert s.serial[0].data == b"\x01\x02"


def test_a_device_error_stops_the_recording_and_keeps_the_file(tmp_path: Path) -> None:
    w = SessionWriter(tmp_path / "e.mcap", Calibration.default())
    rec = Recorder(w, MonotonicClock())
    calls = [0]

    def failing() -> Record | None:
        calls[0] += 1
        if calls[0] > 3:
            raise DeviceError("IMU gone")
        return ImuSample(calls[0], calls[0], (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    with pytest.raises(DeviceError, match="IMU gone"):
        rec.run({"imu": failing})
    s = read_session(tmp_path / "e.mcap")
    assert len(s.imu) == 3 and not s.truncated
