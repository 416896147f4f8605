"""The projector as a Linux framebuffer (``/dev/fb0``), and an in-memory stand-in.

The pixel layout comes from sysfs (``/sys/class/graphics/fb0``: ``virtual_size``,
``bits_per_pixel``, ``stride``); the device node is memory-mapped and each frame is
converted once (BGR -> XRGB8888, BGR888 or RGB565) and copied in row by row. Every
path goes through a ``root`` prefix, so tests point the driver at a fake tree.
"""

from __future__ import annotations

import mmap
import os
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import DeviceError, InputError
from adaproj_edge.hal.oserrors import device_error

Frame = NDArray[np.uint8]
_CHECK = "that the projector is connected and the framebuffer driver is loaded"


class Display(Protocol):
    """Where projector frames go."""

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        ...

    def show(self, frame: Frame) -> None:
        """Show a (height, width, 3) BGR uint8 frame."""
        ...

    def close(self) -> None: ...


class MemoryDisplay:
    """Keeps the last frame shown (and how many), for tests and replays."""

    def __init__(self, width: int = 1280, height: int = 800) -> None:
        self._size = (width, height)
        self.last: Frame | None = None
        self.count = 0

    @property
    def size(self) -> tuple[int, int]:
        return self._size

    def show(self, frame: Frame) -> None:
        _check_frame(frame, self._size)
        if self.last is not None and self.last.shape == frame.shape:
            np.copyto(self.last, frame)  # one buffer: no fresh pages for every frame
        else:
            self.last = frame.copy()
        self.count += 1

    def close(self) -> None:
        pass


def _read_sys(path: Path) -> str:
    try:
        return path.read_text().strip()
    except OSError as e:
        raise device_error(e, f"framebuffer attribute {path}", _CHECK) from None


def _check_frame(frame: Frame, size: tuple[int, int]) -> None:
    w, h = size
    if frame.shape != (h, w, 3) or frame.dtype != np.uint8:
        raise InputError(
            f"display frames must be ({h}, {w}, 3) uint8 BGR, got {frame.shape} {frame.dtype}"
        )


def to_pixels(frame: Frame, bits_per_pixel: int) -> NDArray[np.uint8]:
    """Convert a BGR frame (h, w, 3) to framebuffer bytes (h, w * bytes_per_pixel)."""
    h, w, _ = frame.shape
    if bits_per_pixel == 32:
        out = np.empty((h, w, 4), np.uint8)
        out[..., :3] = frame  # little-endian XRGB8888 is B, G, R, X in memory
        out[..., 3] = 255
    elif bits_per_pixel == 24:
        out = np.ascontiguousarray(frame)
    elif bits_per_pixel == 16:
        b = frame[..., 0].astype(np.uint16) >> 3
        g = frame[..., 1].astype(np.uint16) >> 2
        r = frame[..., 2].astype(np.uint16) >> 3
        out = ((r << 11) | (g << 5) | b).astype("<u2").view(np.uint8).reshape(h, w, 2)
    else:
        raise DeviceError(f"framebuffer with {bits_per_pixel} bits per pixel is not supported")
    return out.reshape(h, -1)


class FramebufferDisplay:
    """The projector on ``/dev/fbN``, memory-mapped."""

    def __init__(self, device: str = "/dev/fb0", root: str | os.PathLike[str] = "/") -> None:
        root = Path(root)
        name = Path(device).name
        sysdir = root / "sys/class/graphics" / name
        try:
            w, h = (int(x) for x in _read_sys(sysdir / "virtual_size").split(","))
            self.bits_per_pixel = int(_read_sys(sysdir / "bits_per_pixel"))
            stride_path = sysdir / "stride"
            self.stride = (
                int(_read_sys(stride_path))
                if stride_path.exists()
                else w * self.bits_per_pixel // 8
            )
        except ValueError:
            raise DeviceError(
                f"unreadable framebuffer attributes in {sysdir}; check {_CHECK}"
            ) from None
        self._size = (w, h)
        if self.bits_per_pixel not in (16, 24, 32) or self.stride < w * self.bits_per_pixel // 8:
            raise DeviceError(
                f"framebuffer {name}: {self.bits_per_pixel} bpp with stride {self.stride} is not "
                "supported (16, 24 or 32 bpp expected)"
            )
        self.path = root / device.lstrip("/")
        try:
            self._fd = os.open(self.path, os.O_RDWR)
            self._map = mmap.mmap(self._fd, self.stride * h, mmap.MAP_SHARED, mmap.PROT_WRITE)
        except OSError as e:
            raise device_error(e, f"framebuffer {self.path}", _CHECK) from None
        except ValueError as e:  # mmap larger than the device
            raise DeviceError(f"framebuffer {self.path} is smaller than {w}x{h}: {e}") from None

    @property
    def size(self) -> tuple[int, int]:
        return self._size

    def show(self, frame: Frame) -> None:
        _check_frame(frame, self._size)
        px = to_pixels(frame, self.bits_per_pixel)
        row = px.shape[1]
        view = np.frombuffer(self._map, np.uint8).reshape(self._size[1], self.stride)
        view[:, :row] = px
        del view

    def close(self) -> None:
        self._map.close()
        os.close(self._fd)
