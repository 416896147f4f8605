"""Malformed input for the link, shared by the test suite and ``tools/fuzz_link.py``.

Three targets for the wire and the dispatcher (five more, for what a hostile host and
a damaged card found, are described further down):

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
import json
import struct
import threading
from collections import Counter
from pathlib import Path
from typing import Any

import cbor2
import cv2
import numpy as np
from hypothesis import strategies as st

from adaproj_edge.errors import DeviceError, ImageError
from adaproj_edge.fileio import decode_image, image_size
from adaproj_edge.link.device import StandaloneDevice
from adaproj_edge.link.framing import CONTINUE, MAX_LINE, START, FrameDecoder, encode_frame
from adaproj_edge.link.ids import ADAPROJ_GROUP
from adaproj_edge.link.message import HEADER
from adaproj_edge.link.server import Server, serve
from adaproj_edge.link.store import MAX_PENDING, ContentStore
from tests.link.media import jpeg_segments

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


# ---- the classes a hostile host and a damaged card found -----------------------------
#
# - jpeg_target: JPEGs with fill bytes, garbage between segments and fake frame
#   headers in comments: the size read from the header is the size the decoder
#   decodes, or the image is refused before decoding.
# - refusals_target: bursts of requests refused for thousands of different reasons:
#   the server's log state stays bounded.
# - pending_target: uploads begun and abandoned, declaring what fills the quota: a new
#   upload of another name still fits.
# - state_target: any JSON as the saved active record: the server starts and answers.
# - hangup_target: a port whose host hangs up or stops reading at any point: the server
#   goes on and answers the next good request.


def _small_jpeg(w: int, h: int, color: bool, seed: int) -> bytes:
    rng = np.random.default_rng(seed)
    shape = (h, w, 3) if color else (h, w)
    ok, enc = cv2.imencode(".jpg", rng.integers(0, 256, shape, dtype=np.uint8))
    assert ok
    return bytes(enc.tobytes())


def _fake_sof(w: int, h: int) -> bytes:
    return b"\xff\xc0\x00\x0b\x08" + struct.pack(">HH", h, w) + b"\x01\x01\x11\x00"


@st.composite
def jpegs(draw: st.DrawFn) -> bytes:
    """A small real JPEG with fill bytes before markers, bytes between segments,
    comments and APPn segments holding fake frame headers, and perhaps a frame header
    that declares another size than its data."""
    w, h = draw(st.integers(2, 40)), draw(st.integers(2, 40))
    jpeg = _small_jpeg(w, h, draw(st.booleans()), draw(st.integers(0, 99)))
    out = b"\xff\xd8"
    for seg in jpeg_segments(jpeg)[1:]:
        if draw(st.integers(0, 3)) == 0:
            out += draw(st.binary(max_size=6))  # stray bytes (libjpeg skips them)
        if draw(st.integers(0, 2)) == 0:
            fake = _fake_sof(draw(st.integers(1, 64)), draw(st.integers(1, 64)))
            body = draw(st.binary(max_size=8)) + fake + draw(st.binary(max_size=8))
            marker = draw(st.sampled_from([0xFE, 0xE0, 0xE1, 0xEC]))
            out += bytes([0xFF, marker]) + struct.pack(">H", len(body) + 2) + body
        if seg[1] == 0xC0 and draw(st.integers(0, 3)) == 0:
            seg = seg[:5] + struct.pack(">HH", draw(st.integers(0, 64)), draw(st.integers(0, 64)))
            seg += _small_tail(jpeg, seg)
        out += b"\xff" * draw(st.integers(0, 3)) + seg
    return out


def _small_tail(jpeg: bytes, seg: bytes) -> bytes:
    """The rest of the original frame header after its size (components)."""
    i = jpeg.index(b"\xff\xc0")
    n = int.from_bytes(jpeg[i + 2 : i + 4], "big")
    return jpeg[i + 9 : i + 2 + n]


def jpeg_target(data: bytes, seen: Counter[str]) -> None:
    """The header's size is the decoder's, or the bytes are refused without decoding."""
    size = image_size(data)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if img is not None:
        assert size == (img.shape[1], img.shape[0]), (size, img.shape)
        seen["decoded"] += 1
    if size is None:
        try:
            decode_image(data, "fuzz.jpg")
        except ImageError:
            seen["refused unread"] += 1
        else:
            raise AssertionError("an image whose size was not read was decoded")


@st.composite
def refusal_bursts(draw: st.DrawFn) -> list[tuple[int, int]]:
    """(group, command) pairs of requests that are all refused, mostly distinct."""
    n = draw(st.integers(1, 400))
    start = draw(st.integers(100, 60_000))
    return [((start + i // 256) % 0xFFFF, i % 256) for i in range(n)]


def refusals_target(server: Server, burst: list[tuple[int, int]], seen: Counter[str]) -> None:
    """Every request refused; the log's state bounded by its kinds, not the burst."""
    for seq, (group, command) in enumerate(burst):
        reply = server.handle(HEADER.pack(2, 0, 0, group, seq % 256, command))
        assert reply is not None and b"rc" in reply
    refusals = server._refusals
    assert len(refusals.reasons) <= refusals.kinds + 1
    seen["refused"] += len(burst)
    if seen["refused"] % 5000 < len(burst):  # now and then a good request ends the burst
        assert server.handle(HEADER.pack(2, 0, 4, 0, 0, 0) + b"\xa1ad`") is not None


def _upload(name: str, off: int, data: bytes, total: int | None = None) -> bytes:
    body = {"name": name, "off": off, "data": data} | ({} if total is None else {"len": total})
    raw = cbor2.dumps(body)
    return HEADER.pack(2, 0, len(raw), 8, 0, 0) + raw


@st.composite
def pending_floods(draw: st.DrawFn) -> list[tuple[str, int, int]]:
    """Uploads begun and abandoned: (name, declared bytes, bytes sent)."""
    n = draw(st.integers(1, 8))
    return [
        (f"p{draw(st.integers(0, 9))}.png", draw(st.integers(33, 2**19)), draw(st.integers(0, 32)))
        for _ in range(n)
    ]


def pending_target(
    server: Server, flood: list[tuple[str, int, int]], png: bytes, seen: Counter[str]
) -> None:
    """After any abandoned uploads, a whole new one (of another name) fits."""
    store = server.store
    for name in store.sizes():
        store.path(name).unlink()  # each case starts from an empty store
    head = png[:32]
    for name, total, sent in flood:
        server.handle(_upload(name, 0, head[:sent], total))
    assert len(store.pending()) <= MAX_PENDING
    assert store.used() <= store.limits.quota
    reply = server.handle(_upload("new.png", 0, png, len(png)))
    assert reply is not None and cbor2.loads(reply[8:]).get("off") == len(png), reply
    seen["fitted"] += 1


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner),
    max_leaves=10,
)
active_records = st.one_of(
    json_values.map(lambda v: json.dumps(v).encode()),
    st.fixed_dictionaries(
        {},
        optional={
            "image": json_values | st.sampled_from(NAMES),
            "mask": json_values | st.sampled_from(NAMES),
            "settings": json_values,
        },
    ).map(lambda v: json.dumps(v).encode()),
    st.binary(max_size=64),
)


def state_target(root: Path, record: bytes, seen: Counter[str]) -> None:
    """Any bytes as the saved active record: the server starts and answers."""
    (root / ".active.json").write_bytes(record)
    server = Server(ContentStore(root), StandaloneDevice(64, 40), buf_size=2048)
    body = cbor2.dumps({})
    reply = server.handle(HEADER.pack(0, 0, len(body), ADAPROJ_GROUP, 0, 3) + body)  # status
    assert reply is not None and b"device" in reply
    seen["started"] += 1


class HangingPort:
    """A port whose host hangs up (reads fail) or stops reading (writes fail) as told."""

    def __init__(self, chunks: list[bytes | None], writes_fail: list[bool], stop: Any) -> None:
        self.chunks, self.writes_fail, self.stop = chunks, writes_fail, stop
        self.written: list[bytes] = []

    def read(self, size: int, timeout: float) -> bytes:
        if not self.chunks:
            self.stop.set()
            return b""
        chunk = self.chunks.pop(0)
        if chunk is None:
            raise DeviceError("the host hung up")
        return chunk

    def write(self, data: bytes) -> None:
        if self.chunks and self.writes_fail and self.writes_fail.pop(0):  # never the last
            raise DeviceError("the host does not read")
        self.written.append(data)

    def close(self) -> None:
        pass


@st.composite
def hangups(draw: st.DrawFn) -> tuple[list[bytes | None], list[bool]]:
    """(what the port reads: frames, junk or a hang-up, and whether each write fails,
    but the last), the last read an intact echo of ``"last"``."""
    chunks: list[bytes | None] = []
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.integers(0, 2))
        if kind == 0:
            chunks.append(None)
        elif kind == 1:
            body = cbor2.dumps({"d": draw(st.text(max_size=8))})
            chunks.append(encode_frame(HEADER.pack(2, 0, len(body), 0, 1, 0) + body))
        else:
            chunks.append(draw(st.binary(max_size=40)))
    body = cbor2.dumps({"d": "last"})
    chunks.append(START + b"\n" + encode_frame(HEADER.pack(2, 0, len(body), 0, 2, 0) + body))
    return chunks, draw(st.lists(st.booleans(), max_size=8))


def hangup_target(
    server: Server, case: tuple[list[bytes | None], list[bool]], seen: Counter[str]
) -> None:
    """``serve`` never ends by the host's doing; the last request is answered."""
    chunks, fails = case
    stop = threading.Event()
    port = HangingPort(list(chunks), list(fails), stop)
    serve(port, server, stop, poll=0.0)
    decoder = FrameDecoder(server.max_message + 4)
    replies = [m for w in port.written for m in decoder.feed(w)]
    assert any(cbor2.loads(r[8:]) == {"r": "last"} for r in replies)
    seen["survived"] += 1
