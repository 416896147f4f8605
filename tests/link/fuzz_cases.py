"""Malformed input for the link, shared by the test suite and ``tools/fuzz_link.py``.

Three targets:

- :func:`wire_target`: a byte stream (valid frames of bad messages, mutated frames,
  noise) through the frame decoder and the dispatcher, replies encoded back.
- :func:`dispatch_target`: one message (header + body) straight into the dispatcher.
- :func:`resync_target`: junk (stray partial frames, cut lines, noise), then one
  intact frame of a good request: the decoder must find it and the server answer it.

Each returns what happened, and raises ``AssertionError`` if a guarantee breaks: the
server raised, a reply is not a well-formed answer to its request, a bad request got
an internal error, the decoder holds more than its bounds, or a good frame after junk
is lost.
"""

from __future__ import annotations

import base64
import struct
from collections import Counter
from typing import Any

import cbor2
from hypothesis import strategies as st

from adaproj_edge.link.framing import CONTINUE, MAX_LINE, START, FrameDecoder, encode_frame
from adaproj_edge.link.ids import ADAPROJ_GROUP
from adaproj_edge.link.message import HEADER
from adaproj_edge.link.server import Server

FIELDS = ["d", "name", "off", "data", "len", "type", "image", "mask", "settings", "force"]
NAMES = [
    "a.png",
    "/a.png",
    "b.jpg",
    "../a.png",
    "/../../etc/passwd",
    "a/b.png",
    "",
    ".a.png",
    "x" * 300,
    "a.png\x00",
    "ä.png",
    "a.gif",
    "/",
    "..",
    "a.PNG",
]
PNG_HEAD = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR"

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True),
    st.text(max_size=24),
    st.binary(max_size=96),
    st.sampled_from(NAMES),
    st.integers(0, 5000),
)
values = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)
maps = st.dictionaries(st.sampled_from(FIELDS) | st.text(max_size=6), values, max_size=6)


def _png_data(n: int, tail: bytes) -> bytes:
    return (PNG_HEAD + struct.pack("!II", n, n) + tail)[: max(0, n)]


upload_maps = st.fixed_dictionaries(
    {
        "name": st.sampled_from(NAMES),
        "off": st.integers(-5, 70_000),
        "data": st.binary(max_size=64),
    },
    optional={"len": st.integers(-5, 10**9)},
)
png_uploads = st.builds(
    lambda name, n, tail, total: {"name": name, "off": 0, "data": _png_data(n, tail), "len": total},
    st.sampled_from(NAMES[:3]),
    st.integers(0, 60_000),
    st.binary(max_size=32),
    st.integers(0, 10**9),
)


def _tagged(tag: int, value: Any) -> bytes:
    return cbor2.dumps({"d": cbor2.CBORTag(tag, value)})


bodies = st.one_of(
    maps.map(cbor2.dumps),
    upload_maps.map(cbor2.dumps),
    png_uploads.map(cbor2.dumps),
    st.binary(max_size=160),
    st.builds(_tagged, st.integers(0, 2**32), scalars),
    st.integers(1, 2000).map(lambda n: b"\x81" * n + b"\x00"),  # deep nesting
    st.integers(0, 2**64 - 1).map(lambda n: b"\xa1\x61d\x5b" + n.to_bytes(8, "big")),  # huge bstr
    st.just(b"\xbf\x61d\xff"),  # indefinite map, truncated
)
groups = st.one_of(st.sampled_from([0, 8, ADAPROJ_GROUP]), st.integers(0, 0xFFFF))
commands = st.one_of(st.integers(0, 8), st.integers(0, 255))


@st.composite
def messages(draw: st.DrawFn) -> bytes:
    """A whole SMP message whose header and body are each likely to be wrong."""
    body = draw(bodies)
    length = draw(st.one_of(st.just(len(body)), st.integers(0, 0xFFFF)))
    header = HEADER.pack(
        draw(st.sampled_from([0, 2, 8, 10]) | st.integers(0, 255)),  # op, version, reserved
        draw(st.integers(0, 255)),
        length,
        draw(groups),
        draw(st.integers(0, 255)),
        draw(commands),
    )
    message = header + body
    cut = draw(st.one_of(st.none(), st.integers(0, len(message))))
    return message if cut is None else message[:cut]


@st.composite
def streams(draw: st.DrawFn) -> list[bytes]:
    """Wire chunks: frames of bad messages, mutated frames, delimiters and noise."""
    parts: list[bytes] = []
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.integers(0, 4))
        if kind == 0:
            parts.append(encode_frame(draw(messages()), draw(st.integers(8, 200))))
        elif kind == 1:
            frame = bytearray(encode_frame(draw(messages())))
            for _ in range(draw(st.integers(1, 4))):
                i = draw(st.integers(0, len(frame) - 1))
                frame[i] = draw(st.integers(0, 255))
            parts.append(bytes(frame))
        elif kind == 2:
            parts.append(START + draw(st.binary(max_size=64)) + b"\n")
        elif kind == 3:
            n = draw(st.integers(0, 0xFFFF))
            head = n.to_bytes(2, "big") + draw(st.binary(max_size=40))
            parts.append(START + base64.b64encode(head) + b"\n" + CONTINUE + b"AAAA\n")
        else:
            parts.append(draw(st.binary(max_size=300)))
    wire = b"".join(parts)
    step = draw(st.integers(1, max(1, len(wire))))
    return [wire[i : i + step] for i in range(0, len(wire), step)]


_B64 = st.binary(max_size=80).map(lambda b: base64.b64encode(b)[: len(b)])


@st.composite
def junk(draw: st.DrawFn) -> bytes:
    """What a line may carry before a good frame: each piece cut anywhere, no newline
    needed between them."""
    parts: list[bytes] = []
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.integers(0, 3))
        if kind == 0:
            parts.append(draw(st.binary(max_size=200)))
        elif kind == 1:
            parts.append(draw(st.sampled_from([START, CONTINUE])) + draw(_B64))
        elif kind == 2:
            frame = encode_frame(draw(messages()), draw(st.integers(8, 200)))
            parts.append(frame[: draw(st.integers(0, len(frame)))])
        else:
            parts.append(b"\r\n" * draw(st.integers(0, 2)) + draw(_B64) + b"\n")
    return b"".join(parts)


@st.composite
def resyncs(draw: st.DrawFn) -> tuple[list[bytes], bytes]:
    """(wire chunks, the good request at their end): junk, then an intact echo frame."""
    body = cbor2.dumps({"d": draw(st.text(max_size=40))})
    message = HEADER.pack(2, 0, len(body), 0, draw(st.integers(0, 255)), 0) + body
    wire = draw(junk()) + encode_frame(message, draw(st.integers(8, 200)))
    step = draw(st.integers(1, max(1, len(wire))))
    return [wire[i : i + step] for i in range(0, len(wire), step)], message


def check_reply(message: bytes, reply: bytes | None, seen: Counter[str]) -> None:
    """Assert ``reply`` is a proper answer to ``message`` (or that ignoring it was right)."""
    if reply is None:
        assert len(message) < 8 or message[0] & 0b111 not in (0, 2), message.hex()
        seen["ignored"] += 1
        return
    assert len(reply) >= 8
    op, _flags, length, group, seq, cmd = struct.unpack_from("!BBHHBB", reply)
    assert (op & 0b111) == (message[0] & 0b111) + 1
    assert (group, seq, cmd) == struct.unpack_from("!HBB", message, 4)
    assert length == len(reply) - 8
    body = cbor2.loads(reply[8:])
    assert isinstance(body, dict)
    if "rc" in body or "err" in body:
        assert "internal error" not in str(body.get("rsn", "")), body
        seen["error"] += 1
    else:
        seen["success"] += 1


def dispatch_target(server: Server, message: bytes, seen: Counter[str]) -> None:
    check_reply(message, server.handle(message), seen)


def wire_target(
    server: Server, decoder: FrameDecoder, chunks: list[bytes], seen: Counter[str]
) -> None:
    for chunk in chunks:
        for message in decoder.feed(chunk):
            reply = server.handle(message)
            check_reply(message, reply, seen)
            if reply is not None:
                encode_frame(reply)
    assert len(decoder._line) <= MAX_LINE
    assert decoder._frame is None or len(decoder._frame) <= decoder.max_message + 4


def resync_target(
    server: Server, decoder: FrameDecoder, case: tuple[list[bytes], bytes], seen: Counter[str]
) -> None:
    """Feed junk then a good frame; the good frame must be the last message decoded."""
    chunks, good = case
    last: bytes | None = None
    for chunk in chunks:
        for message in decoder.feed(chunk):
            reply = server.handle(message)
            check_reply(message, reply, seen)
            last = message
    assert last == good, "the intact frame after the junk was lost"
    seen["resynchronised"] += 1
    assert len(decoder._line) <= MAX_LINE
