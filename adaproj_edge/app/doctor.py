"""``adaproj doctor``'s checks: is every device of the board there and answering, is the
calibration the unit's own and good, is there room for content; and for each failure,
what to do.

Every device is reached through :class:`~adaproj_edge.hal.probes.Probes` (the real
drivers; tests pass a fake tree and stand-ins). A check gives a :class:`Finding`;
``fail`` means the projector cannot run as it should, ``warn`` that it runs with less
(the nominal calibration, an acceptable one).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from adaproj_edge.errors import AdaprojError, DeviceError, DevicePermissionError
from adaproj_edge.extras import DEVICE
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.clock import MonotonicClock
from adaproj_edge.hal.lsm6dsox import Lsm6dsox
from adaproj_edge.hal.probes import Probes

Status = Literal["ok", "warn", "fail"]

MIN_FREE_BYTES = 512 * 1024 * 1024
"""Free space the content store needs (clips up to 1920x1080 and 300 s fit)."""

GROUP_FIX = "add the user to group {group} (sudo usermod -aG {group} $USER; log in again)"


@dataclass(frozen=True)
class Finding:
    """The outcome of one check.

    Attributes
    ----------
    what : str
        What was checked ("depth camera").
    status : {"ok", "warn", "fail"}
        How it went.
    detail : str
        What was found, in a line.
    fix : str
        What to do about it ("" when nothing is to be done).
    """

    what: str
    status: Status
    detail: str
    fix: str = ""


def _permission_or(e: DeviceError, group: str, otherwise: str) -> str:
    return GROUP_FIX.format(group=group) if isinstance(e, DevicePermissionError) else otherwise


def check_depth(board: Board, probes: Probes) -> Finding:
    """The OAK-D: DepthAI finds it on USB, and its own calibration reads."""
    what = "depth camera"
    try:
        ids = probes.oak_devices()
    except ModuleNotFoundError:
        return Finding(what, "fail", "DepthAI is not installed", DEVICE.install)
    if not ids:
        return Finding(
            what,
            "fail",
            "no OAK-D found on USB",
            "plug the OAK-D into a blue USB 3 port; copy hw/udev/80-adaproj-oakd.rules to "
            "/etc/udev/rules.d/, run `sudo udevadm control --reload && sudo udevadm "
            "trigger` and plug it in again",
        )
    try:
        model = probes.oak_model(board.depth)
    except DeviceError as e:
        return Finding(
            what,
            "fail",
            f"OAK-D {ids[0]} found, but its calibration does not read: {e}",
            _permission_or(
                e, "plugdev", "plug it in again; if it stays, stop adaproj.service (it holds it)"
            ),
        )
    fx = float(model.K[0, 0])
    return Finding(
        what,
        "ok",
        f"OAK-D {ids[0]}: calibration read ({model.width}x{model.height}, focal "
        f"{fx:.0f} px, baseline {model.baseline_m * 100:.1f} cm)",
    )


def check_imu(board: Board, probes: Probes) -> Finding:
    """The IMU on I2C: the bus is there and the chip answers WHO_AM_I as an LSM6DSOX."""
    what = "IMU"
    dev = f"/dev/i2c-{board.imu.bus}"
    if not probes.path(dev).exists():
        return Finding(
            what,
            "fail",
            f"{dev} is not there: I2C is off",
            "add dtparam=i2c_arm=on to /boot/firmware/config.txt and i2c-dev to "
            "/etc/modules, then reboot",
        )
    try:
        bus = probes.open_i2c(board.imu.bus)
    except ModuleNotFoundError:
        return Finding(what, "fail", "smbus2 is not installed", DEVICE.install)
    except DeviceError as e:
        return Finding(what, "fail", str(e), _permission_or(e, "i2c", "check the I2C bus"))
    imu = Lsm6dsox(bus, MonotonicClock(), board.imu.address, board.imu.config, dev)
    try:
        chip = imu.identify()
    except DeviceError as e:
        fix = _permission_or(
            e,
            "i2c",
            f"check the wiring (SDA to GPIO2, SCL to GPIO3, 3V3, GND); `i2cdetect -y "
            f"{board.imu.bus}` shows {board.imu.address:02x} when the chip answers",
        )
        return Finding(what, "fail", str(e), fix)
    finally:
        close: Callable[[], None] | None = getattr(bus, "close", None)
        if close is not None:
            close()
    return Finding(
        what, "ok", f"LSM6DSOX at 0x{board.imu.address:02X} on {dev} (WHO_AM_I 0x{chip:02X})"
    )


def check_display(board: Board, calibration: Calibration | None, probes: Probes) -> Finding:
    """The projector's framebuffer: it opens, and its mode is the calibration's size."""
    what = "display"
    try:
        fb = probes.framebuffer(board.display_device)
    except DeviceError as e:
        fix = _permission_or(
            e, "video", "connect the projector to the HDMI port nearest the power input and reboot"
        )
        return Finding(what, "fail", str(e), fix)
    (w, h), bpp = fb.size, fb.bits_per_pixel
    fb.close()
    found = f"{board.display_device}: {w}x{h}, {bpp} bits per pixel"
    if calibration is not None:
        want = (calibration.projector.width, calibration.projector.height)
        if (w, h) != want:
            return Finding(
                what,
                "fail",
                f"{found}; the calibration is for {want[0]}x{want[1]}",
                f"set the mode: add video=HDMI-A-1:{want[0]}x{want[1]}@60 to "
                "/boot/firmware/cmdline.txt and reboot",
            )
    return Finding(what, "ok", found)


def _device_file(what: str, path: Path, device: str, missing: str, fix: str, group: str) -> Finding:
    if not path.exists():
        return Finding(what, "fail", f"{device} is not there: {missing}", fix)
    if not os.access(path, os.R_OK | os.W_OK):
        return Finding(what, "fail", f"{device}: no permission", GROUP_FIX.format(group=group))
    return Finding(what, "ok", f"{device} is there")


def check_serial(board: Board, probes: Probes) -> Finding:
    """The USB gadget's serial port, which the content link uses."""
    return _device_file(
        "USB serial link",
        probes.path(board.serial_device),
        board.serial_device,
        "the USB gadget is not up",
        "sudo systemctl start adaproj-gadget.service (it needs dtoverlay=dwc2,"
        "dr_mode=peripheral in /boot/firmware/config.txt and dwc2 and libcomposite in "
        "/etc/modules); `journalctl -u adaproj-gadget` says why it stopped",
        "dialout",
    )


def check_button(board: Board, probes: Probes) -> Finding:
    """The button's input event device (gpio-keys)."""
    return _device_file(
        "button",
        probes.path(board.button_device),
        board.button_device,
        "no gpio-keys device",
        "add dtoverlay=gpio-key,gpio=17,active_low=1,gpio_pull=up,keycode=28 to "
        "/boot/firmware/config.txt and reboot",
        "input",
    )


def check_calibration(board: Board, path: Path) -> tuple[Finding, Calibration | None]:
    """The calibration in use: it loads, and its verdict (a nominal file has none)."""
    what = "calibration"
    try:
        cal = Calibration.load(path)
    except AdaprojError as e:
        fix = f"run `adaproj calibrate`, or move {path} away to run with the nominal one"
        return Finding(what, "fail", f"{path}: {e}", fix), None
    except OSError as e:
        return Finding(what, "fail", f"{path}: {e.strerror or e}", "check the path"), None
    quality = cal.quality or {}
    verdict = str(quality.get("verdict", ""))
    if not verdict:
        return Finding(
            what,
            "warn",
            f"{path}: nominal values, not measured on this unit",
            "point the device at a wall corner and run `adaproj calibrate` (or hold the "
            "button 5 s while it runs)",
        ), cal
    rms = quality.get("rms_px")
    found = f"{path}: {verdict}" + (f", reprojection RMS {float(rms):.2f} px" if rms else "")
    if verdict == "good":
        return Finding(what, "ok", found), cal
    return Finding(
        what, "warn", found, "calibrate again, at more poses and distances (`adaproj calibrate`)"
    ), cal


def check_disk(store: Path, probes: Probes) -> Finding:
    """Free space on the file system that holds (or will hold) the content store."""
    what = "disk"
    place = store
    while not place.exists() and place != place.parent:
        place = place.parent
    free = probes.free_bytes(place)
    found = f"{free / 2**30:.1f} GiB free for the content store {store}"
    if free < MIN_FREE_BYTES:
        return Finding(
            what,
            "fail",
            found,
            f"free at least {MIN_FREE_BYTES // 2**20} MiB (`sudo apt clean`, old recordings), "
            "or pass --store on a larger disk",
        )
    return Finding(what, "ok", found)


def examine(board: Board, calibration_path: Path, store: Path, probes: Probes) -> list[Finding]:
    """Every check, in the order they are shown.

    Parameters
    ----------
    board : Board
        The board file's description of the devices.
    calibration_path : Path
        The calibration ``adaproj run`` would use.
    store : Path
        The content store.
    probes : Probes
        How the devices are reached.

    Returns
    -------
    list of Finding
        Depth camera, IMU, display, USB serial link, button, calibration, disk.
    """
    calibration, cal = check_calibration(board, calibration_path)
    return [
        check_depth(board, probes),
        check_imu(board, probes),
        check_display(board, cal, probes),
        check_serial(board, probes),
        check_button(board, probes),
        calibration,
        check_disk(store, probes),
    ]
