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
  Linux i2c driver reports it); faults can be injected after N transfers.
"""

from __future__ import annotations

import errno
import math

from adaproj_edge.hal import lsm6dsox as reg

RESET_VALUES = {reg.WHO_AM_I: 0x6C, reg.CTRL3_C: 0x04}
READ_ONLY = {reg.WHO_AM_I, reg.STATUS_REG, 0x1F, *range(0x20, 0x2E)}
ACCEL_LSB_MG = {0b00: 0.061, 0b10: 0.122, 0b11: 0.244, 0b01: 0.488}
GYRO_LSB_MDPS = {0b000: 8.75, 0b001: 4.375, 0b010: 17.5, 0b100: 35.0, 0b110: 70.0}


class Lsm6dsoxModel:
    def __init__(self, reset_reads: int = 2) -> None:
        self.regs = bytearray(128)
        self.reset_reads = reset_reads
        self._reset_left = 0
        self.stuck_in_reset = False
        self._reset()

    def _reset(self) -> None:
        self.regs[:] = bytes(128)
        for r, v in RESET_VALUES.items():
            self.regs[r] = v

    # --- register access ----------------------------------------------------------
    def read(self, register: int) -> int:
        value = self.regs[register]
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

    def read_block(self, register: int, length: int) -> list[int]:
        inc = bool(self.regs[reg.CTRL3_C] & reg.CTRL3_IF_INC)
        return [self.read(register + i if inc else register) for i in range(length)]

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
        for i, c in enumerate(counts):
            c = max(-32768, min(32767, c)) & 0xFFFF
            self.regs[0x20 + 2 * i] = c & 0xFF
            self.regs[0x21 + 2 * i] = c >> 8
        status = 0
        if c1 >> 4:
            status |= reg.STATUS_XLDA
        if c2 >> 4:
            status |= reg.STATUS_GDA
        self.regs[reg.STATUS_REG] |= status


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
