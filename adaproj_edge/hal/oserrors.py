"""Turning OS errors into the named device errors, at the hardware boundary."""

from __future__ import annotations

import errno

from adaproj_edge.errors import DeviceError, DeviceNotFoundError, DevicePermissionError


def device_error(e: OSError, what: str, check: str) -> DeviceError:
    """The named error for an OS error raised while using device ``what``.

    ``check`` says what the person should look at (wiring, overlay, udev rule, ...).
    """
    if isinstance(e, FileNotFoundError) or e.errno in (errno.ENOENT, errno.ENODEV, errno.ENXIO):
        return DeviceNotFoundError(f"{what} is not there ({e.strerror or e}); check {check}")
    if isinstance(e, PermissionError) or e.errno in (errno.EACCES, errno.EPERM):
        return DevicePermissionError(
            f"no permission to use {what} ({e.strerror or e}); check the udev rule and that "
            "this user is in the device's group"
        )
    return DeviceError(f"{what} failed: {e.strerror or e} (errno {e.errno}); check {check}")
