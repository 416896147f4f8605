"""Feeding a recorded session back through the device protocols, on a virtual clock.

Nothing waits on wall-clock time: each record is handed out when the consumer asks
for the next one and the virtual clock jumps to its receive time (PX4 replay style),
so a replay runs as fast as the pipeline consumes it and gives the same results
every time.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent, ReplayButton
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import DepthFrame, ReplayDepthCamera
from adaproj_edge.hal.imu import ImuSample, ReplayImu
from adaproj_edge.session import schemas as s
from adaproj_edge.session.codec import Record
from adaproj_edge.session.reader import iter_records, read_calibration
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.serial_tap import ReplayPort


class Replay:
    """A recorded session as a set of replay devices sharing one virtual clock.

    ``events()`` gives every record in recorded order (advancing the clock); the
    device objects each stream their own channel from the file.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.calibration: Calibration = read_calibration(self.path)
        self.clock = VirtualClock()

    def events(self) -> Iterator[Record]:
        """Every record in recorded order, the clock moved to each one's receive time."""
        for rec in iter_records(self.path):
            self.clock.advance_to(rec.receive_ns)
            yield rec

    def depth_camera(self) -> ReplayDepthCamera:
        """The session's depth frames as a depth camera with the recorded model."""
        frames = (r for r in iter_records(self.path, {s.DEPTH}) if isinstance(r, DepthFrame))
        return ReplayDepthCamera(self.calibration.depth, frames, self.clock)

    def imu(self) -> ReplayImu:
        """The session's IMU samples as an IMU."""
        samples = (r for r in iter_records(self.path, {s.IMU}) if isinstance(r, ImuSample))
        return ReplayImu(samples, self.clock)

    def button(self) -> ReplayButton:
        """The session's button events as a button."""
        evs = (r for r in iter_records(self.path, {s.BUTTON}) if isinstance(r, ButtonEvent))
        return ReplayButton(evs, self.clock)

    def serial_port(self) -> ReplayPort:
        """The session's ``rx`` serial traffic as a port (``tx`` is dropped: the code under
        replay writes its own)."""
        topics = {s.SERIAL_RX, s.SERIAL_TX}
        traffic = (r for r in iter_records(self.path, topics) if isinstance(r, SerialTraffic))
        return ReplayPort(traffic, self.clock)
