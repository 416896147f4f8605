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


class LinkError(DeviceError):
    """The serial link to the device failed, or its SMP server refused a request."""


class LinkTimeoutError(LinkError):
    """The device did not answer a request in time: a frame lost to line noise, or no
    device (or no ``adaproj link``) on the other end. Sending it again may help."""


class LinkGarbledError(LinkError):
    """A reply from the device arrived damaged (bad CRC, cut short, another request's
    sequence number). Sending the request again may help."""


class ContentError(InputError):
    """Content refused by the device's store: a bad name, too big, not an image."""


class VideoError(ContentError):
    """A video clip cannot be used: not a video, unsupported codec, too large or long,
    no frames, truncated or corrupt."""


class ContentNotFoundError(ContentError):
    """No content item (or no pending upload) of that name on the device."""


class QuotaError(ContentError):
    """An upload would take the store past its quota or its item limit."""


class UploadOffsetError(ContentError):
    """An upload chunk is not at the end of the bytes received so far.

    ``expected`` is the offset the store can continue at; a client resumes there.
    """

    def __init__(self, message: str, expected: int) -> None:
        super().__init__(message)
        self.expected = expected
