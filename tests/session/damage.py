"""Damaged MCAP files made on purpose: record offsets, bit flips, lying sizes."""

from __future__ import annotations

import struct
from pathlib import Path

import zstandard
from mcap.opcode import Opcode

MAGIC = b"\x89MCAP0\r\n"


def layout(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, offset, body length) of each top-level record of a whole file."""
    out, i = [], len(MAGIC)
    while i + 9 <= len(data) - len(MAGIC):
        op, n = struct.unpack_from("<BQ", data, i)
        out.append((op, i, n))
        i += 9 + n
    return out


def chunks(data: bytes) -> list[tuple[int, int]]:
    """(offset, body length) of each chunk record."""
    return [(i, n) for op, i, n in layout(data) if op == Opcode.CHUNK]


def flip(data: bytes, bit: int) -> bytes:
    b = bytearray(data)
    b[bit // 8] ^= 1 << (bit % 8)
    return bytes(b)


def record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def header() -> bytes:
    text = b"adaproj"
    return record(Opcode.HEADER, struct.pack("<I", len(text)) + text + struct.pack("<I", 0))


def lying_attachment(declared: int = 2**62) -> bytes:
    """About 100 bytes: an MCAP header and an attachment declaring ``declared`` bytes."""
    name, media = b"calibration.json", b"application/json"
    body = (
        struct.pack("<QQ", 0, 0)
        + struct.pack("<I", len(name))
        + name
        + struct.pack("<I", len(media))
        + media
        + struct.pack("<Q", declared)
        + b"{}"
        + struct.pack("<I", 0)
    )
    return MAGIC + header() + record(Opcode.ATTACHMENT, body)


def inflating_chunk(path: Path, declared: int = 2**30) -> None:
    """Write an MCAP file holding one zstd chunk of zeros that inflates to ``declared``
    bytes (about 32 KB on disk for a gigabyte), declaring that size."""
    out = zstandard.ZstdCompressor(level=1).compressobj()
    block = bytes(2**20)
    parts = [out.compress(block) for _ in range(declared // len(block))]
    data = b"".join(parts) + out.flush()
    name = b"zstd"
    body = (
        struct.pack("<QQQI", 0, 0, declared, 0)
        + struct.pack("<I", len(name))
        + name
        + struct.pack("<Q", len(data))
        + data
    )
    path.write_bytes(MAGIC + header() + record(Opcode.CHUNK, body))
