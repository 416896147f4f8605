"""Board files (``hw/boards/<board>.toml``): which devices a board uses, and where.

Format::

    name = "rpi5-oakd"
    calibration = "../calibration/rpi5-oakd.toml"   # relative to the board file
    [imu]
    chip = "lsm6dsox"
    bus = 1                # /dev/i2c-1
    address = 0x6A
    rate_hz = 208.0
    accel_range_g = 4
    gyro_range_dps = 500
    [button]
    device = "/dev/input/by-path/platform-gpio-keys-event"
    key_code = 28          # KEY_ENTER, as set in the gpio-keys overlay
    [display]
    device = "/dev/fb0"
    [depth]                # any field of StereoSettings
    fps = 15.0
    [serial]
    device = "/dev/ttyGS0"
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, field_errors
from adaproj_edge.hal.button import check_key_code
from adaproj_edge.hal.depth import StereoSettings
from adaproj_edge.hal.lsm6dsox import ADDRESSES, Lsm6dsoxConfig
from adaproj_edge.resources import boards_dir


@dataclass(frozen=True)
class ImuSettings:
    chip: str = "lsm6dsox"
    bus: int = 1
    address: int = ADDRESSES[0]
    config: Lsm6dsoxConfig = field(default_factory=Lsm6dsoxConfig)


@dataclass(frozen=True)
class Board:
    """The devices of one board; paths are as on the device (``/dev/...``)."""

    name: str
    calibration_path: Path
    imu: ImuSettings
    button_device: str
    key_code: int
    display_device: str
    serial_device: str
    depth: StereoSettings

    def calibration(self) -> Calibration:
        return Calibration.load(self.calibration_path)

    @classmethod
    def load(cls, path: str | Path) -> Board:
        """Read a board file by path, or by name from ``hw/boards``."""
        p = Path(path)
        if not p.suffix and not p.exists():
            p = boards_dir() / f"{p}.toml"
        try:
            data = tomllib.loads(p.read_text())
        except FileNotFoundError:
            known = ", ".join(sorted(b.stem for b in boards_dir().glob("*.toml")))
            raise InputError(f"board file not found: {p} (boards: {known})") from None
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise InputError(f"cannot read board file {p}: {e}") from None
        with field_errors(f"board file {p}"):
            return _parse(data, p)


def _pick(cls: Any, table: dict[str, Any]) -> dict[str, Any]:
    names = {f.name for f in fields(cls)}
    unknown = set(table) - names
    if unknown:
        raise InputError(f"unknown keys {sorted(unknown)} (known: {sorted(names)})")
    return table


def _parse(data: dict[str, Any], path: Path) -> Board:
    imu = dict(data["imu"])
    chip = imu.pop("chip", "lsm6dsox")
    if chip != "lsm6dsox":
        raise InputError(f"IMU chip {chip!r} has no driver (supported: lsm6dsox)")
    bus, address = int(imu.pop("bus")), int(imu.pop("address", ADDRESSES[0]))
    if address not in ADDRESSES:
        raise InputError(f"LSM6DSOX address 0x{address:02X} is not 0x6A or 0x6B")
    config = Lsm6dsoxConfig(**_pick(Lsm6dsoxConfig, imu))
    return Board(
        name=str(data["name"]),
        calibration_path=(path.parent / str(data["calibration"])).resolve(),
        imu=ImuSettings(chip, bus, address, config),
        button_device=str(data["button"]["device"]),
        key_code=check_key_code(int(data["button"]["key_code"])),
        display_device=str(data.get("display", {}).get("device", "/dev/fb0")),
        serial_device=str(data.get("serial", {}).get("device", "/dev/ttyGS0")),
        depth=StereoSettings(**_pick(StereoSettings, dict(data.get("depth", {})))),
    )
