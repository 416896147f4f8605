"""The LSM6DSOX driver's FIFO path against the register model: batching, the chip's
timestamps on the host's clock, wrap-around, overrun, parity and read errors."""

from __future__ import annotations

import errno
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import DeviceError, DeviceNotFoundError
from adaproj_edge.hal import lsm6dsox as reg
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.lsm6dsox import Lsm6dsox, Lsm6dsoxConfig
from tests.hal.lsm6dsox_model import FIFO_WORDS, FakeSMBus, Lsm6dsoxModel, parity_tag

RATE = 416.0
T0 = 1_000_000_000


def rig(freq_fine: int = 0) -> tuple[Lsm6dsox, Lsm6dsoxModel, FakeSMBus, VirtualClock]:
    chip = Lsm6dsoxModel(freq_fine=freq_fine)
    bus = FakeSMBus({0x6A: chip})
    clock = VirtualClock(T0)
    imu = Lsm6dsox(bus, clock, 0x6A, Lsm6dsoxConfig(rate_hz=RATE))
    imu.start()
    return imu, chip, bus, clock


def push(chip: Lsm6dsoxModel, clock: VirtualClock, n: int, gyro: float = 0.1) -> list[int]:
    """``n`` samples, one chip period apart; the host's clock moves with the chip's.
    Returns the host times the samples were taken."""
    out = []
    for k in range(n):
        chip.advance(1 / RATE)
        clock.advance_to(clock.now_ns() + round(1e9 / RATE))
        out.append(clock.now_ns())
        chip.push_sample((0.0, -9.80665, 0.0), (gyro * k / max(n, 1), 0.0, 0.0), 31.0)
    return out


def wait(chip: Lsm6dsoxModel, clock: VirtualClock, ns: int) -> None:
    """Time passes for both the chip and the host."""
    chip.advance(ns / 1e9)
    clock.advance_to(clock.now_ns() + ns)


def drain(imu: Lsm6dsox) -> list[ImuSample]:
    out = []
    while (s := imu.read()) is not None:
        out.append(s)
    return out


def test_start_configures_batching_timestamps_and_continuous_mode() -> None:
    imu, chip, _, _ = rig()
    assert chip.regs[reg.FIFO_CTRL3] == (0b0110 << 4) | 0b0110
    assert chip.regs[reg.FIFO_CTRL4] == (0b01 << 6) | (0b01 << 4) | 0b110
    assert chip.regs[reg.CTRL10_C] & reg.CTRL10_TIMESTAMP_EN
    assert imu.read() is None
    imu.stop()
    assert chip.regs[reg.FIFO_CTRL4] == 0 and not chip.fifo


def test_a_batch_comes_out_in_order_timed_by_the_chip() -> None:
    imu, chip, _, clock = rig()
    taken = push(chip, clock, 10)
    wait(chip, clock, 300_000)  # read 0.3 ms after the last sample
    got = drain(imu)
    assert len(got) == 10
    assert all(s.receive_ns == clock.now_ns() for s in got)  # one read
    t = np.array([s.sensor_ns for s in got])
    # spaced by the chip's period; the newest is mapped to when it was read (the
    # smallest delay seen so far)
    assert np.allclose(np.diff(t), 1e9 / RATE, atol=30e3)
    assert t[-1] == clock.now_ns()
    assert abs((t - np.array(taken)).std()) < 30e3
    assert got[-1].gyro[0] == pytest.approx(0.1 * 9 / 10, abs=imu.config.gyro_scale)
    assert got[0].accel[1] == pytest.approx(-9.80665, abs=imu.config.accel_scale)


def test_the_smallest_delay_is_kept_and_may_grow_slowly() -> None:
    imu, chip, _, clock = rig()
    push(chip, clock, 2)
    wait(chip, clock, 5_000_000)  # a late read: 5 ms
    late = drain(imu)
    push(chip, clock, 2)
    wait(chip, clock, 200_000)  # a prompt one: 0.2 ms
    prompt = drain(imu)
    taken = push(chip, clock, 2)
    wait(chip, clock, 5_000_000)
    again = drain(imu)
    assert late[-1].sensor_ns - late[-1].receive_ns == 0  # the only delay seen
    assert abs(prompt[-1].receive_ns - prompt[-1].sensor_ns) < 30_000  # the chip's ticks
    # the prompt read's delay stays: samples keep close to when they were taken
    assert abs(again[-1].sensor_ns - (taken[-1] + 200_000)) < 10_000


def test_the_chips_trimmed_clock_is_used() -> None:
    imu, chip, _, clock = rig(freq_fine=20)  # the chip's clock runs 3 % fast
    push(chip, clock, 20)
    got = drain(imu)
    assert np.allclose(np.diff([s.sensor_ns for s in got]), 1e9 / RATE, atol=30e3)


def test_the_32_bit_timestamp_wraps_without_a_jump() -> None:
    imu, chip, _, clock = rig()
    chip.set_ticks(2**32 - 40)
    push(chip, clock, 20)  # 96 ticks a sample: it wraps after the first
    got = drain(imu)
    assert len(got) == 20
    assert np.allclose(np.diff([s.sensor_ns for s in got]), 1e9 / RATE, atol=30e3)


def test_an_overrun_is_counted_and_reading_goes_on() -> None:
    imu, chip, _, clock = rig()
    push(chip, clock, 300)  # 3 words each: far more than 512
    got = drain(imu)
    assert imu.overruns == 1
    assert FIFO_WORDS // 3 - 2 <= len(got) <= FIFO_WORDS // 3 + 1
    t = [s.sensor_ns for s in got]
    assert t == sorted(t)
    push(chip, clock, 3)
    assert len(drain(imu)) == 3 and imu.overruns == 1


def test_a_full_fifo_is_drained_over_several_reads() -> None:
    imu, chip, bus, clock = rig()
    push(chip, clock, 100)
    before = bus.transfers
    first = imu.read()
    assert first is not None
    # one read took at most MAX_WORDS words: 1 status + MAX_WORDS / 4 blocks
    assert bus.transfers - before <= 1 + reg.MAX_WORDS // reg.WORDS_PER_BLOCK
    assert len(drain(imu)) == 99


def test_a_word_with_a_bad_parity_is_dropped() -> None:
    imu, chip, _, clock = rig()
    push(chip, clock, 5)
    chip.corrupt_next_tags = 1  # the first word: the first sample's gyro
    got = drain(imu)
    assert imu.parity_errors == 1 and len(got) == 4


def test_temperature_words_set_the_temperature() -> None:
    imu, chip, _, clock = rig()
    push(chip, clock, 3)
    got = drain(imu)
    assert got[-1].temperature_c == pytest.approx(31.0, abs=1 / 256)


def test_slots_without_a_timestamp_are_timed_by_the_rate() -> None:
    imu, chip, _, clock = rig()
    push(chip, clock, 2)
    chip.write(reg.FIFO_CTRL4, reg.FIFO_MODE_CONTINUOUS)  # no timestamp words from now
    push(chip, clock, 3)
    got = drain(imu)
    assert len(got) == 5
    assert np.allclose(np.diff([s.sensor_ns for s in got]), 1e9 / RATE, atol=30e3)


@pytest.mark.parametrize(
    ("err", "kind"), [(errno.EIO, DeviceError), (errno.ENXIO, DeviceNotFoundError)]
)
def test_read_errors_become_named_errors(err: int, kind: type[DeviceError]) -> None:
    imu, chip, bus, clock = rig()
    push(chip, clock, 5)
    bus.fail_after, bus.fail_errno = bus.transfers + 1, err  # the status read works
    with pytest.raises(kind, match="LSM6DSOX at 0x6A"):
        imu.read()


def test_a_short_block_is_an_error() -> None:
    imu, chip, bus, clock = rig()
    push(chip, clock, 2)
    bus.read_i2c_block_data = lambda a, r, n: [0] * (n - 1)  # type: ignore[method-assign]
    with pytest.raises(DeviceError, match="returned 1 bytes, expected 2"):
        imu.read()


class _Scripted:
    """A bus whose FIFO holds the given words (status and data reads only)."""

    def __init__(self, words: list[bytes]) -> None:
        self.data = b"".join(words)
        self.n = len(words)

    def read_byte_data(self, i2c_addr: int, register: int) -> int:
        return 0

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None:
        pass

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]:
        if register == reg.FIFO_STATUS1:
            return [self.n & 0xFF, (self.n >> 8) & 0x03]
        out, self.data = self.data[:length], self.data[length:]
        self.n -= length // 7
        return list(out.ljust(length, b"\0"))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(min_size=7, max_size=7), max_size=60))
def test_any_fifo_bytes_give_ordered_samples_or_none(words: list[bytes]) -> None:
    imu = Lsm6dsox(_Scripted(words), VirtualClock(T0), 0x6A, Lsm6dsoxConfig(rate_hz=RATE))
    got = drain(imu)
    t = [s.sensor_ns for s in got]
    assert t == sorted(t) and len(got) <= len(words) // 2


def test_fuzzed_words_keep_good_samples() -> None:
    good = []
    for k in range(4):
        good += [
            bytes([parity_tag(reg.TAG_GYRO, k)]) + struct.pack("<3h", 1, 2, 3),
            bytes([parity_tag(reg.TAG_ACCEL, k)]) + struct.pack("<3h", 0, -100, 0),
            bytes([parity_tag(reg.TAG_TIMESTAMP, k)]) + struct.pack("<IH", 1000 + 96 * k, 0),
        ]
    imu = Lsm6dsox(_Scripted(good), VirtualClock(T0), 0x6A, Lsm6dsoxConfig(rate_hz=RATE))
    got = drain(imu)
    assert len(got) == 4
    assert np.allclose(np.diff([s.sensor_ns for s in got]), 96 * 25_000, atol=1)
