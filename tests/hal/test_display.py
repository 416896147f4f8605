"""The framebuffer display on a fake /sys + /dev tree."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import DeviceError, DeviceNotFoundError, InputError
from adaproj_edge.hal.display import FramebufferDisplay, MemoryDisplay, to_pixels


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
