"""The IMU protocol, its sample record, and its replay implementation.

The real driver is :class:`adaproj_edge.hal.lsm6dsox.Lsm6dsox` (I2C, ``smbus2``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.recorded import ReplayStream

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ImuSample:
    """One accelerometer + gyroscope reading in the IMU frame I.

    ``accel`` is the specific force in m/s^2 (about (0, -9.81, 0) at rest with y down),
    ``gyro`` the angular rate in rad/s, ``temperature_c`` the die temperature.
    """

    sensor_ns: int
    receive_ns: int
    accel: Vec3
    gyro: Vec3
    temperature_c: float = 25.0


class Imu(Protocol):
    """An inertial measurement unit."""

    def read(self) -> ImuSample | None:
        """The newest sample, or None when none is ready (or the recording ended)."""
        ...

    def close(self) -> None:
        """Release the IMU."""
        ...


class ReplayImu:
    """IMU samples from a recording, on a virtual clock."""

    def __init__(self, samples: Iterable[ImuSample], clock: VirtualClock) -> None:
        self._stream = ReplayStream(samples, clock)

    def read(self) -> ImuSample | None:
        """The next recorded sample, or None at the end of the recording."""
        return self._stream.next()

    def close(self) -> None:
        """Nothing to release."""
        pass
