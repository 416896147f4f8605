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


def jpeg_segments(jpeg: bytes) -> list[bytes]:
    """The marker segments of a plain JPEG (as OpenCV writes it), SOS with its data last."""
    i, out = 2, []
    while i < len(jpeg):
        if jpeg[i + 1] == 0xDA:
            out.append(jpeg[i:])
            break
        n = int.from_bytes(jpeg[i + 2 : i + 4], "big")
        out.append(jpeg[i : i + 2 + n])
        i += 2 + n
    return out


def jpeg_fill_bomb(w: int = 8000, h: int = 8000) -> bytes:
    """About 49 KB of JPEG whose frame header declares ``w`` x ``h`` (the entropy data of
    16x16 pixels: the decoder fills the rest), behind one 0xFF fill byte.

    A parser that does not skip fill bytes (libjpeg does) reads the fill and the real
    marker as a marker and a length, 0xC000 bytes, and lands in a comment placed there
    that holds a fake 16x16 frame header.
    """
    ok, enc = cv2.imencode(".jpg", np.full((16, 16), 128, np.uint8))
    assert ok
    head, tail = b"\xff\xd8", b""
    for seg in jpeg_segments(bytes(enc.tobytes())):
        if seg[1] == 0xC0:
            head += b"\xff" + seg[:5] + struct.pack(">HH", h, w) + seg[9:]
        elif seg[1] == 0xDA:
            tail = seg
        else:
            head += seg
    fill = head.index(b"\xff\xff\xc0")
    lands = fill + 2 + int.from_bytes(head[fill + 2 : fill + 4], "big")
    fake = b"\xff\xc0\x00\x0b\x08\x00\x10\x00\x10\x01\x01\x11\x00"
    payload = b"\x00" * (lands - (len(head) + 4)) + fake + b"\x00" * 8
    comment = b"\xff\xfe" + struct.pack(">H", len(payload) + 2) + payload
    return head + comment + tail
