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
    compensate = false         # even out the projector's light over the picture (a gain
                               # made from the surface: docs/photometry.md)
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
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from adaproj_edge import checks
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
    """The projector's framebuffer, its refresh rate (Hz), the stabilisation margin
    (a fraction of the frame's width and height on each side; 0 turns it off) and
    whether frames carry the brightness gain made from the surface."""

    device: str = "/dev/fb0"
    refresh_hz: float = 60.0
    stabilise_margin: float = 0.04
    compensate: bool = False

    def __post_init__(self) -> None:
        checks.text(self.device, "device")
        checks.number(self.refresh_hz, "refresh_hz", 1.0, 1000.0)
        checks.number(self.stabilise_margin, "stabilise_margin", 0.0, 0.2)
        checks.flag(self.compensate, "compensate")


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
        except RecursionError:
            raise InputError(f"cannot read board file {p}: values nested too deeply") from None
        except FileNotFoundError:
            known = ", ".join(sorted(b.stem for b in boards_dir().glob("*.toml")))
            raise InputError(f"board file not found: {p} (boards: {known})") from None
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise InputError(f"cannot read board file {p}: {e}") from None
        with field_errors(f"board file {p}"):
            return _parse(data, p)


def _pick(cls: Any, table: dict[str, Any]) -> dict[str, Any]:
    return _known(table, {f.name for f in fields(cls)})


def _known(table: dict[str, Any], names: set[str]) -> dict[str, Any]:
    unknown = set(table) - names
    if unknown:
        raise InputError(f"unknown keys {sorted(unknown)} (known: {sorted(names)})")
    return table


SECTIONS = ("imu", "button", "display", "depth", "serial", "calibrate")
"""The board file's tables."""


@contextmanager
def _section(name: str) -> Iterator[None]:
    """Name the table ``[name]`` in any error raised while it is read."""
    try:
        yield
    except KeyError as e:
        raise InputError(f"[{name}] missing field {e.args[0]!r}") from None
    except InputError as e:
        raise InputError(f"[{name}] {e}") from None


def _table(data: dict[str, Any], name: str, required: bool = False) -> dict[str, Any]:
    if name not in data and not required:
        return {}
    table = data[name]
    if not isinstance(table, dict):
        raise InputError(f"[{name}] must be a table, got {type(table).__name__}")
    return dict(table)


def _parse(data: dict[str, Any], path: Path) -> Board:
    _known(data, {"name", "calibration", *SECTIONS})
    name = checks.text(data["name"], "name")
    calibration = checks.text(data["calibration"], "calibration")
    with _section("imu"):
        imu = _table(data, "imu", required=True)
        chip = checks.text(imu.pop("chip", "lsm6dsox"), "chip")
        if chip != "lsm6dsox":
            raise InputError(f"IMU chip {chip!r} has no driver (supported: lsm6dsox)")
        bus = checks.integer(imu.pop("bus"), "bus", 0, MAX_I2C_BUS)
        address = checks.integer(imu.pop("address", ADDRESSES[0]), "address", 0, 0x7F)
        if address not in ADDRESSES:
            raise InputError(f"LSM6DSOX address 0x{address:02X} is not 0x6A or 0x6B")
        config = Lsm6dsoxConfig(**_pick(Lsm6dsoxConfig, imu))
    with _section("button"):
        button = _table(data, "button", required=True)
        _known(button, {"device", "key_code"})
        button_device = checks.text(button["device"], "device")
        key_code = check_key_code(checks.integer(button["key_code"], "key_code", 1, 0x2FF))
    with _section("display"):
        display = DisplayConfig(**_pick(DisplayConfig, _table(data, "display")))
    with _section("serial"):
        serial = _table(data, "serial")
        _known(serial, {"device"})
        serial_device = checks.text(serial.get("device", "/dev/ttyGS0"), "device")
    with _section("depth"):
        depth = StereoSettings(**_pick(StereoSettings, _table(data, "depth")))
    with _section("calibrate"):
        camera = CameraSettings(**_pick(CameraSettings, _table(data, "calibrate")))
    return Board(
        name=name,
        calibration_path=(path.parent / calibration).resolve(),
        imu=ImuSettings(chip, bus, address, config),
        button_device=button_device,
        key_code=key_code,
        display=display,
        serial_device=serial_device,
        depth=depth,
        camera=camera,
    )


MAX_I2C_BUS = 1023
"""The highest I2C bus number taken (``/dev/i2c-N``)."""


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
