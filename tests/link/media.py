"""Test images: real PNG/JPEG bytes, and hand-made headers for bombs."""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np


def _noise(w: int, h: int, seed: int, ext: str) -> bytes:
    """A noisy colour image (noise keeps it from compressing away) encoded as ``ext``."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    ok, enc = cv2.imencode(ext, img)
    assert ok
    return bytes(enc.tobytes())


def png_bytes(w: int, h: int, seed: int = 0) -> bytes:
    return _noise(w, h, seed, ".png")


def jpeg_bytes(w: int, h: int, seed: int = 0) -> bytes:
    return _noise(w, h, seed, ".jpg")


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack("!I", len(data)) + kind + data + struct.pack("!I", zlib.crc32(kind + data))


def png_bomb(w: int = 8000, h: int = 6000) -> bytes:
    """A valid PNG of ``w`` x ``h`` black gray pixels: tens of KB that decode to 48 MB."""
    ihdr = struct.pack("!IIBBBBB", w, h, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * ((w + 1) * h), 9)
    chunks = _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")
    return b"\x89PNG\r\n\x1a\n" + chunks
