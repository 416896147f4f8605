"""The serial framing: round trips, interop with the smp package, and hostile input."""

from __future__ import annotations

import logging
import os

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smp.packet import encode

from adaproj_edge.link.framing import CONTINUE, START, FrameDecoder, crc16, encode_frame


def feed_all(d: FrameDecoder, data: bytes, step: int = 0) -> list[bytes]:
    if step <= 0:
        return list(d.feed(data))
    out: list[bytes] = []
    for i in range(0, len(data), step):
        out += d.feed(data[i : i + step])
    return out


def test_crc_is_xmodem() -> None:
    assert crc16(b"123456789") == 0x31C3


def test_same_bytes_as_smp_package() -> None:
    for n in (0, 1, 91, 92, 93, 1000):
        m = os.urandom(n)
        assert encode_frame(m) == b"".join(encode(m, line_length=128))


def test_decodes_smp_package_frames_of_any_line_length() -> None:
    d = FrameDecoder(70000)
    for line_length in (8, 64, 127, 128, 4000):
        m = os.urandom(3000)
        assert feed_all(d, b"".join(encode(m, line_length=line_length)), step=7) == [m]


def test_skips_console_noise_and_crlf() -> None:
    d = FrameDecoder(1024)
    m = b"\x02\x00\x00\x00\x00\x00\x00\x00"
    noisy = b"login: \r\n" + encode_frame(m).replace(b"\n", b"\r\n") + b"garbage\n"
    assert feed_all(d, noisy) == [m]


def test_bad_crc_and_bad_base64_are_dropped() -> None:
    d = FrameDecoder(1024)
    good = encode_frame(b"12345678")
    bad_crc = bytearray(good)
    bad_crc[5] ^= 0x01
    assert feed_all(d, bytes(bad_crc)) == []
    assert feed_all(d, START + b"!!!!\n") == []
    assert feed_all(d, good) == [b"12345678"]
    assert d.stats.dropped.get("bad base64") == 1
    assert sum(d.stats.dropped.values()) == 2


def test_oversized_frame_dropped_at_its_first_line() -> None:
    d = FrameDecoder(100)
    assert feed_all(d, encode_frame(b"x" * 101)) == []
    assert d.stats.dropped == {"bad length": 1}


def test_overlong_line_is_skipped_and_decoder_recovers() -> None:
    d = FrameDecoder(1024)
    assert feed_all(d, START + b"A" * 100_000 + b"\n" + encode_frame(b"abcdefgh")) == [b"abcdefgh"]


def test_new_start_abandons_partial_frame() -> None:
    d = FrameDecoder(4096)
    first = encode_frame(os.urandom(500)).split(b"\n")[0] + b"\n"
    assert feed_all(d, first + encode_frame(b"abcdefgh")) == [b"abcdefgh"]


@settings(max_examples=300, deadline=None)
@given(
    messages=st.lists(st.binary(min_size=0, max_size=600), max_size=4),
    step=st.integers(1, 300),
    line_length=st.integers(8, 300),
)
def test_round_trip_any_split(messages: list[bytes], step: int, line_length: int) -> None:
    d = FrameDecoder(1024)
    wire = b"".join(encode_frame(m, line_length) for m in messages)
    assert feed_all(d, wire, step) == messages


@settings(max_examples=500, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=200), st.sampled_from([START, CONTINUE, b"\n"]))))
def test_arbitrary_bytes_never_raise_and_memory_is_bounded(parts: list[bytes]) -> None:
    d = FrameDecoder(512)
    for p in parts:
        for m in d.feed(p):
            assert len(m) <= 512
    assert len(d._line) <= 4096
    assert d._frame is None or len(d._frame) <= 512 + 4 + 3


def test_a_stray_partial_frame_costs_only_itself() -> None:
    d = FrameDecoder(4096)
    m = b"\x02\x00\x00\x00\x00\x00\x00\x06"
    assert feed_all(d, START + b"AAAAB" + encode_frame(m)) == [m]  # no newline before it
    assert feed_all(d, b"noise" + START + b"QUJD" + CONTINUE + encode_frame(m)) == [m]
    assert sum(d.stats.dropped.values()) == 2


def test_a_lost_newline_inside_a_frame_loses_nothing() -> None:
    d = FrameDecoder(4096)
    m = os.urandom(300)
    wire = encode_frame(m, line_length=64)
    assert wire.count(b"\n") > 3
    joined = wire.replace(b"\n", b"", 2)  # two lines run into the next ones
    assert feed_all(d, joined, step=5) == [m]
    assert d.stats.dropped == {}


def test_a_delimiter_split_between_reads_is_found() -> None:
    d = FrameDecoder(1024)
    m = b"abcdefgh"
    wire = START + b"AAAAB" + encode_frame(m)
    cut = wire.index(START, 1) + 1  # between the 06 and the 09 of the real frame start
    assert feed_all(d, wire[:cut]) + feed_all(d, wire[cut:]) == [m]


def test_garbage_longer_than_a_line_then_a_frame() -> None:
    d = FrameDecoder(1024)
    m = b"abcdefgh"
    assert feed_all(d, START + b"A" * 9000 + b"\x06" + encode_frame(m), step=1000) == [m]
    assert len(d._line) <= 4096


def test_a_burst_of_bad_frames_is_logged_once_and_summarised(
    caplog: pytest.LogCaptureFixture,
) -> None:
    d = FrameDecoder(1024)
    bad = START + b"AAAAB\n"
    with caplog.at_level(logging.WARNING, logger="adaproj_edge.link.framing"):
        for _ in range(50):
            assert feed_all(d, bad) == []
        assert feed_all(d, encode_frame(b"abcdefgh")) == [b"abcdefgh"]
        assert feed_all(d, bad) == []
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 3 + 1 + 1  # the first three, the summary, the next burst's first
    assert warned[3] == "50 bad SMP frames dropped before this good one: bad base64 50"
    assert d.stats.dropped == {"bad base64": 51}


@settings(max_examples=300, deadline=None)
@given(
    junk=st.binary(max_size=600),
    message=st.binary(max_size=600),
    step=st.integers(1, 200),
    line_length=st.integers(8, 300),
)
def test_any_junk_then_a_frame_gives_the_frame(
    junk: bytes, message: bytes, step: int, line_length: int
) -> None:
    """Resynchronisation: whatever came before, an intact frame after it gets through."""
    d = FrameDecoder(1024)
    out = feed_all(d, junk + encode_frame(message, line_length), step)
    assert out and out[-1] == message
