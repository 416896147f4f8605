"""The LSM6DSOX driver against the register model of the chip."""

from __future__ import annotations

import errno
import math

import pytest

from adaproj_edge.errors import DeviceError, DeviceNotFoundError, DevicePermissionError, InputError
from adaproj_edge.hal import lsm6dsox as reg
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.lsm6dsox import Lsm6dsox, Lsm6dsoxConfig
from tests.hal.lsm6dsox_model import FakeSMBus, Lsm6dsoxModel


def make(config: Lsm6dsoxConfig | None = None) -> tuple[Lsm6dsox, Lsm6dsoxModel, FakeSMBus]:
    chip = Lsm6dsoxModel()
    bus = FakeSMBus({0x6A: chip})
    return Lsm6dsox(bus, VirtualClock(5), 0x6A, config), chip, bus


def test_startup_resets_and_configures_the_chip() -> None:
    imu, chip, _ = make(Lsm6dsoxConfig(rate_hz=416.0, accel_range_g=8, gyro_range_dps=2000))
    chip.regs[reg.CTRL1_XL] = 0xFF  # left over from an earlier run: the reset clears it
    imu.start()
    assert chip.regs[reg.CTRL1_XL] == (0b0110 << 4) | (0b11 << 2)
    assert chip.regs[reg.CTRL2_G] == (0b0110 << 4) | (0b110 << 1)
    assert chip.regs[reg.CTRL3_C] == reg.CTRL3_BDU | reg.CTRL3_IF_INC


def test_no_data_before_the_first_sample() -> None:
    imu, _, _ = make()
    imu.start()
    assert imu.read() is None


@pytest.mark.parametrize("accel_g", [2, 4, 8, 16])
@pytest.mark.parametrize("gyro_dps", [125, 250, 500, 1000, 2000])
def test_scaling_to_si_units(accel_g: int, gyro_dps: int) -> None:
    imu, chip, _ = make(Lsm6dsoxConfig(accel_range_g=accel_g, gyro_range_dps=gyro_dps))
    imu.start()
    accel = (0.3, -9.80665, 1.7)
    gyro = (0.5, -0.02, 1.2)
    gyro = tuple(min(g, 0.9 * math.radians(gyro_dps)) for g in gyro)  # type: ignore[assignment]
    chip.push_sample(accel, gyro, 31.5)
    s = imu.read()
    assert s is not None and s.sensor_ns == 5
    a_lsb = imu.config.accel_scale
    g_lsb = imu.config.gyro_scale
    for got, want in zip(s.accel, accel, strict=True):
        assert got == pytest.approx(want, abs=a_lsb)
    for got, want in zip(s.gyro, gyro, strict=True):
        assert got == pytest.approx(want, abs=g_lsb)
    assert s.temperature_c == pytest.approx(31.5, abs=1 / 256)
    assert imu.read() is None  # the data-ready flags were cleared by the burst


def test_saturates_at_full_scale() -> None:
    imu, chip, _ = make(Lsm6dsoxConfig(accel_range_g=2))
    imu.start()
    chip.push_sample((50.0, 0.0, 0.0), (0.0, 0.0, 0.0), 25.0)
    s = imu.read()
    assert s is not None
    assert s.accel[0] == pytest.approx(32767 * imu.config.accel_scale)
    assert 2 * 9.8 < s.accel[0] < 2.1 * 9.81


def test_missing_chip_says_check_wiring_and_address() -> None:
    imu = Lsm6dsox(FakeSMBus({}), VirtualClock(), 0x6B, bus_name="/dev/i2c-1")
    with pytest.raises(DeviceNotFoundError, match=r"0x6B on /dev/i2c-1.*wiring.*address"):
        imu.start()


def test_wrong_chip_says_check_wiring_and_address() -> None:
    imu, chip, _ = make()
    chip.regs[reg.WHO_AM_I] = 0x6A  # an LSM6DSL answers here
    with pytest.raises(DeviceError, match=r"WHO_AM_I = 0x6A, expected 0x6C.*wiring.*address"):
        imu.start()


def test_reset_that_never_finishes() -> None:
    imu, chip, _ = make()
    chip.stuck_in_reset = True
    with pytest.raises(DeviceError, match="software reset"):
        imu.start()


def test_configuration_that_does_not_stick() -> None:
    imu, chip, _ = make()
    orig = chip.write

    def drop_ctrl2(register: int, value: int) -> None:
        if register != reg.CTRL2_G:
            orig(register, value)

    chip.write = drop_ctrl2  # type: ignore[method-assign]
    with pytest.raises(DeviceError, match=r"register 0x11 reads 0x00"):
        imu.start()


@pytest.mark.parametrize(
    ("err", "kind"),
    [
        (errno.EIO, DeviceError),
        (errno.EREMOTEIO, DeviceNotFoundError),
        (errno.EACCES, DevicePermissionError),
        (errno.ETIMEDOUT, DeviceError),
    ],
)
def test_io_errors_during_reads_become_named_errors(err: int, kind: type[DeviceError]) -> None:
    imu, chip, bus = make()
    imu.start()
    chip.push_sample((0.0, 0.0, 9.8), (0.0, 0.0, 0.0), 25.0)
    bus.fail_after, bus.fail_errno = bus.transfers, err
    with pytest.raises(kind, match="LSM6DSOX at 0x6A"):
        imu.read()


def test_io_error_during_configuration() -> None:
    imu, _, bus = make()
    bus.fail_after = 3
    with pytest.raises(DeviceError, match="check the IMU wiring"):
        imu.start()


def test_short_burst_is_an_error() -> None:
    imu, _, bus = make(Lsm6dsoxConfig(fifo=False))
    imu.start()
    bus.read_i2c_block_data = lambda a, r, n: [0] * (n - 1)  # type: ignore[method-assign]
    with pytest.raises(DeviceError, match="returned 15 bytes"):
        imu.read()


def test_burst_needs_auto_increment() -> None:
    """Without IF_INC the chip repeats one register; the driver must set it."""
    chip = Lsm6dsoxModel()
    chip.write(reg.CTRL3_C, 0x00)
    assert chip.read_block(reg.WHO_AM_I, 3) == [0x6C, 0x6C, 0x6C]
    imu = Lsm6dsox(FakeSMBus({0x6A: chip}), VirtualClock())
    imu.start()
    assert chip.regs[reg.CTRL3_C] & reg.CTRL3_IF_INC


def test_stop_and_close() -> None:
    imu, chip, bus = make()
    imu.start()
    imu.stop()
    assert chip.regs[reg.CTRL1_XL] == 0 and chip.regs[reg.CTRL2_G] == 0
    imu.close()
    assert bus.closed


@pytest.mark.parametrize(
    "kwargs", [{"rate_hz": 100.0}, {"accel_range_g": 3}, {"gyro_range_dps": 4000}]
)
def test_invalid_configuration(kwargs: dict[str, float]) -> None:
    with pytest.raises(InputError):
        Lsm6dsoxConfig(**kwargs)  # type: ignore[arg-type]


def test_open_missing_bus() -> None:
    with pytest.raises(DeviceNotFoundError, match="I2C is enabled"):
        reg.open_i2c(97)
