"""The content check: what the store accepts as an image or a clip, and its limits.

Used twice: by the device's store before an upload is committed, and by ``adaproj
push`` on the host before a byte is sent, so a bad file is refused with the same
message on both sides.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from adaproj_edge.content.video import VideoLimits, check_video, check_video_head, is_video_name
from adaproj_edge.errors import ImageError
from adaproj_edge.fileio import MAX_IMAGE_PIXELS, decode_image
from adaproj_edge.fileio import image_size as header_size

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"
HEAD = 32
"""Bytes of a file's start checked before anything is written (magic, PNG size)."""


@dataclass(frozen=True)
class Limits:
    """What the store accepts.

    Attributes
    ----------
    quota : int
        Bytes of committed items plus the declared sizes of pending uploads.
    max_items : int
        Committed items at most.
    max_file : int
        Bytes of one item at most.
    max_pixels : int
        Width times height at most, read from the header before decoding.
    max_side : int
        Width and height at most.
    video : VideoLimits
        What a clip may be (size, rate, frames, duration).
    """

    quota: int = 256 * 2**20
    max_items: int = 256
    max_file: int = 64 * 2**20
    max_pixels: int = MAX_IMAGE_PIXELS
    max_side: int = 16384
    video: VideoLimits = field(default_factory=VideoLimits)


def check_head(head: bytes, what: str, limits: Limits) -> None:
    """Refuse bytes that do not start like a PNG or JPEG, or whose header is too big."""
    if not (head.startswith(PNG_MAGIC) or head.startswith(JPEG_MAGIC)):
        raise ImageError(f"{what} is not a PNG or JPEG image")
    size = header_size(head)
    if size is not None:
        check_dimensions(size, what, limits)


def check_dimensions(size: tuple[int, int], what: str, limits: Limits) -> None:
    w, h = size
    if w * h > limits.max_pixels:
        raise ImageError(
            f"{what} is {w}x{h} pixels, more than the {limits.max_pixels} allowed "
            "(refused before decoding)"
        )
    if w > limits.max_side or h > limits.max_side or w < 2 or h < 2:
        raise ImageError(f"{what} is {w}x{h} pixels; each side must be 2..{limits.max_side}")


def check_image(data: bytes, what: str, limits: Limits) -> None:
    """Refuse anything but a whole, decodable PNG or JPEG of acceptable size."""
    check_head(data[:HEAD], what, limits)
    size = header_size(data)
    if size is None:
        raise ImageError(f"{what}: cannot read the image size from its header")
    check_dimensions(size, what, limits)
    decode_image(data, what)


def check_content_head(head: bytes, name: str, limits: Limits) -> None:
    """Refuse a file start that is not what ``name`` says: a PNG/JPEG (with an
    acceptable header size) for an image name, the named container for a clip."""
    if is_video_name(name):
        check_video_head(head, name)
    else:
        check_head(head, name, limits)


def check_content(path: Path, name: str, limits: Limits) -> None:
    """Refuse a whole file that is not usable content of the kind ``name`` says.

    An image is decoded whole (:func:`check_image`); a clip is probed, checked against
    ``limits.video`` and its first and last frames decoded
    (:func:`~adaproj_edge.content.video.check_video`).

    Raises
    ------
    ImageError, VideoError
        With the reason, naming ``name``.
    """
    if is_video_name(name):
        check_video_head(path.read_bytes()[:HEAD], name)
        check_video(path, name, limits.video)
    else:
        check_image(path.read_bytes(), name, limits)
