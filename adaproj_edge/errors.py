"""The one exception tree of adaproj-edge.

Every error the product raises on purpose derives from :class:`AdaprojError`; the
command line turns any of them into one clear message and a non-zero exit.
"""

from __future__ import annotations


class AdaprojError(Exception):
    """Root of every error adaproj-edge raises on purpose."""


class InputError(AdaprojError):
    """Input from outside (a file, an argument, a message) is missing or malformed."""


class SurfaceError(InputError):
    """A surface cannot be used: wrong shapes, too few valid points, out of range."""


class ImageError(InputError):
    """An image or mask cannot be read or has unusable dimensions."""


class MaskError(ImageError):
    """A user mask cannot be used (unreadable, wrong shape); the content stays usable."""


class ModelError(InputError):
    """A saliency model file is missing, unloadable or does not meet the model contract."""


class WarpError(AdaprojError):
    """The warp could not be computed for the given surface and content."""


class DeviceError(AdaprojError):
    """A hardware device failed; the message says what to check."""


class DeviceNotFoundError(DeviceError):
    """A device file or bus address is not there."""


class DevicePermissionError(DeviceError):
    """A device exists but this process may not open it."""
