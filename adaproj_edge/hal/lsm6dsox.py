"""Register-level driver for the ST LSM6DSOX 6-axis IMU on I2C (``smbus2``).

Register addresses, bit fields and sensitivities are from the ST datasheet
DS12814 (LSM6DSOX, rev. 4): section 8 "Register mapping", section 9 "Register
description", table 2 "Mechanical characteristics" and table 4 "Temperature sensor".

Start-up: read ``WHO_AM_I`` (0x0F, must be 0x6C), software reset (``CTRL3_C``.SW_RESET,
self-clearing), then ``CTRL3_C`` = BDU | IF_INC (block data update, address
auto-increment for burst reads), ``CTRL1_XL`` = ODR_XL | FS_XL and ``CTRL2_G`` =
ODR_G | FS_G.

FIFO (the default, section 6.5): the chip batches every sample and its own timestamp,
so none is lost when the host is busy and each carries the time the chip took it.
``CTRL10_C``.TIMESTAMP_EN, ``FIFO_CTRL3`` = BDR_GY | BDR_XL (both at the output data
rate), ``FIFO_CTRL4`` = DEC_TS_BATCH 01 (a timestamp word every time slot) |
ODR_T_BATCH 01 (temperature at 1.6 Hz) | FIFO_MODE 110 (continuous: the oldest words go
when it is full). A read takes ``FIFO_STATUS1-2`` (unread words, overrun), then the
words in bursts from ``FIFO_DATA_OUT_TAG`` (0x78; 7 bytes each, at most 4 per SMBus
block of 32 bytes, at most ``MAX_WORDS`` per read so that a full FIFO does not hold the
reader for long). Words are grouped into time slots by their tag counter; a slot with
gyro and accelerometer words is one sample, timed by its timestamp word (25 us LSB,
trimmed by ``INTERNAL_FREQ_FINE``; 32 bits, unwrapped) and mapped onto the host's clock
by the smallest delay seen between a sample and the read that fetched it, in reads
that emptied the FIFO (allowed to grow by 100 ppm: the chip's and the host's clocks
drift apart; times handed out never go back). A word whose tag fails
its parity check is dropped and counted, so is a slot whose timestamp goes back; an
overrun is counted and logged, and the samples before it are simply gone.

Without FIFO (``fifo = false``) each read is one 16-byte burst from ``STATUS_REG``
(0x1E): status, reserved, temperature, gyro x/y/z, accel x/y/z, little-endian int16,
timed by the host's clock when read.

This file is about 470 lines on purpose: it is one chip's register map and the two ways
of reading it, which share the start-up, the scaling and the fault handling; the
bus is reached through ``smbus2`` only, so the whole file runs against a fake bus in the
tests.
"""

from __future__ import annotations

import errno
import logging
import struct
from collections import deque
from dataclasses import dataclass
from typing import Protocol

from adaproj_edge import checks
from adaproj_edge.errors import DeviceError, DeviceNotFoundError, InputError
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.oserrors import device_error

log = logging.getLogger(__name__)

# --- registers (DS12814 section 8) --------------------------------------------------
FIFO_CTRL1 = 0x07  # WTM[7:0]
FIFO_CTRL2 = 0x08  # STOP_ON_WTM[7] FIFO_COMPR_RT_EN[6] ODRCHG_EN[4] UNCOPTR_RATE[2:1] WTM8[0]
FIFO_CTRL3 = 0x09  # BDR_GY[7:4] BDR_XL[3:0] (codes as ODR)
FIFO_CTRL4 = 0x0A  # DEC_TS_BATCH[7:6] ODR_T_BATCH[5:4] FIFO_MODE[2:0]
WHO_AM_I = 0x0F
CTRL1_XL = 0x10  # ODR_XL[7:4] FS_XL[3:2] LPF2_XL_EN[1]
CTRL2_G = 0x11  # ODR_G[7:4] FS_G[3:2] FS_125[1]
CTRL3_C = 0x12  # BOOT[7] BDU[6] H_LACTIVE[5] PP_OD[4] SIM[3] IF_INC[2] - SW_RESET[0]
CTRL10_C = 0x19  # TIMESTAMP_EN[5]
STATUS_REG = 0x1E  # TDA[2] GDA[1] XLDA[0]
OUT_TEMP_L = 0x20
OUTX_L_G = 0x22
OUTX_L_A = 0x28
FIFO_STATUS1 = 0x3A  # DIFF_FIFO[7:0]
FIFO_STATUS2 = 0x3B  # WTM_IA[7] OVR_IA[6] FULL_IA[5] COUNTER_BDR_IA[4] OVR_LATCHED[3] DIFF[9:8]
TIMESTAMP0 = 0x40  # TIMESTAMP0..3: 32-bit counter, 25 us LSB
INTERNAL_FREQ_FINE = 0x63  # signed: the chip's clock is off by 0.15 % per LSB
FIFO_DATA_OUT_TAG = 0x78  # TAG_SENSOR[7:3] TAG_CNT[2:1] TAG_PARITY[0]; data 0x79..0x7E

CHIP_ID = 0x6C
ADDRESSES = (0x6A, 0x6B)  # SDO/SA0 pin low / high
CTRL3_SW_RESET = 0x01
CTRL3_IF_INC = 0x04
CTRL3_BDU = 0x40
STATUS_XLDA = 0x01
STATUS_GDA = 0x02
BURST_START = STATUS_REG
BURST_LEN = 16
CTRL10_TIMESTAMP_EN = 0x20
FIFO_MODE_CONTINUOUS = 0b110
FIFO_OVR_LATCHED = 0x08
FIFO_FULL_IA = 0x20
FIFO_OVR_IA = 0x40
DEC_TS_EVERY_SLOT = 0b01
ODR_T_1_6_HZ = 0b01
TAG_GYRO = 0x01
TAG_ACCEL = 0x02
TAG_TEMPERATURE = 0x03
TAG_TIMESTAMP = 0x04
WORD_LEN = 7
WORDS_PER_BLOCK = 4  # an SMBus block is at most 32 bytes
MAX_WORDS = 96  # per read: a full FIFO (512 words) is drained over a few reads
TICK_S = 25e-6
CLOCK_DRIFT = 1e-4  # the host-chip delay may grow this fast (100 ppm)

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

    def read_byte_data(self, i2c_addr: int, register: int) -> int:
        """The byte in ``register`` of the chip at ``i2c_addr``."""
        ...

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None:
        """Write ``value`` to ``register``."""
        ...

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]:
        """``length`` registers from ``register`` on."""
        ...


@dataclass(frozen=True)
class Lsm6dsoxConfig:
    """Output data rate (Hz), full-scale ranges (g, dps), and whether samples are read
    from the chip's FIFO (timed by the chip) or one at a time (timed when read)."""

    rate_hz: float = 416.0
    accel_range_g: int = 4
    gyro_range_dps: int = 500
    fifo: bool = True

    def __post_init__(self) -> None:
        checks.flag(self.fifo, "fifo")
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
        """CTRL1_XL value: accelerometer data rate and full scale."""
        return (ODR_CODES[self.rate_hz] << 4) | (ACCEL_RANGES[self.accel_range_g][0] << 2)

    @property
    def ctrl2_g(self) -> int:
        """CTRL2_G value: gyroscope data rate and full scale."""
        return (ODR_CODES[self.rate_hz] << 4) | (GYRO_RANGES[self.gyro_range_dps][0] << 1)

    @property
    def fifo_ctrl3(self) -> int:
        """Both sensors batched at the output data rate."""
        return (ODR_CODES[self.rate_hz] << 4) | ODR_CODES[self.rate_hz]

    @property
    def fifo_ctrl4(self) -> int:
        """A timestamp every slot, temperature at 1.6 Hz, continuous mode."""
        return (DEC_TS_EVERY_SLOT << 6) | (ODR_T_1_6_HZ << 4) | FIFO_MODE_CONTINUOUS

    @property
    def accel_scale(self) -> float:
        """m/s^2 per LSB."""
        return ACCEL_RANGES[self.accel_range_g][1] * 1e-3 * STANDARD_GRAVITY

    @property
    def gyro_scale(self) -> float:
        """rad/s per LSB."""
        return GYRO_RANGES[self.gyro_range_dps][1] * 1e-3 * 3.141592653589793 / 180.0


@dataclass
class _Slot:
    """The FIFO words of one time slot gathered so far (raw counts, raw timestamp)."""

    cnt: int | None = None
    gyro: tuple[int, int, int] | None = None
    accel: tuple[int, int, int] | None = None
    ticks: int | None = None


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
        self.overruns = 0
        self.parity_errors = 0
        self.time_errors = 0
        self._samples: deque[ImuSample] = deque()
        self._fresh: list[ImuSample] = []  # decoded in this read, on the chip's clock
        self._slot = _Slot()
        self._tick_ns = TICK_S * 1e9
        self._ticks: int | None = None  # unwrapped timestamp of the newest slot
        self._offset: int | None = None  # host time - chip time (ns)
        self._last_read_ns: int | None = None
        self._last_sensor_ns = -(1 << 62)
        self._temperature = 25.0

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
    def identify(self) -> int:
        """Read ``WHO_AM_I``; raises a named DeviceError unless it is an LSM6DSOX's.

        Returns
        -------
        int
            The chip id read (:data:`CHIP_ID`).
        """
        chip = self._read(WHO_AM_I)
        if chip != CHIP_ID:
            raise DeviceError(
                f"{self._what()} answered WHO_AM_I = 0x{chip:02X}, expected 0x{CHIP_ID:02X} "
                f"(LSM6DSOX); another chip is at this address: check {_CHECK}"
            )
        return chip

    def start(self) -> None:
        """Identity check, software reset, configuration; raises a named DeviceError."""
        self.identify()
        self._write(CTRL3_C, CTRL3_SW_RESET | CTRL3_IF_INC)
        for _ in range(RESET_POLLS):
            if not self._read(CTRL3_C) & CTRL3_SW_RESET:
                break
        else:
            raise DeviceError(f"{self._what()} did not finish its software reset; check its power")
        self._write(CTRL3_C, CTRL3_BDU | CTRL3_IF_INC)
        self._write(CTRL1_XL, self.config.ctrl1_xl)
        self._write(CTRL2_G, self.config.ctrl2_g)
        check = [(CTRL1_XL, self.config.ctrl1_xl), (CTRL2_G, self.config.ctrl2_g)]
        if self.config.fifo:
            self._write(CTRL10_C, CTRL10_TIMESTAMP_EN)
            self._write(FIFO_CTRL3, self.config.fifo_ctrl3)
            self._write(FIFO_CTRL4, self.config.fifo_ctrl4)
            check.append((FIFO_CTRL4, self.config.fifo_ctrl4))
            fine = struct.unpack("b", bytes([self._read(INTERNAL_FREQ_FINE)]))[0]
            self._tick_ns = TICK_S * 1e9 / (1.0 + 0.0015 * fine)
        for reg, want in check:
            got = self._read(reg)
            if got != want:
                raise DeviceError(
                    f"{self._what()} register 0x{reg:02X} reads 0x{got:02X} after writing "
                    f"0x{want:02X}; check {_CHECK}"
                )

    def stop(self) -> None:
        """Power both sensors down (ODR = 0) and the FIFO off (bypass)."""
        self._write(CTRL1_XL, 0)
        self._write(CTRL2_G, 0)
        if self.config.fifo:
            self._write(FIFO_CTRL4, 0)

    # ------------------------------------------------------------------ data
    def read(self) -> ImuSample | None:
        """The next sample; None when none is ready. From the FIFO: the oldest sample
        not handed out yet, reading the FIFO when none is left."""
        if not self.config.fifo:
            return self._read_burst()
        if not self._samples:
            self._drain()
        return self._samples.popleft() if self._samples else None

    def _block(self, register: int, length: int) -> bytes:
        try:
            raw = self.bus.read_i2c_block_data(self.address, register, length)
        except OSError as e:
            raise self._io_error(e) from None
        if len(raw) != length:
            raise DeviceError(f"{self._what()} returned {len(raw)} bytes, expected {length}")
        return bytes(raw)

    def _drain(self) -> None:
        """Read what the FIFO holds (at most ``MAX_WORDS`` words) into samples."""
        status = self._block(FIFO_STATUS1, 2)
        t_read = self.clock.now_ns()
        waiting = status[0] | ((status[1] & 0x03) << 8)
        n = min(waiting, MAX_WORDS)
        if status[1] & (FIFO_OVR_LATCHED | FIFO_OVR_IA):
            self.overruns += 1
            self._slot = _Slot()
            log.warning(
                "%s: FIFO overrun, samples were lost (%d so far)", self._what(), self.overruns
            )
        newest: int | None = None
        while n > 0:
            k = min(n, WORDS_PER_BLOCK)
            raw = self._block(FIFO_DATA_OUT_TAG, WORD_LEN * k)
            n -= k
            for i in range(k):
                chip_ns = self._word(raw[WORD_LEN * i : WORD_LEN * (i + 1)])
                newest = chip_ns if chip_ns is not None else newest
        slot_ns = self._emit()  # the newest slot is complete: its words come together
        newest = slot_ns if slot_ns is not None else newest
        if newest is not None:
            # only a read that emptied the FIFO says how late its newest sample is
            self._sync(t_read, newest, update=waiting <= MAX_WORDS or self._offset is None)
        self._fresh = []

    def _word(self, w: bytes) -> int | None:
        """Take one FIFO word; the chip time (ns) of a slot it completes, if any."""
        tag = w[0]
        if bin(tag).count("1") & 1:
            self.parity_errors += 1
            return None
        sensor, cnt = tag >> 3, (tag >> 1) & 0x03
        done = None
        if self._slot.cnt is not None and self._slot.cnt != cnt:
            done = self._emit()
        self._slot.cnt = cnt
        if sensor == TAG_GYRO:
            self._slot.gyro = struct.unpack_from("<3h", w, 1)
        elif sensor == TAG_ACCEL:
            self._slot.accel = struct.unpack_from("<3h", w, 1)
        elif sensor == TAG_TIMESTAMP:
            self._slot.ticks = int(struct.unpack_from("<I", w, 1)[0])
        elif sensor == TAG_TEMPERATURE:
            self._temperature = 25.0 + struct.unpack_from("<h", w, 1)[0] / TEMP_LSB_PER_C
        return done

    def _emit(self) -> int | None:
        """The slot gathered so far as a sample (when it has both sensors); its chip
        time (ns)."""
        slot, self._slot = self._slot, _Slot()
        if slot.gyro is None or slot.accel is None:
            return None
        period_ticks = 1e9 / self.config.rate_hz / self._tick_ns
        raw = slot.ticks
        if raw is not None:
            base = 0 if self._ticks is None else self._ticks & ~0xFFFFFFFF
            ticks = base | raw
            if self._ticks is not None and ticks < self._ticks - 0x80000000:
                ticks += 1 << 32  # the 32-bit counter wrapped
            if self._ticks is not None and ticks <= self._ticks:
                self.time_errors += 1  # a timestamp that goes back: a corrupt word
                return None
            self._ticks = ticks
        elif self._ticks is not None:
            self._ticks = round(self._ticks + period_ticks)  # no timestamp word: one period
        else:
            return None
        chip_ns = round(self._ticks * self._tick_ns)
        g, a = self.config.gyro_scale, self.config.accel_scale
        gx, gy, gz = slot.gyro
        ax, ay, az = slot.accel
        self._fresh.append(
            ImuSample(
                chip_ns,
                0,
                (ax * a, ay * a, az * a),
                (gx * g, gy * g, gz * g),
                self._temperature,
            )
        )
        return chip_ns

    def _sync(self, t_read: int, newest_chip_ns: int, update: bool) -> None:
        """Map the samples just read onto the host's clock: offset = the smallest delay
        between a sample and its read (allowed to grow by ``CLOCK_DRIFT``), learnt from
        reads that emptied the FIFO (``update``); times never go back."""
        offset = t_read - newest_chip_ns
        if self._offset is None or (update and offset < self._offset):
            self._offset = offset
        elif update and self._last_read_ns is not None:
            grow = round(CLOCK_DRIFT * max(0, t_read - self._last_read_ns))
            self._offset = min(offset, self._offset + grow)
        self._last_read_ns = t_read
        for s in self._fresh:
            t = max(s.sensor_ns + self._offset, self._last_sensor_ns + 1)
            self._last_sensor_ns = t
            self._samples.append(ImuSample(t, t_read, s.accel, s.gyro, s.temperature_c))

    def _read_burst(self) -> ImuSample | None:
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
        """Close the bus if it can be closed."""
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
