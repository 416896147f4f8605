"""The ways ``adaproj doctor`` reaches each device, in one object tests replace.

Each probe goes through the real driver of :mod:`adaproj_edge.hal` (DepthAI for the
OAK-D, the LSM6DSOX driver on smbus2, the framebuffer display); paths under ``/dev``
and ``/sys`` go through a ``root`` prefix, as the drivers' own do, so tests point them
at a fake tree. The functions are looked up on their modules at each call, so a test
may also replace them there.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.hal import depth, display, lsm6dsox
from adaproj_edge.hal.depth import StereoSettings
from adaproj_edge.hal.lsm6dsox import SMBusLike


class Probes:
    """Probes of the board's devices, under ``root`` (``/`` on the device).

    Parameters
    ----------
    root : path
        Prefix of every ``/dev`` and ``/sys`` path.
    """

    def __init__(self, root: str | os.PathLike[str] = "/") -> None:
        self.root = Path(root)

    def path(self, device: str) -> Path:
        """Where a device path (``/dev/...``) is under the root."""
        return self.root / device.lstrip("/")

    def oak_devices(self) -> list[str]:
        """Ids of the OAK devices on USB (``ModuleNotFoundError`` without DepthAI)."""
        return depth.find_oak_devices()

    def oak_model(self, settings: StereoSettings) -> DepthCameraModel:
        """The depth camera model from the first OAK-D's own calibration."""
        return depth.read_oak_calibration(settings)

    def open_i2c(self, bus: int) -> SMBusLike:
        """The I2C bus ``bus`` (smbus2; ``ModuleNotFoundError`` without it)."""
        return lsm6dsox.open_i2c(bus)

    def framebuffer(self, device: str) -> display.FramebufferDisplay:
        """The projector's framebuffer, opened (close it after use)."""
        return display.FramebufferDisplay(device, root=self.root)

    def free_bytes(self, path: Path) -> int:
        """Free space for an unprivileged user on the file system holding ``path``."""
        return int(shutil.disk_usage(path).free)
