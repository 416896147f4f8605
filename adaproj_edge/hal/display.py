"""The projector as a Linux framebuffer (``/dev/fb0``), and an in-memory stand-in.

The pixel layout comes from sysfs (``/sys/class/graphics/fb0``: ``virtual_size``,
``bits_per_pixel``, ``stride``); the device node is memory-mapped and each frame is
converted once (BGR -> XRGB8888, BGR888 or RGB565; a BGRX frame is XRGB8888 already)
and copied in row by row. Every path goes through a ``root`` prefix, so tests point
the driver at a fake tree.

Refreshes: :meth:`Display.wait_refresh` blocks until the next vertical sync and says
when it was. The framebuffer asks the driver (``FBIO_WAITFORVSYNC``); a driver without
it (``ENOTTY``/``EINVAL``, logged once) gets a virtual refresh, as the in-memory
display always does: the next multiple of the refresh period on the injected clock.
A frame shown right after a refresh is copied ahead of the scan-out (a frame takes
milliseconds to copy, the scan-out the whole period).
"""

from __future__ import annotations

import errno
import fcntl
import logging
import mmap
import os
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import DeviceError, InputError
from adaproj_edge.hal.clock import Clock, MonotonicClock, VirtualClock
from adaproj_edge.hal.oserrors import device_error

log = logging.getLogger(__name__)

Frame = NDArray[np.uint8]
_CHECK = "that the projector is connected and the framebuffer driver is loaded"
FBIO_WAITFORVSYNC = 0x40044620  # _IOW('F', 0x20, __u32), linux/fb.h
DEFAULT_REFRESH_HZ = 60.0
Ioctl = Callable[[int, int, Any], Any]


class Display(Protocol):
    """Where projector frames go."""

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        ...

    @property
    def refresh_hz(self) -> float:
        """Refreshes per second."""
        ...

    def show(self, frame: Frame) -> None:
        """Show a (height, width, 3) BGR or (height, width, 4) BGRX uint8 frame."""
        ...

    def wait_refresh(self) -> int:
        """Block until the next refresh begins; its time (ns, the display's clock)."""
        ...

    def close(self) -> None:
        """Release the display."""
        ...


class RefreshTimer:
    """Virtual refreshes: every ``1 / refresh_hz`` seconds on ``clock`` from ``phase_ns``.

    Parameters
    ----------
    clock : Clock
    refresh_hz : float
    phase_ns : int
        The time of one refresh (the others are whole periods away).
    """

    def __init__(self, clock: Clock, refresh_hz: float, phase_ns: int = 0) -> None:
        if not 1.0 <= refresh_hz <= 1000.0:
            raise InputError(f"a display refreshes 1 to 1000 times a second, not {refresh_hz}")
        self.clock = clock
        self.refresh_hz = refresh_hz
        self.period_ns = round(1e9 / refresh_hz)
        self.phase_ns = phase_ns

    def next_after(self, t_ns: int) -> int:
        """The first refresh strictly after ``t_ns``."""
        k = (t_ns - self.phase_ns) // self.period_ns + 1
        return int(self.phase_ns + k * self.period_ns)

    def wait(self) -> int:
        """Sleep on the clock until the next refresh; its time."""
        t = self.next_after(self.clock.now_ns())
        self.clock.sleep_until(t)
        return t


class MemoryDisplay:
    """Keeps the last frame shown (and how many), for tests and replays; refreshes on
    ``clock`` (a virtual one by default)."""

    def __init__(
        self,
        width: int = 1280,
        height: int = 800,
        clock: Clock | None = None,
        refresh_hz: float = DEFAULT_REFRESH_HZ,
    ) -> None:
        self._size = (width, height)
        self.last: Frame | None = None
        self.count = 0
        self.timer = RefreshTimer(clock or VirtualClock(), refresh_hz)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self._size

    @property
    def refresh_hz(self) -> float:
        """The refresh rate, Hz."""
        return self.timer.refresh_hz

    def wait_refresh(self) -> int:
        """Wait for the next refresh (virtual); its time, ns."""
        return self.timer.wait()

    def show(self, frame: Frame) -> None:
        """Keep a copy of the (height, width, 3) BGR uint8 frame in :attr:`last`."""
        _check_frame(frame, self._size)
        if self.last is not None and self.last.shape == frame.shape:
            np.copyto(self.last, frame)  # one buffer: no fresh pages for every frame
        else:
            self.last = frame.copy()
        self.count += 1

    def close(self) -> None:
        """Nothing to release."""
        pass


def _read_sys(path: Path) -> str:
    try:
        return path.read_text().strip()
    except OSError as e:
        raise device_error(e, f"framebuffer attribute {path}", _CHECK) from None


def _check_frame(frame: Frame, size: tuple[int, int]) -> None:
    w, h = size
    if frame.shape not in ((h, w, 3), (h, w, 4)) or frame.dtype != np.uint8:
        raise InputError(
            f"display frames must be ({h}, {w}, 3) uint8 BGR or ({h}, {w}, 4) BGRX, got "
            f"{frame.shape} {frame.dtype}"
        )


def to_pixels(frame: Frame, bits_per_pixel: int) -> NDArray[np.uint8]:
    """Convert a BGR (h, w, 3) or BGRX (h, w, 4) frame to framebuffer bytes
    (h, w * bytes_per_pixel)."""
    h, w, c = frame.shape
    if bits_per_pixel == 32 and c == 4:
        out = np.ascontiguousarray(frame)  # BGRX is little-endian XRGB8888 already
    elif bits_per_pixel == 32:
        out = np.empty((h, w, 4), np.uint8)
        out[..., :3] = frame  # little-endian XRGB8888 is B, G, R, X in memory
        out[..., 3] = 255
    elif bits_per_pixel == 24:
        out = np.ascontiguousarray(frame[..., :3])
    elif bits_per_pixel == 16:
        b = frame[..., 0].astype(np.uint16) >> 3
        g = frame[..., 1].astype(np.uint16) >> 2
        r = frame[..., 2].astype(np.uint16) >> 3
        out = ((r << 11) | (g << 5) | b).astype("<u2").view(np.uint8).reshape(h, w, 2)
    else:
        raise DeviceError(f"framebuffer with {bits_per_pixel} bits per pixel is not supported")
    return out.reshape(h, -1)


class FramebufferDisplay:
    """The projector on ``/dev/fbN``, memory-mapped.

    Parameters
    ----------
    device : str
        The framebuffer device.
    root : path
        Prefix of every path (tests point it at a fake tree).
    clock : Clock
        The refresh times' clock (the monotonic one by default).
    refresh_hz : float
        The refresh rate of the virtual refresh used when the driver cannot wait for
        vertical sync.
    ioctl : callable
        ``fcntl.ioctl`` (tests pass a stand-in).
    """

    def __init__(
        self,
        device: str = "/dev/fb0",
        root: str | os.PathLike[str] = "/",
        clock: Clock | None = None,
        refresh_hz: float = DEFAULT_REFRESH_HZ,
        ioctl: Ioctl = fcntl.ioctl,
    ) -> None:
        self.clock = clock or MonotonicClock()
        self.timer = RefreshTimer(self.clock, refresh_hz)
        self._ioctl = ioctl
        self.vsync = True  # until the driver says it cannot
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
        """(width, height) in pixels, from ``virtual_size``."""
        return self._size

    @property
    def refresh_hz(self) -> float:
        """The refresh rate, Hz."""
        return self.timer.refresh_hz

    def wait_refresh(self) -> int:
        """Wait for the driver's vertical sync (``FBIO_WAITFORVSYNC``, CRTC 0); a driver
        without it gets a virtual refresh from then on."""
        if self.vsync:
            try:
                self._ioctl(self._fd, FBIO_WAITFORVSYNC, struct.pack("I", 0))
                return self.clock.now_ns()
            except OSError as e:
                if e.errno not in (errno.ENOTTY, errno.EINVAL, errno.EOPNOTSUPP):
                    raise device_error(
                        e, f"framebuffer {self.path} (wait for vsync)", _CHECK
                    ) from None
                self.vsync = False
                log.warning(
                    "framebuffer %s cannot wait for vertical sync (%s): refreshing every "
                    "%.1f ms by the clock instead",
                    self.path,
                    e.strerror or e,
                    1e3 / self.timer.refresh_hz,
                )
        return self.timer.wait()

    def show(self, frame: Frame) -> None:
        """Write a (height, width, 3) BGR uint8 frame into the mapped framebuffer."""
        _check_frame(frame, self._size)
        px = to_pixels(frame, self.bits_per_pixel)
        row = px.shape[1]
        view = np.frombuffer(self._map, np.uint8).reshape(self._size[1], self.stride)
        view[:, :row] = px
        del view

    def close(self) -> None:
        """Unmap and close the framebuffer."""
        self._map.close()
        os.close(self._fd)
