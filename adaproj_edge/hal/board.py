"""Board files (``hw/boards/<board>.toml``): which devices a board uses, and where.

Format::

    name = "rpi5-oakd"
    calibration = "../calibration/rpi5-oakd.toml"   # relative to the board file
    [imu]
    chip = "lsm6dsox"
    bus = 1                # /dev/i2c-1
    address = 0x6A
    rate_hz = 416.0
    accel_range_g = 4
    gyro_range_dps = 500
    [button]
    device = "/dev/input/by-path/platform-gpio-keys-event"
    key_code = 28          # KEY_ENTER, as set in the gpio-keys overlay
    [display]
    device = "/dev/fb0"
    refresh_hz = 60.0          # used when the driver cannot wait for vertical sync
    stabilise_margin = 0.04    # room for image stabilisation, of the frame per side; 0: off
    [depth]                # any field of StereoSettings
    fps = 15.0
    [serial]
    device = "/dev/ttyGS0"
    [calibrate]            # optional: `adaproj calibrate`, any field of CameraSettings
                           # (not [calibration]: that name is the key above)
    socket = "CAM_A"       # the camera depth is aligned to ([depth] align_to)
    width = 1280           # its frames for the structured light
    height = 800
    fps = 30.0
    exposure_us = 8000     # fixed exposure and sensitivity: lower them when the
    iso = 400              # white pattern saturates
    display_latency_ms = 100.0   # Display.show -> pattern on the wall
    camera_latency_ms = 60.0     # end of exposure -> frame on the host

The calibration a board runs with: ``adaproj run --calibration FILE``, else the
device's own file written by ``adaproj calibrate`` (:data:`DEVICE_CALIBRATION`)
when there is one, else the board's nominal ``calibration`` file
(:func:`calibration_in_use`).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, field_errors
from adaproj_edge.hal.button import check_key_code
from adaproj_edge.hal.camera import CameraSettings
from adaproj_edge.hal.depth import StereoSettings
from adaproj_edge.hal.lsm6dsox import ADDRESSES, Lsm6dsoxConfig
from adaproj_edge.resources import DEVICE_CALIBRATION, boards_dir

"""Where ``adaproj calibrate`` writes a unit's own calibration on the device, and
where ``adaproj run`` looks for it first."""


@dataclass(frozen=True)
class ImuSettings:
    """The board's IMU: chip name, I2C bus number, address and chip configuration."""

    chip: str = "lsm6dsox"
    bus: int = 1
    address: int = ADDRESSES[0]
    config: Lsm6dsoxConfig = field(default_factory=Lsm6dsoxConfig)


@dataclass(frozen=True)
class DisplayConfig:
    """The projector's framebuffer, its refresh rate (Hz) and the stabilisation margin
    (a fraction of the frame's width and height on each side; 0 turns it off)."""

    device: str = "/dev/fb0"
    refresh_hz: float = 60.0
    stabilise_margin: float = 0.04

    def __post_init__(self) -> None:
        if not 1.0 <= self.refresh_hz <= 1000.0:
            raise InputError(f"display refresh_hz must be in [1, 1000], got {self.refresh_hz}")
        if not 0.0 <= self.stabilise_margin <= 0.2:
            raise InputError(
                f"display stabilise_margin must be in [0, 0.2], got {self.stabilise_margin}"
            )


@dataclass(frozen=True)
class Board:
    """The devices of one board; paths are as on the device (``/dev/...``)."""

    name: str
    calibration_path: Path
    imu: ImuSettings
    button_device: str
    key_code: int
    serial_device: str
    depth: StereoSettings
    camera: CameraSettings = field(default_factory=CameraSettings)
    display: DisplayConfig = field(default_factory=DisplayConfig)

    @property
    def display_device(self) -> str:
        """The projector's framebuffer device."""
        return self.display.device

    def calibration(self) -> Calibration:
        """The calibration loaded from :attr:`calibration_path`."""
        return Calibration.load(self.calibration_path)

    def with_calibration(self, path: str | Path) -> Board:
        """The same board running with the calibration file ``path``."""
        return replace(self, calibration_path=Path(path))

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
        display=DisplayConfig(**_pick(DisplayConfig, dict(data.get("display", {})))),
        serial_device=str(data.get("serial", {}).get("device", "/dev/ttyGS0")),
        depth=StereoSettings(**_pick(StereoSettings, dict(data.get("depth", {})))),
        camera=CameraSettings(**_pick(CameraSettings, dict(data.get("calibrate", {})))),
    )


def calibration_in_use(
    board: Board, explicit: str | Path | None = None, device_file: Path = DEVICE_CALIBRATION
) -> Path:
    """The calibration file ``board`` runs with: ``explicit`` when given, else the
    unit's own ``device_file`` when it exists, else the board's nominal file."""
    if explicit is not None:
        return Path(explicit)
    if device_file.is_file():
        return device_file
    return board.calibration_path
