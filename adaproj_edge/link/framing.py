"""SMP serial framing: base64 lines with a length and a CRC16, in both directions.

A frame on the wire is ``[uint16 length][message][uint16 CRC16]`` (big-endian; the
length counts the message and the CRC; the CRC is CRC-16/XMODEM over the message),
base64-encoded and cut into lines. The first line starts with ``06 09``, every
further line with ``04 14``; each line ends with ``\\n`` and carries a whole number
of base64 quads. This is Zephyr's "SMP over console", what ``smpclient``'s
``SMPSerialTransport`` speaks.

The decoder never trusts the wire: it keeps at most one line and one frame in memory,
drops what does not parse (with a logged reason) and starts over at the next frame
start. A delimiter is a frame-start or line-start wherever it appears, not only after
a newline: neither ``06 09`` nor ``04 14`` can occur in base64 text, so bytes before
one are the remains of a cut line (a stray partial frame, noise, a lost newline) and
the line that follows is read on its own. One stray partial frame therefore costs
nothing but itself. Bad frames are counted by reason (:class:`DecoderStats`) and
logged in bursts (:class:`~adaproj_edge.link.burstlog.BurstLog`). Nothing it is fed
can make it raise.
"""

from __future__ import annotations

import binascii
import logging
from collections.abc import Iterator
from dataclasses import dataclass, field

from adaproj_edge.link.burstlog import BurstLog

log = logging.getLogger(__name__)

START = b"\x06\x09"
CONTINUE = b"\x04\x14"
LINE_LENGTH = 128
"""Bytes per line we send, delimiters and newline included (the SMP convention)."""
MAX_LINE = 4096
"""Longest line we accept; a longer one is noise and is skipped up to its newline."""


def crc16(data: bytes) -> int:
    """CRC-16/XMODEM (poly 0x1021, init 0), the SMP serial checksum."""
    return binascii.crc_hqx(data, 0)


def encode_frame(message: bytes, line_length: int = LINE_LENGTH) -> bytes:
    """The wire bytes (all lines) for one SMP ``message``.

    Parameters
    ----------
    message : bytes
        Header and CBOR body, at most 65533 bytes.
    line_length : int
        Bytes per line including the 2-byte delimiter and the newline (>= 8).
    """
    if len(message) > 0xFFFF - 2:
        raise ValueError(f"an SMP message is at most 65533 bytes, not {len(message)}")
    body = (len(message) + 2).to_bytes(2, "big") + message + crc16(message).to_bytes(2, "big")
    text = binascii.b2a_base64(body, newline=False)
    per_line = max(4, ((line_length - 3) // 4) * 4)
    lines = []
    for i in range(0, len(text), per_line):
        lines.append((START if i == 0 else CONTINUE) + text[i : i + per_line] + b"\n")
    return b"".join(lines)


@dataclass
class DecoderStats:
    """What the decoder has seen; each ``dropped`` entry is counted by reason."""

    frames: int = 0
    dropped: dict[str, int] = field(default_factory=dict)

    def drop(self, reason: str) -> None:
        self.dropped[reason] = self.dropped.get(reason, 0) + 1


class FrameDecoder:
    """Turns a byte stream into SMP messages (header + body, CRC checked).

    Parameters
    ----------
    max_message : int
        The largest message accepted (the advertised buffer size minus the 4 bytes of
        length and CRC); a frame declaring more is dropped as soon as its first line
        is read.

    Examples
    --------
    >>> d = FrameDecoder(1024)
    >>> list(d.feed(encode_frame(b"\\x00" * 8)))
    [b'\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00']

    A partial frame left on the line does not cost the next frame anything:

    >>> list(d.feed(START + b"AAAAB" + encode_frame(b"\\x01" * 8)))
    [b'\\x01\\x01\\x01\\x01\\x01\\x01\\x01\\x01']
    >>> d.stats.dropped
    {'line cut short': 1}
    """

    def __init__(self, max_message: int) -> None:
        self.max_message = max_message
        self.stats = DecoderStats()
        self._burst = BurstLog(log, "bad SMP frames dropped")
        self._line = bytearray()
        self._frame: bytearray | None = None
        self._want = 0

    def feed(self, data: bytes) -> Iterator[bytes]:
        """Consume ``data``; yield each complete, intact message it finishes."""
        start = 0
        while start < len(data):
            nl = data.find(b"\n", start)
            end = len(data) if nl < 0 else nl
            if nl >= 0 and not self._line and end - start <= MAX_LINE:
                inner = start + 1
                if data.find(START, inner, end) < 0 and data.find(CONTINUE, inner, end) < 0:
                    # the usual case, a whole line with no delimiter inside: no copying
                    line = data[start:end]
                    start = nl + 1
                    message = self._take_line(line.removesuffix(b"\r"), cut=False)
                    if message is not None:
                        yield message
                    continue
            yield from self._extend(data[start:end])
            if nl < 0:
                return
            start = nl + 1
            line = bytes(self._line)
            self._line.clear()
            message = self._take_line(line.removesuffix(b"\r"), cut=False)
            if message is not None:
                yield message

    def _extend(self, part: bytes) -> Iterator[bytes]:
        """Add ``part`` (no newline in it) to the line; a delimiter inside it ends a line."""
        old = len(self._line)
        self._line += part
        at = _delimiter(self._line, max(1, old - 1))
        while at > 0:
            piece = bytes(self._line[:at])
            del self._line[:at]
            message = self._take_line(piece, cut=True)
            if message is not None:
                yield message
            at = _delimiter(self._line, 1)
        if len(self._line) > MAX_LINE:
            self._abandon("overlong line")
            del self._line[:-1]  # the last byte may be the first half of a delimiter

    def _drop(self, reason: str) -> None:
        self._frame = None
        self.stats.drop(reason)
        self._burst.bad(reason, "dropped an SMP frame: %s", reason)

    def _abandon(self, reason: str) -> None:
        if self._frame is not None:
            self._drop(reason)

    def _take_line(self, line: bytes, *, cut: bool) -> bytes | None:
        """One line (``cut``: ended by the next delimiter, not by a newline)."""
        head, text = line[:2], line[2:]
        if head == START:
            self._abandon("new frame started before the last one ended")
            self._frame = bytearray()
        elif head != CONTINUE or self._frame is None:
            return None  # console text, noise, or a stray continuation: not ours
        chunk = _b64(text)
        if chunk is None:
            self._drop("line cut short" if cut else "bad base64")
            return None
        frame = self._frame
        frame += chunk
        if head == START:
            if len(frame) < 2:
                self._drop("first line too short")
                return None
            self._want = int.from_bytes(frame[:2], "big")
            if self._want < 2 or self._want - 2 > self.max_message:
                self._drop("bad length")
                return None
        have = len(frame) - 2
        if have < self._want:
            return None
        if have > self._want:
            self._drop("longer than declared")
            return None
        self._frame = None
        message = bytes(frame[2:-2])
        if crc16(message) != int.from_bytes(frame[-2:], "big"):
            self._drop("bad CRC")
            return None
        self.stats.frames += 1
        self._burst.ok()
        return message


def _delimiter(line: bytearray, start: int) -> int:
    """Index of the first frame- or line-start delimiter in ``line`` from ``start``, or -1."""
    a = line.find(START, start)
    b = line.find(CONTINUE, start)
    return b if a < 0 else a if b < 0 else min(a, b)


def _b64(text: bytes) -> bytes | None:
    if len(text) % 4:
        return None
    try:
        return binascii.a2b_base64(text, strict_mode=True)
    except (binascii.Error, ValueError):
        return None
