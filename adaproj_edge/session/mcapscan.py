"""MCAP records read with every declared size checked: damage is skipped, not trusted.

The ``mcap`` package's stream reader allocates what a record declares (an attachment
of 2^62 bytes, a chunk that inflates to a gigabyte) and stops at the first bad byte.
:func:`scan_records` reads the same records, but

- a record's length is checked against the bytes left in the file, and no record
  larger than :data:`MAX_RECORD` is read into memory;
- each record is parsed from its own bytes, so a size declared inside it can never
  reach past it; attachments and chunks are checked against their CRCs;
- a chunk is inflated only up to the size it declares (at most :data:`MAX_CHUNK`),
  in a bounded stream: a chunk that inflates to more, or does not match its CRC, is
  skipped whole;
- after a damaged record it looks for the next good one (a chunk, an attachment, a
  metadata record or the end of the data, each checked whole before it is believed)
  and goes on from there.

What it skips comes out as :class:`Damage` items between the records; a file that
stops mid-record comes out as :class:`Cut`. Records are ``mcap.records`` objects.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from adaproj_edge.errors import InputError

MAGIC = b"\x89MCAP0\r\n"
MAX_RECORD = 64 * 2**20
"""Bytes of one record read at most (a session's chunks and attachments are a few MiB at most)."""
MAX_CHUNK = 32 * 2**20
"""Bytes a chunk may inflate to at most (and the largest zstd window taken)."""
_RECORD = struct.Struct("<BQ")
_CHUNK_HEAD = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, name length
_SYNC = (Opcode.CHUNK, Opcode.ATTACHMENT, Opcode.METADATA, Opcode.DATA_END)
"""Records looked for after damage: each can be checked whole before it is believed."""
_WINDOW = 1 << 20

_READERS: dict[int, Any] = {
    Opcode.ATTACHMENT_INDEX: AttachmentIndex.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.CHUNK_INDEX: ChunkIndex.read,
    Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read,
    Opcode.HEADER: Header.read,
    Opcode.MESSAGE_INDEX: MessageIndex.read,
    Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.STATISTICS: Statistics.read,
    Opcode.SUMMARY_OFFSET: SummaryOffset.read,
}
_MALFORMED = (
    McapError,
    struct.error,
    ValueError,
    EOFError,
    UnicodeDecodeError,
    KeyError,
    OverflowError,
)


@dataclass(frozen=True)
class Damage:
    """Bytes ``start``..``end`` of the file were skipped, for ``reason``."""

    start: int
    end: int
    reason: str

    def __str__(self) -> str:
        return f"bytes {self.start}-{self.end}: {self.reason}"


@dataclass(frozen=True)
class Cut:
    """The file ends at ``at`` without its closing records (``reason``: how, when it
    ends inside a record)."""

    at: int
    reason: str


class _Bad(Exception):
    """A record that cannot be believed (the reason is the message)."""


class _PastEnd(_Bad):
    """A record that runs past the end of the file (cut short, or its length is bad)."""


def scan_records(f: IO[bytes], size: int) -> Iterator[McapRecord | Damage | Cut]:
    """The records of the MCAP file ``f`` (``size`` bytes), chunks opened, in file order.

    Damage comes out as :class:`Damage` where it was skipped, a cut file ends with a
    :class:`Cut`. After the footer, the generator ends (bytes after it are the caller's
    to count: ``f.tell()``).

    Raises
    ------
    InputError
        The file does not start with the MCAP magic.
    """
    f.seek(0)
    if f.read(len(MAGIC)) != MAGIC:
        raise InputError("no MCAP magic at its start")
    pos = len(MAGIC)
    while True:
        if pos == size:
            yield Cut(pos, "")
            return
        f.seek(pos)
        head = f.read(_RECORD.size)
        if len(head) < _RECORD.size:
            yield Cut(pos, "it ends inside a record's header")
            return
        opcode, length = _RECORD.unpack(head)
        body_at = pos + _RECORD.size
        try:
            if length > size - body_at:
                raise _PastEnd(
                    f"a record (opcode {opcode}) declares {length} bytes, past the file's "
                    f"end ({size} bytes)"
                )
            if length > MAX_RECORD:
                yield Damage(pos, body_at + length, f"a record of {length} bytes, too large")
                pos = body_at + length
                continue
            records = _parse(opcode, f.read(length), pos)
        except _Bad as e:
            good = _resync(f, pos + 1, size)
            if good is None and isinstance(e, _PastEnd):
                yield Cut(pos, str(e))
                return
            if good is None:
                yield Damage(pos, size, f"{e}; nothing readable after it")
                yield Cut(size, "")
                return
            yield Damage(pos, good, f"{e}; skipped to the next good record")
            pos = good
            continue
        if isinstance(records, Damage):
            yield records
        else:
            yield from records
            if records and isinstance(records[-1], Footer):
                f.seek(body_at + length)
                if f.read(len(MAGIC)) != MAGIC:
                    yield Cut(body_at + length, "its closing magic is missing")
                return
        pos = body_at + length


def _parse(opcode: int, body: bytes, at: int) -> list[McapRecord] | Damage:
    """The record(s) in ``body``: a chunk's content, or one record; unknown opcodes
    give nothing. :class:`_Bad` when it is malformed (its framing cannot be trusted),
    a :class:`Damage` when it is whole but unusable (a chunk failing its CRC)."""
    stream = ReadDataStream(io.BytesIO(body))
    try:
        if opcode == Opcode.CHUNK:
            return _chunk(Chunk.read(stream), len(body), at)
        if opcode == Opcode.ATTACHMENT:
            record: McapRecord = Attachment.read(stream)
            crc = struct.unpack_from("<I", body, len(body) - 4)[0] if len(body) >= 4 else 0
            if stream.count != len(body) or (crc and crc != zlib.crc32(body[:-4])):
                raise _Bad("an attachment that fails its size or CRC check")
            return [record]
        if opcode == Opcode.MESSAGE:
            if len(body) < 22:
                raise _Bad("a message record too short for its header")
            return [Message.read(stream, len(body))]
        reader = _READERS.get(opcode)
        if reader is None:
            if 0 < opcode < 0x80:
                raise _Bad(f"an unknown record type (opcode {opcode})")
            return []  # a private record (opcode 0x80 and up): not ours to read
        record = reader(stream)
    except _MALFORMED as e:
        raise _Bad(f"a malformed record (opcode {opcode}: {type(e).__name__})") from None
    if stream.count != len(body):
        raise _Bad(f"a record (opcode {opcode}) whose fields do not fill its length")
    return [record]


def _chunk(chunk: Chunk, length: int, at: int) -> list[McapRecord] | Damage:
    """The records inside ``chunk`` (of ``length`` bytes at byte ``at``)."""
    end = at + _RECORD.size + length
    if _CHUNK_HEAD.size + len(chunk.compression.encode()) + 8 + len(chunk.data) != length:
        raise _Bad("a chunk whose data does not fill it")
    if chunk.uncompressed_size > MAX_CHUNK:
        return Damage(at, end, f"a chunk declaring {chunk.uncompressed_size} bytes, too large")
    try:
        data = _inflate(chunk)
    except (_Bad, zstandard.ZstdError, RuntimeError, ValueError) as e:
        return Damage(at, end, f"a damaged chunk ({e})")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        return Damage(at, end, "a chunk that fails its CRC")
    out: list[McapRecord] = []
    i = 0
    while i < len(data):
        if len(data) - i < _RECORD.size:
            return Damage(at, end, "a chunk whose last record is cut")
        opcode, n = _RECORD.unpack_from(data, i)
        i += _RECORD.size
        if n > len(data) - i:
            return Damage(at, end, "a chunk holding a record longer than the chunk")
        body = data[i : i + n]
        i += n
        try:
            if opcode in (Opcode.CHANNEL, Opcode.SCHEMA, Opcode.MESSAGE):
                parsed = _parse(opcode, body, at)
                assert isinstance(parsed, list)
                out += parsed
        except _Bad as e:
            return Damage(at, end, f"a chunk holding {e}")
    return out


def _inflate(chunk: Chunk) -> bytes:
    """The chunk's records, inflated to at most the size it declares."""
    want = chunk.uncompressed_size
    if chunk.compression == "":
        data = chunk.data
    elif chunk.compression == "zstd":
        reader = zstandard.ZstdDecompressor(max_window_size=MAX_CHUNK).stream_reader(
            io.BytesIO(chunk.data)
        )
        data = reader.read(want + 1)
    else:  # lz4 and anything else: sessions are written with zstd
        raise _Bad(f"compression {chunk.compression[:20]!r} is not read (sessions use zstd)")
    if len(data) != want:
        raise _Bad(
            f"it inflates to {'more than' if len(data) > want else len(data)} of the "
            f"{want} bytes it declares"
        )
    return bytes(data)


def _resync(f: IO[bytes], start: int, size: int) -> int | None:
    """The offset of the next record from ``start`` on that is whole and checks out
    (:data:`_SYNC`), or None."""
    pos = start
    while pos < size:
        f.seek(pos)
        window = f.read(_WINDOW + _RECORD.size)
        for i in _candidates(window):
            at = pos + i
            if i >= _WINDOW:
                break
            opcode, length = _RECORD.unpack_from(window, i)
            body_at = at + _RECORD.size
            if length > size - body_at or length > MAX_RECORD:
                continue
            if opcode == Opcode.DATA_END and length != 4:
                continue
            if opcode == Opcode.CHUNK and not _chunk_head_fits(window, i, length):
                continue
            f.seek(body_at)
            try:
                parsed = _parse(opcode, f.read(length), at)
            except _Bad:
                continue
            if isinstance(parsed, list):
                return at
        pos += _WINDOW
    return None


def _candidates(window: bytes) -> Iterator[int]:
    """Offsets in ``window`` where a record looked for after damage may start."""
    hits: list[int] = []
    for op in _SYNC:
        j = window.find(bytes([op]))
        while j >= 0 and j + _RECORD.size <= len(window):
            hits.append(j)
            j = window.find(bytes([op]), j + 1)
    return iter(sorted(hits))


def _chunk_head_fits(window: bytes, i: int, length: int) -> bool:
    """Whether a chunk's fixed fields at ``i`` are consistent (a cheap first test)."""
    j = i + _RECORD.size
    if j + _CHUNK_HEAD.size + 12 > len(window):
        return True  # cannot tell from here: the whole check decides
    name_len = _CHUNK_HEAD.unpack_from(window, j)[4]
    if name_len not in (0, 3, 4):
        return False
    k = j + _CHUNK_HEAD.size + name_len
    data_len = struct.unpack_from("<Q", window, k)[0] if k + 8 <= len(window) else None
    return data_len is None or _CHUNK_HEAD.size + name_len + 8 + data_len == length


def summary_channels(f: IO[bytes], size: int) -> dict[int, Channel]:
    """The channels listed in the file's summary section (after the data, found from
    the footer), or none when the file has no readable footer or summary.

    A streaming reader learns channels from the chunks that first use them; when such
    a chunk is damaged, the summary still names the channels of the messages after it.
    """
    footer_at = size - len(MAGIC) - _RECORD.size - 20
    if footer_at < len(MAGIC):
        return {}
    f.seek(footer_at)
    tail = f.read(_RECORD.size + 20 + len(MAGIC))
    # the footer record decides; a damaged trailing magic alone does not lose the summary
    # (every record read from it is checked below)
    if _RECORD.unpack_from(tail) != (Opcode.FOOTER, 20):
        return {}
    start = struct.unpack_from("<Q", tail, _RECORD.size)[0]
    channels: dict[int, Channel] = {}
    pos = start
    while len(MAGIC) <= pos < footer_at:
        f.seek(pos)
        head = f.read(_RECORD.size)
        if len(head) < _RECORD.size:
            break
        opcode, length = _RECORD.unpack(head)
        if length > footer_at - pos - _RECORD.size:
            break
        if opcode == Opcode.CHANNEL:
            try:
                parsed = _parse(opcode, f.read(length), pos)
            except _Bad:
                parsed = []
            for r in parsed if isinstance(parsed, list) else []:
                if isinstance(r, Channel):
                    channels[r.id] = r
        pos += _RECORD.size + length
    return channels
