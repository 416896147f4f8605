"""The framebuffer display on a fake /sys + /dev tree."""

from __future__ import annotations

import errno
import os
import struct
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import DeviceError, DeviceNotFoundError, InputError
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.display import (
    FBIO_WAITFORVSYNC,
    FramebufferDisplay,
    MemoryDisplay,
    RefreshTimer,
    to_pixels,
)


def fake_fb(root: Path, w: int, h: int, bpp: int, stride: int | None = None) -> int:
    stride = stride or w * bpp // 8
    sysdir = root / "sys/class/graphics/fb0"
    sysdir.mkdir(parents=True)
    (sysdir / "virtual_size").write_text(f"{w},{h}\n")
    (sysdir / "bits_per_pixel").write_text(f"{bpp}\n")
    (sysdir / "stride").write_text(f"{stride}\n")
    (root / "dev").mkdir()
    (root / "dev/fb0").write_bytes(bytes(stride * h))
    return stride


def frame(w: int, h: int) -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_xrgb8888_with_padded_stride(tmp_path: Path) -> None:
    stride = fake_fb(tmp_path, 8, 4, 32, stride=40)
    d = FramebufferDisplay("/dev/fb0", root=tmp_path)
    assert d.size == (8, 4)
    f = frame(8, 4)
    d.show(f)
    d.close()
    raw = np.frombuffer((tmp_path / "dev/fb0").read_bytes(), np.uint8).reshape(4, stride)
    px = raw[:, :32].reshape(4, 8, 4)
    assert np.array_equal(px[..., :3], f) and np.all(px[..., 3] == 255)
    assert not raw[:, 32:].any()


def test_rgb565(tmp_path: Path) -> None:
    fake_fb(tmp_path, 6, 2, 16)
    d = FramebufferDisplay(root=tmp_path)
    f = np.zeros((2, 6, 3), np.uint8)
    f[0, 0] = (255, 0, 0)  # blue
    f[0, 1] = (0, 0, 255)  # red
    d.show(f)
    d.close()
    words = np.frombuffer((tmp_path / "dev/fb0").read_bytes(), "<u2")
    assert words[0] == 0x001F and words[1] == 0xF800


def test_bgr888_bytes() -> None:
    f = frame(3, 2)
    assert np.array_equal(to_pixels(f, 24).reshape(2, 3, 3), f)


def test_missing_framebuffer(tmp_path: Path) -> None:
    with pytest.raises(DeviceNotFoundError, match="projector is connected"):
        FramebufferDisplay(root=tmp_path)


def test_unsupported_depth(tmp_path: Path) -> None:
    fake_fb(tmp_path, 4, 4, 8)
    with pytest.raises(DeviceError, match="8 bpp"):
        FramebufferDisplay(root=tmp_path)


def test_device_smaller_than_mode(tmp_path: Path) -> None:
    fake_fb(tmp_path, 4, 4, 32)
    (tmp_path / "dev/fb0").write_bytes(bytes(10))
    with pytest.raises(DeviceError, match="smaller"):
        FramebufferDisplay(root=tmp_path)


def test_wrong_frame_size_is_an_input_error(tmp_path: Path) -> None:
    fake_fb(tmp_path, 4, 4, 32)
    d = FramebufferDisplay(root=tmp_path)
    with pytest.raises(InputError):
        d.show(frame(5, 4))
    d.close()


def test_memory_display_keeps_the_last_frame() -> None:
    d = MemoryDisplay(4, 3)
    f = frame(4, 3)
    d.show(f)
    assert d.count == 1 and d.last is not None and np.array_equal(d.last, f)
    d.close()


class FakeIoctl:
    """``fcntl.ioctl`` stand-in: records calls, advances the clock to the next sync of a
    60 Hz display, or raises ``error``."""

    def __init__(self, clock: VirtualClock, error: int | None = None) -> None:
        self.clock, self.error = clock, error
        self.calls: list[tuple[int, bytes]] = []

    def __call__(self, fd: int, request: int, arg: bytes) -> bytes:
        self.calls.append((request, arg))
        if self.error is not None:
            raise OSError(self.error, os.strerror(self.error))
        period = round(1e9 / 60)
        self.clock.sleep_until((self.clock.now_ns() // period + 1) * period)
        return arg


def test_wait_refresh_asks_the_driver_for_vertical_sync(tmp_path: Path) -> None:
    fake_fb(tmp_path, 8, 4, 32)
    clock = VirtualClock(1_000)
    ioctl = FakeIoctl(clock)
    d = FramebufferDisplay(root=tmp_path, clock=clock, ioctl=ioctl)
    times = [d.wait_refresh() for _ in range(3)]
    d.close()
    period = round(1e9 / 60)
    assert times == [period, 2 * period, 3 * period]
    assert ioctl.calls == [(FBIO_WAITFORVSYNC, struct.pack("I", 0))] * 3


@pytest.mark.parametrize("err", [errno.ENOTTY, errno.EINVAL])
def test_a_driver_without_vsync_gets_virtual_refreshes(tmp_path: Path, err: int) -> None:
    fake_fb(tmp_path, 8, 4, 32)
    clock = VirtualClock(5_000_000)
    ioctl = FakeIoctl(clock, error=err)
    d = FramebufferDisplay(root=tmp_path, clock=clock, refresh_hz=100.0, ioctl=ioctl)
    times = [d.wait_refresh() for _ in range(3)]
    d.close()
    assert times == [10_000_000, 20_000_000, 30_000_000]
    assert len(ioctl.calls) == 1 and not d.vsync  # asked once, then by the clock


def test_a_failing_vsync_is_a_device_error(tmp_path: Path) -> None:
    fake_fb(tmp_path, 8, 4, 32)
    clock = VirtualClock(0)
    d = FramebufferDisplay(root=tmp_path, clock=clock, ioctl=FakeIoctl(clock, errno.EIO))
    with pytest.raises(DeviceError, match="wait for vsync"):
        d.wait_refresh()
    d.close()


def test_memory_display_refreshes_on_its_clock() -> None:
    clock = VirtualClock(0)
    d = MemoryDisplay(4, 2, clock, refresh_hz=50.0)
    assert d.refresh_hz == 50.0
    assert [d.wait_refresh() for _ in range(2)] == [20_000_000, 40_000_000]
    assert clock.now_ns() == 40_000_000
    with pytest.raises(InputError, match="refreshes"):
        RefreshTimer(clock, 0.5)
