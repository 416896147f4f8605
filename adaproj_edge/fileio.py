"""Durable file writes and checked image reads.

Nothing written to storage is ever half-written: every write goes to a temporary file
in the same directory, is fsynced, renamed into place, and the directory is fsynced.
Files are created as ``open()`` creates them (mode 0666 less the process's umask).
"""

from __future__ import annotations

import io
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge import MAX_IMAGE_PIXELS as MAX_IMAGE_PIXELS
from adaproj_edge.errors import ImageError, InputError

IMAGE_FORMATS = {".png": ".png", ".jpg": ".jpg", ".jpeg": ".jpg"}
"""File name extensions :func:`write_image` writes (lower case), and their encoders."""


def fsync_dir(directory: Path) -> None:
    """Make a rename in ``directory`` durable (no-op where directories cannot be opened)."""
    try:
        dfd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], Any]) -> None:
    """Call ``write(f)`` on a temporary file, then fsync and rename it to ``path``."""
    path = Path(path)
    directory = path.parent
    directory.mkdir(parents=True, exist_ok=True)
    fd, tmp = _create_temp(directory, path.name)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    fsync_dir(directory)


def _create_temp(directory: Path, name: str) -> tuple[int, Path]:
    """A new, empty temporary file for ``name`` in ``directory``, opened for writing.

    Made with ``O_EXCL`` and mode 0666, so the umask applies as to any new file (not
    ``mkstemp``'s 0600: the output of a command is the user's to share).
    """
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = directory / f".{name}.{secrets.token_hex(4)}.tmp"
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name for {name} in {directory}")


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`atomic_write`)."""
    atomic_write(path, lambda f: f.write(data))


def atomic_savez(path: str | os.PathLike[str], **arrays: Any) -> None:
    """Write a compressed ``.npz`` atomically."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def write_png(path: str | os.PathLike[str], image: NDArray[Any]) -> None:
    """Write an image (gray or BGR, uint8) as PNG atomically, whatever its name."""
    _write_encoded(path, image, ".png")


def write_image(path: str | os.PathLike[str], image: NDArray[Any]) -> None:
    """Write an image atomically, encoded as its name's extension says.

    Parameters
    ----------
    path : path
        Where to write; the extension picks the format (:data:`IMAGE_FORMATS`: PNG or
        JPEG).
    image : (H, W) or (H, W, 3) uint8 array
        Gray or BGR.

    Raises
    ------
    ImageError
        For any other extension (nothing is written).
    """
    ext = IMAGE_FORMATS.get(Path(path).suffix.lower())
    if ext is None:
        raise ImageError(
            f"cannot tell the image format of {path}: name it "
            + " or ".join(f"*{e}" for e in IMAGE_FORMATS)
        )
    _write_encoded(path, image, ext)


def _write_encoded(path: str | os.PathLike[str], image: NDArray[Any], ext: str) -> None:
    ok, enc = cv2.imencode(ext, np.ascontiguousarray(image))
    if not ok:
        raise ImageError(f"cannot encode image of shape {image.shape} as {ext}")
    atomic_write_bytes(path, enc.tobytes())


def decode_image(data: bytes, what: str, *, gray: bool = False) -> NDArray[np.uint8]:
    """Decode PNG/JPEG bytes into uint8 BGR (or gray), refusing decompression bombs.

    The size is read from the header as the decoder reads it (:func:`image_size`) and
    checked before a pixel is decoded; bytes whose size cannot be told that way (another
    format, a damaged header) are refused without decoding.
    """
    if not data:
        raise ImageError(f"{what} is empty")
    size = _header_size(data)
    if size is None:
        if data[:8] == b"\x89PNG\r\n\x1a\n" or data[:2] == b"\xff\xd8":
            raise ImageError(f"{what} is not a readable image (no size in its header)")
        raise ImageError(f"{what} is not a readable image (PNG or JPEG expected)")
    w, h = size
    if w * h > MAX_IMAGE_PIXELS:
        raise ImageError(f"{what} is {w}x{h} pixels, more than the {MAX_IMAGE_PIXELS} allowed")
    if w < 2 or h < 2:
        raise ImageError(f"{what} is only {w}x{h} pixels")
    flags = cv2.IMREAD_GRAYSCALE if gray else cv2.IMREAD_COLOR
    try:
        img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
    except cv2.error:  # OpenCV's own size limit (OPENCV_IO_MAX_IMAGE_PIXELS), a backstop
        img = None
    if img is None:
        raise ImageError(f"{what} is not a readable image (PNG or JPEG expected)")
    if img.shape[0] * img.shape[1] > MAX_IMAGE_PIXELS:
        raise ImageError(f"{what} has more than {MAX_IMAGE_PIXELS} pixels")
    return np.asarray(img, dtype=np.uint8)


def read_input(
    path: str | os.PathLike[str], what: str, error: type[InputError] = InputError
) -> bytes:
    """The bytes of ``path``; ``error`` naming ``what`` if it cannot be read."""
    path = Path(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise error(f"{what} not found: {path}") from None
    except IsADirectoryError:
        raise error(f"{what} {path} is a directory") from None
    except OSError as e:
        raise error(f"cannot read {what} {path}: {e.strerror}") from None


def load_npz(
    path: str | os.PathLike[str],
    what: str,
    required: tuple[str, ...],
    error: type[InputError] = InputError,
) -> dict[str, NDArray[Any]]:
    """All arrays of an ``.npz`` file, checked to contain ``required``.

    Any damage (not a zip, truncated, a corrupt member, pickled objects) is ``error``
    naming ``what``; the file is read whole first, so no handle is left open.
    """
    data = read_input(path, what, error)
    if not data.startswith(b"PK"):  # an .npz is a zip file; np.load would try pickle
        raise error(f"cannot read {what} {path}: not an .npz file (numpy's zip of arrays)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as f:
            arrays = {k: np.asarray(f[k]) for k in f.files}
    except Exception as e:  # zipfile, zlib, EOF, pickle refusals: all mean a damaged file
        raise error(f"cannot read {what} {path}: {type(e).__name__}: {e}") from None
    for key in required:
        if key not in arrays:
            raise error(f"{what} {path} has no {key!r} array")
    return arrays


def read_image(path: str | os.PathLike[str], *, gray: bool = False) -> NDArray[np.uint8]:
    """Read an image file with a clear error for every way it can fail."""
    return decode_image(read_input(path, "image", ImageError), str(path), gray=gray)


def image_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) read from the header of PNG or JPEG bytes, without decoding.

    ``None`` when ``data`` is neither format or its header is cut short.
    """
    return _header_size(data)


def _header_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG or JPEG header, None if it cannot be told cheaply."""
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        # libpng reads IHDR, which must be the first chunk
        if len(data) < 24 or data[12:16] != b"IHDR":
            return None
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    return None


_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""Start-of-frame markers (every coding process): the first one carries the size."""
_JPEG_STANDALONE = frozenset([0x01, *range(0xD0, 0xD8)])
"""Markers without a length (TEM, RST0..7)."""
_JPEG_SEGMENTS = frozenset([0xC4, 0xCC, 0xDB, 0xDC, 0xDD, 0xFE, *range(0xE0, 0xF0)])
"""Markers whose segment libjpeg skips by its length before the frame header: DHT,
DAC, DQT, DNL, DRI, COM and APP0..15."""


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) of the frame header libjpeg would read, or None where it would stop.

    Follows ``jdmarker.c``: after SOI, the next marker is found by skipping any bytes
    that are not 0xFF, then any number of 0xFF fill bytes (``FF 00`` is data, not a
    marker); segments are skipped by their length; the first SOF gives the size. SOS or
    EOI before a SOF, a second SOI, an unknown marker or a length below 2 end the
    header (the decoder refuses the file), and so does the end of the data.
    """
    n = len(data)
    i = 2
    while True:
        while True:  # next_marker()
            j = data.find(b"\xff", i)
            if j < 0:
                return None
            i = j + 1
            while i < n and data[i] == 0xFF:
                i += 1
            if i >= n:
                return None
            if data[i] != 0:
                break
            i += 1
        marker = data[i]
        i += 1
        if marker in _JPEG_SOF:
            if i + 7 > n:
                return None
            h = int.from_bytes(data[i + 3 : i + 5], "big")
            w = int.from_bytes(data[i + 5 : i + 7], "big")
            return w, h
        if marker in _JPEG_STANDALONE:
            continue
        if marker not in _JPEG_SEGMENTS or i + 2 > n:
            return None
        length = int.from_bytes(data[i : i + 2], "big")
        if length < 2:
            return None
        i += length
