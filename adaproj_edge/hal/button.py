"""The push button: Linux ``gpio-keys`` -> ``/dev/input/eventN``.

The kernel delivers ``struct input_event`` records (``linux/input.h``)::

    struct input_event { struct timeval time; __u16 type; __u16 code; __s32 value; };

which on 64-bit Linux is ``"llHHi"`` (24 bytes). They are read with :mod:`struct`;
``EV_KEY`` records for the board's key code become :class:`ButtonEvent` s (value 1
press, 0 release; 2, autorepeat, is dropped). The driver asks the kernel for
``CLOCK_MONOTONIC`` timestamps (``EVIOCSCLOCKID``) so they share the clock of the
rest of the device.
"""

from __future__ import annotations

import fcntl
import os
import select
import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

from adaproj_edge.errors import InputError
from adaproj_edge.hal.clock import Clock, VirtualClock
from adaproj_edge.hal.oserrors import device_error
from adaproj_edge.hal.recorded import ReplayStream

EV_SYN = 0x00
EV_KEY = 0x01
KEY_RELEASE, KEY_PRESS, KEY_REPEAT = 0, 1, 2
EVENT_FORMAT = "llHHi"
EVIOCSCLOCKID = 0x400445A0  # _IOW('E', 0xa0, int)
CLOCK_MONOTONIC = 1


@dataclass(frozen=True)
class InputEvent:
    """One ``struct input_event``; ``time_ns`` from its ``timeval``."""

    time_ns: int
    type: int
    code: int
    value: int


@dataclass(frozen=True)
class ButtonEvent:
    """A press (``pressed``) or release of key ``code``.

    ``sensor_ns`` is the kernel's timestamp of the edge, ``receive_ns`` when the
    process read it (both on the device's monotonic clock).
    """

    sensor_ns: int
    receive_ns: int
    code: int
    pressed: bool


class InputEventParser:
    """Turns a byte stream into :class:`InputEvent` s; keeps a partial record for later."""

    def __init__(self, fmt: str = EVENT_FORMAT) -> None:
        self._struct = struct.Struct(fmt)
        self._buf = b""

    @property
    def record_size(self) -> int:
        return self._struct.size

    def feed(self, data: bytes) -> list[InputEvent]:
        self._buf += data
        n = len(self._buf) // self._struct.size
        out = []
        for i in range(n):
            sec, usec, typ, code, value = self._struct.unpack_from(self._buf, i * self._struct.size)
            out.append(InputEvent(sec * 1_000_000_000 + usec * 1000, typ, code, value))
        self._buf = self._buf[n * self._struct.size :]
        return out

    @property
    def pending(self) -> int:
        """Bytes of an incomplete record still waiting for the rest."""
        return len(self._buf)


def key_events(events: Iterable[InputEvent], code: int, receive_ns: int) -> list[ButtonEvent]:
    """Press/release edges of key ``code`` among ``events``."""
    return [
        ButtonEvent(e.time_ns, receive_ns, code, e.value == KEY_PRESS)
        for e in events
        if e.type == EV_KEY and e.code == code and e.value in (KEY_PRESS, KEY_RELEASE)
    ]


class Button(Protocol):
    """The device's push button."""

    def read(self, timeout_s: float = 0.0) -> ButtonEvent | None:
        """The next press or release, or None if none came within ``timeout_s``."""
        ...

    def close(self) -> None: ...


class EvdevButton:
    """The real button: an evdev node (``gpio-keys``) read without third-party code."""

    def __init__(self, path: str, key_code: int, clock: Clock, fmt: str = EVENT_FORMAT) -> None:
        self.path = path
        self.key_code = key_code
        self._clock = clock
        self._parser = InputEventParser(fmt)
        self._queue: list[ButtonEvent] = []
        try:
            self._fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError as e:
            raise device_error(e, f"button {path}", _CHECK) from None
        try:
            fcntl.ioctl(self._fd, EVIOCSCLOCKID, struct.pack("i", CLOCK_MONOTONIC))
        except OSError:
            pass  # not an evdev node (a pipe or file in tests): timestamps as given

    def read(self, timeout_s: float = 0.0) -> ButtonEvent | None:
        deadline = time.monotonic() + timeout_s
        while not self._queue:
            left = max(0.0, deadline - time.monotonic())
            try:
                ready, _, _ = select.select([self._fd], [], [], left)
                if not ready:
                    return None
                data = os.read(self._fd, 64 * self._parser.record_size)
            except BlockingIOError:
                continue
            except OSError as e:
                raise device_error(e, f"button {self.path}", _CHECK) from None
            if not data:  # end of file (a recording or closed pipe)
                return None
            self._queue.extend(
                key_events(self._parser.feed(data), self.key_code, self._clock.now_ns())
            )
        return self._queue.pop(0)

    def close(self) -> None:
        os.close(self._fd)


_CHECK = "the gpio-keys overlay, the button wiring and the event device in the board file"


class ReplayButton:
    """Button events from a recording, on a virtual clock."""

    def __init__(self, events: Iterable[ButtonEvent], clock: VirtualClock) -> None:
        self._stream = ReplayStream(events, clock)

    def read(self, timeout_s: float = 0.0) -> ButtonEvent | None:
        return self._stream.next()

    def close(self) -> None:
        pass


def check_key_code(code: int) -> int:
    """Validate a key code from a board file (``linux/input-event-codes.h`` range)."""
    if not 0 < code < 0x300:
        raise InputError(f"key code {code} is outside the Linux key code range 1..767")
    return code
