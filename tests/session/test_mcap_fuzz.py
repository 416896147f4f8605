"""The session reader against damaged files: lying sizes, broken chunks, flipped bits.

Every mutated file must read without any error but a named :class:`InputError` (for a
file whose start or calibration is gone), give only records the recording holds, in
order, and lose no more than the chunk a flipped bit lands in.
"""

from __future__ import annotations

import functools
import io
import struct
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Chunk
from mcap.stream_reader import breakup_chunk

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.session.codec import Record
from adaproj_edge.session.reader import Scan, iter_records, read_session
from adaproj_edge.session.records import SerialTraffic
from adaproj_edge.session.writer import SessionWriter
from tests.session.damage import flip, layout
from tests.session.test_session_io import some_records

FUZZ = settings(
    max_examples=150,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)


@functools.cache
def recording() -> tuple[bytes, list[Record], int]:
    """(file, its records, the most messages one chunk holds)."""
    path = Path(tempfile.mkdtemp(prefix="adaproj-fuzz-")) / "s.mcap"
    with SessionWriter(path, Calibration.default()) as w:
        for r in some_records(8):
            w.write(r)
            if isinstance(r, SerialTraffic) and r.direction == "tx":
                w.flush()
    data = path.read_bytes()
    most = 0
    for op, at, n in layout(data):
        if op == Opcode.CHUNK:
            chunk = Chunk.read(ReadDataStream(io.BytesIO(data[at + 9 : at + 9 + n])))
            most = max(most, len(breakup_chunk(chunk)))
    return data, read_session(path).records, most


def read(path: Path) -> tuple[list[Record], Scan] | None:
    """The records and scan of ``path``; None when it is refused with an InputError."""
    scan = Scan()
    try:
        return list(iter_records(path, scan=scan)), scan
    except InputError:
        return None


def in_order(got: list[Record], want: list[Record]) -> bool:
    it = iter(want)
    return all(any(r == w for w in it) for r in got)


@FUZZ
@given(where=st.lists(st.floats(0.0, 1.0, exclude_max=True), min_size=1, max_size=3))
def test_flipped_bits_lose_at_most_their_chunks(tmp_path: Path, where: list[float]) -> None:
    whole, records, most = recording()
    flips = [int(w * 8 * len(whole)) for w in where]
    blob = whole
    for bit in flips:
        blob = flip(blob, bit)
    p = tmp_path / "flipped.mcap"
    p.write_bytes(blob)
    result = read(p)
    if result is None:  # the magic or the header record was hit
        assert min(flips) // 8 < layout(whole)[1][1]
        return
    got, scan = result
    assert in_order(got, records)
    data_end = next(at for op, at, _ in layout(whole) if op == Opcode.DATA_END)
    if any(f // 8 >= data_end for f in flips) and any(f // 8 < data_end for f in flips):
        # the summary (the second place channels are named) hit as well as a chunk: the
        # chunk that named a channel may take that channel's later messages with it
        return
    assert len(records) - len(got) <= len(flips) * most + (most if scan.damaged_count else 0)
    if max(flips) // 8 < data_end:
        assert "cut short" not in (scan.damage() or ""), scan.damage()


SIZE_FIELDS = {
    "record length": 1,
    "chunk uncompressed size": 9 + 16,
    "chunk data length": 9 + 32,
}


@FUZZ
@given(
    chunk=st.integers(0, 10**6),
    field=st.sampled_from(sorted(SIZE_FIELDS)),
    value=st.one_of(
        st.integers(0, 2**64 - 1),
        st.sampled_from([0, 1, 2**30, 2**62, 2**64 - 1]),
        st.integers(0, 4096),
    ),
)
def test_lying_sizes_never_crash_or_exhaust(
    tmp_path: Path,
    chunk: int,
    field: str,
    value: int,
) -> None:
    whole, records, most = recording()
    chunks = [at for op, at, _ in layout(whole) if op == Opcode.CHUNK]
    at = chunks[chunk % len(chunks)]
    if field == "chunk data length":
        at += 4 + whole[at + 9 + 28]  # past the compression name
    where = at + SIZE_FIELDS[field]
    blob = whole[:where] + struct.pack("<Q", value) + whole[where + 8 :]
    p = tmp_path / "lying.mcap"
    p.write_bytes(blob)
    result = read(p)
    assert result is not None
    got, scan = result
    assert in_order(got, records)
    assert len(records) - len(got) <= most
    assert scan.complete


@FUZZ
@given(cut=st.integers(0, 10**6), junk=st.binary(max_size=64))
def test_cut_or_overwritten_files_read_up_to_the_damage(
    tmp_path: Path, cut: int, junk: bytes
) -> None:
    whole, records, _ = recording()
    cut %= len(whole)
    p = tmp_path / "cut.mcap"
    p.write_bytes(whole[:cut] + junk)
    result = read(p)
    if result is None:
        return
    got, scan = result
    assert in_order(got, records)
    assert scan.truncated or not scan.complete or scan.trailing_bytes
