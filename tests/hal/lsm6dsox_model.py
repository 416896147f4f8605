"""A register model of the ST LSM6DSOX (datasheet DS12814) behind an SMBus-shaped bus.

What is modelled, from the datasheet:

- 0x00..0x7F register file with the reset values of section 9 (``WHO_AM_I`` = 0x6C,
  ``CTRL3_C`` = 0x04 i.e. IF_INC set, everything used here else 0x00);
- read-only registers (``WHO_AM_I``, ``STATUS_REG``, outputs) ignore writes;
- ``CTRL3_C``.SW_RESET restores the reset values and clears itself after a few reads;
- multi-byte reads auto-increment the address only while IF_INC is set;
- output registers hold the last sample as little-endian int16 counts at the
  configured full scale, saturating at the int16 limits; ``STATUS_REG`` XLDA/GDA are
  set when a sample arrives with the sensor powered (ODR != 0) and cleared when the
  outputs are read;
- a bus with no device at an address NACKs (``OSError`` ENXIO/EREMOTEIO, as the
  Linux i2c driver reports it); faults can be injected after N transfers;
- the FIFO (section 6.5, registers FIFO_CTRL1-4, FIFO_STATUS1-2, FIFO_DATA_OUT_TAG and
  X/Y/Z, TIMESTAMP0-3, INTERNAL_FREQ_FINE): in continuous mode (FIFO_MODE = 110) every
  sample of a sensor whose batch data rate (FIFO_CTRL3 BDR_GY / BDR_XL) is set is
  stored as a 7-byte word (tag byte: TAG_SENSOR[7:3] 0x01 gyro, 0x02 accel, 0x03
  temperature, 0x04 timestamp; TAG_CNT[2:1] the time slot modulo 4; TAG_PARITY[0] makes
  the byte's parity even), temperature at its ODR_T_BATCH rate (1.6, 12.5 or 52 Hz),
  with a timestamp word per slot when DEC_TS_BATCH = 01 and
  CTRL10_C.TIMESTAMP_EN is set (TIMESTAMP[31:0] in X_L..Y_H, one LSB = 25 us /
  (1 + 0.0015 INTERNAL_FREQ_FINE)); 512 words (3 kbytes uncompressed), the oldest
  overwritten when full (FIFO_OVR_IA, FIFO_OVR_LATCHED, the latter cleared by reading
  FIFO_STATUS2); DIFF_FIFO[9:0] counts the unread words; reading FIFO_DATA_OUT_TAG takes
  the next word out, X_L..Z_H return its data, and a burst rolls over from 0x7E back to
  0x78; writing FIFO_MODE = 000 (bypass) empties it. Parity errors can be injected.
"""

from __future__ import annotations

import errno
import math
import struct
from collections import deque

from adaproj_edge.hal import lsm6dsox as reg

RESET_VALUES = {reg.WHO_AM_I: 0x6C, reg.CTRL3_C: 0x04}
READ_ONLY = {
    reg.WHO_AM_I,
    reg.STATUS_REG,
    0x1F,
    *range(0x20, 0x2E),
    reg.FIFO_STATUS1,
    reg.FIFO_STATUS2,
    *range(reg.TIMESTAMP0, reg.TIMESTAMP0 + 4),
    reg.INTERNAL_FREQ_FINE,
    *range(reg.FIFO_DATA_OUT_TAG, reg.FIFO_DATA_OUT_TAG + 7),
}
FIFO_WORDS = 512
ODR_HZ = {code: hz for hz, code in reg.ODR_CODES.items()}
ACCEL_LSB_MG = {0b00: 0.061, 0b10: 0.122, 0b11: 0.244, 0b01: 0.488}
GYRO_LSB_MDPS = {0b000: 8.75, 0b001: 4.375, 0b010: 17.5, 0b100: 35.0, 0b110: 70.0}


def parity_tag(sensor: int, cnt: int) -> int:
    """The tag byte of a FIFO word: sensor, slot counter and the parity bit that makes
    the byte's parity even."""
    t = (sensor << 3) | ((cnt & 3) << 1)
    return t | (bin(t).count("1") & 1)


class Lsm6dsoxModel:
    def __init__(self, reset_reads: int = 2, freq_fine: int = 0) -> None:
        self.regs = bytearray(128)
        self.reset_reads = reset_reads
        self._reset_left = 0
        self.stuck_in_reset = False
        self.freq_fine = freq_fine  # the chip's trim of its clock (signed, per unit)
        self.fifo: deque[bytes] = deque()
        self._word = bytes(7)
        self._slot = 0
        self._slots = 0  # time slots batched
        self._ticks = 0  # timestamp counter
        self.corrupt_next_tags = 0  # the next N words read have a bad parity
        self._reset()

    def _reset(self) -> None:
        self.regs[:] = bytes(128)
        for r, v in RESET_VALUES.items():
            self.regs[r] = v
        self.regs[reg.INTERNAL_FREQ_FINE] = self.freq_fine & 0xFF
        self.fifo.clear()
        self._update_fifo_status()

    # --- the FIFO ----------------------------------------------------------------------
    @property
    def fifo_on(self) -> bool:
        return self.regs[reg.FIFO_CTRL4] & 0x07 == reg.FIFO_MODE_CONTINUOUS

    def _update_fifo_status(self) -> None:
        n = len(self.fifo)
        self.regs[reg.FIFO_STATUS1] = n & 0xFF
        keep = self.regs[reg.FIFO_STATUS2] & (reg.FIFO_OVR_LATCHED | reg.FIFO_OVR_IA)
        full = reg.FIFO_FULL_IA if n >= FIFO_WORDS - 1 else 0
        self.regs[reg.FIFO_STATUS2] = keep | full | ((n >> 8) & 0x03)

    def _store(self, word: bytes) -> None:
        if len(self.fifo) >= FIFO_WORDS:
            self.fifo.popleft()
            self.regs[reg.FIFO_STATUS2] |= reg.FIFO_OVR_IA | reg.FIFO_OVR_LATCHED
        self.fifo.append(word)

    def tick_seconds(self) -> float:
        """One timestamp LSB in seconds, as trimmed by INTERNAL_FREQ_FINE."""
        fine = struct.unpack("b", bytes([self.regs[reg.INTERNAL_FREQ_FINE]]))[0]
        return 1.0 / (40_000.0 * (1.0 + 0.0015 * fine))

    def advance(self, seconds: float) -> None:
        """Time passes on the chip: its timestamp counter runs (32 bits, wrapping)."""
        self._ticks = (self._ticks + round(seconds / self.tick_seconds())) & 0xFFFFFFFF
        for i in range(4):
            self.regs[reg.TIMESTAMP0 + i] = (self._ticks >> (8 * i)) & 0xFF

    def set_ticks(self, ticks: int) -> None:
        """Set the timestamp counter (e.g. just before it wraps)."""
        self._ticks = ticks & 0xFFFFFFFF
        self.advance(0.0)

    def _batch(self, gyro_counts: list[int], accel_counts: list[int], temp: int) -> None:
        c3 = self.regs[reg.FIFO_CTRL3]
        words = []
        if c3 >> 4 and self.regs[reg.CTRL2_G] >> 4:
            words.append(bytes([parity_tag(reg.TAG_GYRO, self._slot)]) + _le(gyro_counts))
        if c3 & 0x0F and self.regs[reg.CTRL1_XL] >> 4:
            words.append(bytes([parity_tag(reg.TAG_ACCEL, self._slot)]) + _le(accel_counts))
        if not words:
            return
        c4 = self.regs[reg.FIFO_CTRL4]
        if (c4 >> 6) == 0b01 and self.regs[reg.CTRL10_C] & reg.CTRL10_TIMESTAMP_EN:
            ts = struct.pack("<I", self._ticks) + bytes(2)
            words.append(bytes([parity_tag(reg.TAG_TIMESTAMP, self._slot)]) + ts)
        t_rate = {0b01: 1.6, 0b10: 12.5, 0b11: 52.0}.get((c4 >> 4) & 0b11)
        odr = ODR_HZ.get(c3 >> 4) or ODR_HZ.get(c3 & 0x0F) or 1.0
        if t_rate is not None and self._slots % max(1, round(odr / t_rate)) == 0:
            words.append(bytes([parity_tag(reg.TAG_TEMPERATURE, self._slot)]) + _le([temp, 0, 0]))
        for w in words:
            self._store(w)
        self._slot = (self._slot + 1) & 3
        self._slots += 1
        self._update_fifo_status()

    # --- register access ----------------------------------------------------------
    def read(self, register: int) -> int:
        if register == reg.FIFO_DATA_OUT_TAG:
            self._word = self.fifo.popleft() if self.fifo else bytes(7)
            if self.corrupt_next_tags:
                self.corrupt_next_tags -= 1
                self._word = bytes([self._word[0] ^ 0x01]) + self._word[1:]
            self._update_fifo_status()
        if reg.FIFO_DATA_OUT_TAG <= register <= reg.FIFO_DATA_OUT_TAG + 6:
            return self._word[register - reg.FIFO_DATA_OUT_TAG]
        value = self.regs[register]
        if register == reg.FIFO_STATUS2:
            self.regs[reg.FIFO_STATUS2] &= ~(reg.FIFO_OVR_LATCHED | reg.FIFO_OVR_IA) & 0xFF
        if register == reg.CTRL3_C and self._reset_left:
            self._reset_left -= 1
            if self._reset_left == 0 and not self.stuck_in_reset:
                self.regs[reg.CTRL3_C] &= ~reg.CTRL3_SW_RESET & 0xFF
        if 0x28 <= register <= 0x2D:
            self.regs[reg.STATUS_REG] &= ~reg.STATUS_XLDA & 0xFF
        if 0x22 <= register <= 0x27:
            self.regs[reg.STATUS_REG] &= ~reg.STATUS_GDA & 0xFF
        return value

    def write(self, register: int, value: int) -> None:
        if register in READ_ONLY:
            return
        if register == reg.CTRL3_C and value & reg.CTRL3_SW_RESET:
            self._reset()
            self.regs[reg.CTRL3_C] = RESET_VALUES[reg.CTRL3_C] | reg.CTRL3_SW_RESET
            self._reset_left = self.reset_reads
            return
        self.regs[register] = value & 0xFF
        if register == reg.FIFO_CTRL4 and not self.fifo_on:
            self.fifo.clear()  # bypass mode empties the FIFO
            self.regs[reg.FIFO_STATUS2] = 0
            self._update_fifo_status()

    def read_block(self, register: int, length: int) -> list[int]:
        inc = bool(self.regs[reg.CTRL3_C] & reg.CTRL3_IF_INC)
        out = []
        r = register
        for _ in range(length):
            out.append(self.read(r))
            if inc:
                # the FIFO's output registers roll over from 0x7E to 0x78
                r = reg.FIFO_DATA_OUT_TAG if r == reg.FIFO_DATA_OUT_TAG + 6 else r + 1
        return out

    # --- the physical side ---------------------------------------------------------
    def push_sample(
        self, accel: tuple[float, float, float], gyro: tuple[float, float, float], temp_c: float
    ) -> None:
        """A new sample (m/s^2, rad/s, degC) arrives, converted as the chip does."""
        c1, c2 = self.regs[reg.CTRL1_XL], self.regs[reg.CTRL2_G]
        a_lsb = ACCEL_LSB_MG[(c1 >> 2) & 0b11] * 1e-3 * reg.STANDARD_GRAVITY
        g_lsb = GYRO_LSB_MDPS[(c2 >> 1) & 0b111] * 1e-3 * math.pi / 180
        counts = [round((temp_c - 25.0) * 256)]
        counts += [round(v / g_lsb) for v in gyro] + [round(v / a_lsb) for v in accel]
        counts = [max(-32768, min(32767, c)) for c in counts]
        for i, c in enumerate(counts):
            c &= 0xFFFF
            self.regs[0x20 + 2 * i] = c & 0xFF
            self.regs[0x21 + 2 * i] = c >> 8
        if self.fifo_on:
            self._batch(counts[1:4], counts[4:7], counts[0])
        status = 0
        if c1 >> 4:
            status |= reg.STATUS_XLDA
        if c2 >> 4:
            status |= reg.STATUS_GDA
        self.regs[reg.STATUS_REG] |= status


def _le(counts: list[int]) -> bytes:
    return struct.pack("<3h", *counts)


class FakeSMBus:
    """The three smbus2 calls the driver makes, served by register models."""

    def __init__(self, devices: dict[int, Lsm6dsoxModel]) -> None:
        self.devices = devices
        self.transfers = 0
        self.fail_after: int | None = None
        self.fail_errno = errno.EIO
        self.closed = False

    def _dev(self, addr: int) -> Lsm6dsoxModel:
        self.transfers += 1
        if self.fail_after is not None and self.transfers > self.fail_after:
            raise OSError(self.fail_errno, "Remote I/O error")
        if addr not in self.devices:
            raise OSError(errno.EREMOTEIO, "Remote I/O error")
        return self.devices[addr]

    def read_byte_data(self, i2c_addr: int, register: int) -> int:
        return self._dev(i2c_addr).read(register)

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None:
        self._dev(i2c_addr).write(register, value)

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]:
        return self._dev(i2c_addr).read_block(register, length)

    def close(self) -> None:
        self.closed = True
