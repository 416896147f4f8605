"""Serial traffic: recorded through a wrapped port (a real pty), replayed through a port."""

from __future__ import annotations

from pathlib import Path

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.clock import MonotonicClock
from adaproj_edge.hal.serial import FdPort, PtyPair
from adaproj_edge.session.player import Replay
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.recorder import Recorder
from adaproj_edge.session.serial_tap import RecordingPort
from adaproj_edge.session.writer import SessionWriter


def test_record_then_replay_serial_traffic(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    rec = Recorder(SessionWriter(path, Calibration.default()), MonotonicClock())
    with PtyPair.open() as pty:
        device = RecordingPort(pty.port(), rec.serial)
        host = FdPort(pty.slave)
        host.write(b"\x02\x00hello")
        got = b""
        while len(got) < 7:
            got += device.read(64, 1.0)
        device.write(b"reply")
        assert host.read(5, 1.0) == b"reply"

    def stop() -> None:
        rec.stop()
        return None

    rec.run({"stop": stop})
    s = read_session(path)
    assert b"".join(t.data for t in s.serial if t.direction == "rx") == b"\x02\x00hello"
    assert [t.data for t in s.serial if t.direction == "tx"] == [b"reply"]

    replay = Replay(path)
    port = replay.serial_port()
    assert port.read(3, 0.0) + port.read(64, 0.0) == b"\x02\x00hello"
    assert port.read(64, 0.0) == b""
    port.write(b"reply")
    assert port.written == [b"reply"]
    port.close()
