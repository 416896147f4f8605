"""Register-level driver for the ST LSM6DSOX 6-axis IMU on I2C (``smbus2``).

Register addresses, bit fields and sensitivities are from the ST datasheet
DS12814 (LSM6DSOX, rev. 4): section 8 "Register mapping", section 9 "Register
description", table 2 "Mechanical characteristics" and table 4 "Temperature sensor".

Start-up: read ``WHO_AM_I`` (0x0F, must be 0x6C), software reset (``CTRL3_C``.SW_RESET,
self-clearing), then ``CTRL3_C`` = BDU | IF_INC (block data update, address
auto-increment for burst reads), ``CTRL1_XL`` = ODR_XL | FS_XL and ``CTRL2_G`` =
ODR_G | FS_G. Each read is one 16-byte burst from ``STATUS_REG`` (0x1E): status,
reserved, temperature, gyro x/y/z, accel x/y/z, little-endian int16.
"""

from __future__ import annotations

import errno
import struct
from dataclasses import dataclass
from typing import Protocol

from adaproj_edge.errors import DeviceError, DeviceNotFoundError, InputError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.oserrors import device_error

# --- registers (DS12814 section 8) --------------------------------------------------
WHO_AM_I = 0x0F
CTRL1_XL = 0x10  # ODR_XL[7:4] FS_XL[3:2] LPF2_XL_EN[1]
CTRL2_G = 0x11  # ODR_G[7:4] FS_G[3:2] FS_125[1]
CTRL3_C = 0x12  # BOOT[7] BDU[6] H_LACTIVE[5] PP_OD[4] SIM[3] IF_INC[2] - SW_RESET[0]
STATUS_REG = 0x1E  # TDA[2] GDA[1] XLDA[0]
OUT_TEMP_L = 0x20
OUTX_L_G = 0x22
OUTX_L_A = 0x28

CHIP_ID = 0x6C
ADDRESSES = (0x6A, 0x6B)  # SDO/SA0 pin low / high
CTRL3_SW_RESET = 0x01
CTRL3_IF_INC = 0x04
CTRL3_BDU = 0x40
STATUS_XLDA = 0x01
STATUS_GDA = 0x02
BURST_START = STATUS_REG
BURST_LEN = 16

# ODR_XL / ODR_G codes (high-performance mode), DS12814 tables 52 and 55
ODR_CODES: dict[float, int] = {
    12.5: 0b0001,
    26.0: 0b0010,
    52.0: 0b0011,
    104.0: 0b0100,
    208.0: 0b0101,
    416.0: 0b0110,
    833.0: 0b0111,
    1660.0: 0b1000,
    3330.0: 0b1001,
    6660.0: 0b1010,
}
# full scale -> (CTRL1_XL bits [3:2], sensitivity in mg/LSB), table 2 "LA_So"
ACCEL_RANGES: dict[int, tuple[int, float]] = {
    2: (0b00, 0.061),
    4: (0b10, 0.122),
    8: (0b11, 0.244),
    16: (0b01, 0.488),
}
# full scale (dps) -> (CTRL2_G bits [3:1] incl. FS_125, sensitivity in mdps/LSB), "G_So"
GYRO_RANGES: dict[int, tuple[int, float]] = {
    125: (0b001, 4.375),
    250: (0b000, 8.75),
    500: (0b010, 17.5),
    1000: (0b100, 35.0),
    2000: (0b110, 70.0),
}
TEMP_LSB_PER_C = 256.0  # table 4, 0 LSB at 25 degC
STANDARD_GRAVITY = 9.80665
RESET_POLLS = 10

_CHECK = "the IMU wiring (SDA, SCL, 3V3, GND) and its I2C address (0x6A with SA0 low, 0x6B high)"


class SMBusLike(Protocol):
    """The part of ``smbus2.SMBus`` the driver uses."""

    def read_byte_data(self, i2c_addr: int, register: int) -> int: ...

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None: ...

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]: ...


@dataclass(frozen=True)
class Lsm6dsoxConfig:
    """Output data rate (Hz) and full-scale ranges (g, dps)."""

    rate_hz: float = 208.0
    accel_range_g: int = 4
    gyro_range_dps: int = 500

    def __post_init__(self) -> None:
        if self.rate_hz not in ODR_CODES:
            raise InputError(f"LSM6DSOX rate {self.rate_hz} Hz not in {sorted(ODR_CODES)}")
        if self.accel_range_g not in ACCEL_RANGES:
            raise InputError(
                f"LSM6DSOX accel range ±{self.accel_range_g} g not in {sorted(ACCEL_RANGES)}"
            )
        if self.gyro_range_dps not in GYRO_RANGES:
            raise InputError(
                f"LSM6DSOX gyro range ±{self.gyro_range_dps} dps not in {sorted(GYRO_RANGES)}"
            )

    @property
    def ctrl1_xl(self) -> int:
        return (ODR_CODES[self.rate_hz] << 4) | (ACCEL_RANGES[self.accel_range_g][0] << 2)

    @property
    def ctrl2_g(self) -> int:
        return (ODR_CODES[self.rate_hz] << 4) | (GYRO_RANGES[self.gyro_range_dps][0] << 1)

    @property
    def accel_scale(self) -> float:
        """m/s^2 per LSB."""
        return ACCEL_RANGES[self.accel_range_g][1] * 1e-3 * STANDARD_GRAVITY

    @property
    def gyro_scale(self) -> float:
        """rad/s per LSB."""
        return GYRO_RANGES[self.gyro_range_dps][1] * 1e-3 * 3.141592653589793 / 180.0


class Lsm6dsox:
    """The LSM6DSOX on an SMBus; :meth:`start` checks identity and configures it."""

    def __init__(
        self,
        bus: SMBusLike,
        clock: Clock,
        address: int = ADDRESSES[0],
        config: Lsm6dsoxConfig | None = None,
        bus_name: str = "the I2C bus",
    ) -> None:
        self.bus = bus
        self.clock = clock
        self.address = address
        self.config = config or Lsm6dsoxConfig()
        self.bus_name = bus_name

    # ------------------------------------------------------------------ bus access
    def _what(self) -> str:
        return f"LSM6DSOX at 0x{self.address:02X} on {self.bus_name}"

    def _io_error(self, e: OSError) -> DeviceError:
        if e.errno in (errno.ENXIO, errno.EREMOTEIO, errno.ENODEV):
            return DeviceNotFoundError(f"no device answers as {self._what()}; check {_CHECK}")
        return device_error(e, self._what(), _CHECK)

    def _read(self, register: int) -> int:
        try:
            return int(self.bus.read_byte_data(self.address, register))
        except OSError as e:
            raise self._io_error(e) from None

    def _write(self, register: int, value: int) -> None:
        try:
            self.bus.write_byte_data(self.address, register, value)
        except OSError as e:
            raise self._io_error(e) from None

    # ------------------------------------------------------------------ start-up
    def start(self) -> None:
        """Identity check, software reset, configuration; raises a named DeviceError."""
        chip = self._read(WHO_AM_I)
        if chip != CHIP_ID:
            raise DeviceError(
                f"{self._what()} answered WHO_AM_I = 0x{chip:02X}, expected 0x{CHIP_ID:02X} "
                f"(LSM6DSOX); another chip is at this address: check {_CHECK}"
            )
        self._write(CTRL3_C, CTRL3_SW_RESET | CTRL3_IF_INC)
        for _ in range(RESET_POLLS):
            if not self._read(CTRL3_C) & CTRL3_SW_RESET:
                break
        else:
            raise DeviceError(f"{self._what()} did not finish its software reset; check its power")
        self._write(CTRL3_C, CTRL3_BDU | CTRL3_IF_INC)
        self._write(CTRL1_XL, self.config.ctrl1_xl)
        self._write(CTRL2_G, self.config.ctrl2_g)
        for reg, want in ((CTRL1_XL, self.config.ctrl1_xl), (CTRL2_G, self.config.ctrl2_g)):
            got = self._read(reg)
            if got != want:
                raise DeviceError(
                    f"{self._what()} register 0x{reg:02X} reads 0x{got:02X} after writing "
                    f"0x{want:02X}; check {_CHECK}"
                )

    def stop(self) -> None:
        """Power both sensors down (ODR = 0)."""
        self._write(CTRL1_XL, 0)
        self._write(CTRL2_G, 0)

    # ------------------------------------------------------------------ data
    def read(self) -> ImuSample | None:
        """One burst read; None when neither sensor has new data."""
        try:
            raw = self.bus.read_i2c_block_data(self.address, BURST_START, BURST_LEN)
        except OSError as e:
            raise self._io_error(e) from None
        t = self.clock.now_ns()
        if len(raw) != BURST_LEN:
            raise DeviceError(f"{self._what()} returned {len(raw)} bytes, expected {BURST_LEN}")
        status = raw[0]
        if not status & (STATUS_XLDA | STATUS_GDA):
            return None
        return decode_burst(bytes(raw), self.config, t, t)

    def close(self) -> None:
        close = getattr(self.bus, "close", None)
        if close is not None:
            close()


def decode_burst(raw: bytes, config: Lsm6dsoxConfig, sensor_ns: int, receive_ns: int) -> ImuSample:
    """Scale a 16-byte burst from ``STATUS_REG`` into an :class:`ImuSample` (SI units)."""
    temp, gx, gy, gz, ax, ay, az = struct.unpack_from("<7h", raw, 2)
    g, a = config.gyro_scale, config.accel_scale
    return ImuSample(
        sensor_ns,
        receive_ns,
        (ax * a, ay * a, az * a),
        (gx * g, gy * g, gz * g),
        25.0 + temp / TEMP_LSB_PER_C,
    )


def open_i2c(bus_number: int) -> SMBusLike:
    """Open ``/dev/i2c-N`` with smbus2, turning OS errors into named errors."""
    from smbus2 import SMBus

    try:
        bus: SMBusLike = SMBus(bus_number)
    except OSError as e:
        raise device_error(
            e,
            f"I2C bus /dev/i2c-{bus_number}",
            "that I2C is enabled (dtparam=i2c_arm=on) and the bus number in the board file",
        ) from None
    return bus
