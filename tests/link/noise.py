"""Line noise on a serial port, on a schedule: for tests of the link through a real pty.

:class:`NoisyPort` wraps the device's side of the line. What the host sends is damaged
as the server reads it, what the server answers as it is written, so the real clients
on the other end of the pty (``smpclient``, ``smpmgr``, ``adaproj push``) meet the
damage exactly as they would on a noisy cable. A :class:`Damage` names an SMP frame by
its number in that direction and says what happens to it; the port records what it
did, so a test can check that the noise it asked for was really there.
"""

from __future__ import annotations

import string
from dataclasses import dataclass, field

from adaproj_edge.hal.serial import SerialPort

BASE64 = frozenset((string.ascii_letters + string.digits + "+/").encode())


@dataclass(frozen=True)
class Damage:
    """What happens to frame number ``frame`` (1 = the first) of one direction.

    ``before`` goes on the line just before the frame's start delimiter (garbage, a
    stray partial frame); with ``flip_at`` set, the first base64 character at or
    after that many bytes past the delimiter is replaced by another one (a corrupted
    byte that base64 and the length cannot catch: only the CRC can).
    """

    frame: int
    before: bytes = b""
    flip_at: int | None = None


@dataclass
class Mangler:
    """Applies a list of :class:`Damage` to one direction's byte stream, chunk by chunk,
    and counts its frames (``frames``: start delimiters seen)."""

    plan: list[Damage]
    frames: int = 0
    done: list[str] = field(default_factory=list)
    _since: int = -1
    _held: bool = False
    _flip: int | None = None
    _last: bytes = b""

    def __call__(self, data: bytes) -> bytes:
        if not self.plan and not self._held and self._flip is None:  # nothing to do: count
            self.frames += (self._last + data).count(b"\x06\x09")
            self._last = data[-1:] or self._last
            return data
        self._last = b""
        out = bytearray()
        for b in data:
            if self._held:
                self._held = False
                if b == 0x09:
                    self._start_frame(out)
                    continue
                self._byte(0x06, out)
            if b == 0x06:
                self._held = True
            else:
                self._byte(b, out)
        return bytes(out)

    def _start_frame(self, out: bytearray) -> None:
        self.frames += 1
        self._since = 0
        for d in [d for d in self.plan if d.frame == self.frames]:
            self.plan.remove(d)
            if d.before:
                out += d.before
                self.done.append(f"frame {d.frame}: {len(d.before)} bytes before it")
            if d.flip_at is not None:
                self._flip = d.flip_at
        out += b"\x06\x09"

    def _byte(self, b: int, out: bytearray) -> None:
        if self._flip is not None and self._since >= self._flip and b in BASE64:
            out.append(ord("B") if b == ord("A") else ord("A"))
            self.done.append(f"frame {self.frames}: byte {self._since} flipped")
            self._flip = None
        else:
            out.append(b)
        if self._since >= 0:
            self._since += 1


class NoisyPort:
    """A :class:`~adaproj_edge.hal.serial.SerialPort` whose line damages frames.

    Parameters
    ----------
    port : SerialPort
        The device's side of the real line.
    to_device : list of Damage
        What happens to the frames the host sends (as the server reads them).
    to_host : list of Damage
        What happens to the frames the server answers (as it writes them).
    """

    def __init__(
        self,
        port: SerialPort,
        to_device: list[Damage] | None = None,
        to_host: list[Damage] | None = None,
    ) -> None:
        self.port = port
        self.rx = Mangler(list(to_device or []))
        self.tx = Mangler(list(to_host or []))

    def read(self, size: int, timeout: float) -> bytes:
        return self.rx(self.port.read(size, timeout))

    def write(self, data: bytes) -> None:
        self.port.write(self.tx(data))

    def close(self) -> None:
        self.port.close()
