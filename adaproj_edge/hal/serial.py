"""The serial port: one small protocol, the pyserial driver, and a pty pair for tests.

On the device the port is the USB gadget's CDC-ACM function, ``/dev/ttyGS0``; in tests
and benchmarks it is one end of a pseudo-terminal pair made with :func:`os.openpty`.
Everything above this module (the SMP server, a session recorder) sees only
:class:`SerialPort`: read what has arrived within a timeout, write all of a buffer,
close. A recorder wraps a port and logs each chunk with its time; a replay feeds the
recorded chunks back through the same three calls.
"""

from __future__ import annotations

import errno
import logging
import os
import select
import termios
import time
import tty
from dataclasses import dataclass
from typing import Any, Protocol

from adaproj_edge.errors import DeviceError
from adaproj_edge.hal.oserrors import device_error

log = logging.getLogger(__name__)

DEVICE_PORT = "/dev/ttyGS0"
"""The gadget's ACM port on the device (see ``hw/gadget/``)."""

WRITE_TIMEOUT_S = 5.0
"""Longest wait for a host to take a reply before it is dropped."""

_CHECK = "the USB gadget (hw/gadget/adaproj-gadget.sh) and the udev rule in hw/udev/"


class SerialPort(Protocol):
    """A byte stream to the host computer.

    ``read`` returns at most ``size`` bytes: what has arrived, as soon as at least one
    byte is there, or ``b""`` when ``timeout`` seconds pass with nothing. ``write``
    sends all of ``data`` or raises :class:`~adaproj_edge.errors.DeviceError` (a host
    that does not read, or none connected: the bytes are dropped, the port goes on).
    A read never raises for an absent peer (an unplugged cable, a host that hung up):
    it just times out until the next host comes.
    """

    def read(self, size: int, timeout: float) -> bytes:
        """At most ``size`` bytes as soon as one has arrived; ``b""`` after ``timeout`` seconds."""
        ...

    def write(self, data: bytes) -> None:
        """Send all of ``data``."""
        ...

    def close(self) -> None:
        """Release the port."""
        ...


class PySerialPort:
    """A real serial device through pyserial (``/dev/ttyGS0``, ``/dev/ttyACM0``, a pty).

    A host that hangs up (the USB cable pulled, the host's port closed: the tty is hung
    up, reads see end-of-file) does not end the port: it is closed, and opened again
    on the next read (every ``timeout`` until it opens), so the next host is served
    without a restart. A host that stops reading makes a write give up after
    :data:`WRITE_TIMEOUT_S` with a :class:`~adaproj_edge.errors.DeviceError`, its
    unsent bytes dropped (and the writes after it at once, until the host reads again).

    Parameters
    ----------
    path : str
        The device file.
    baudrate : int
        Ignored by USB ACM and ptys; matters for a real UART.

    Attributes
    ----------
    reopened : int
        How many times the port was opened again after a hang-up.
    """

    def __init__(self, path: str, baudrate: int = 115200) -> None:
        self.path = path
        self.baudrate = baudrate
        self.reopened = 0
        self._ser: Any = None
        self._stalled = False  # the host left a write waiting: drop without waiting
        self._open()

    def _open(self) -> None:
        import serial

        try:
            self._ser = serial.Serial(
                self.path,
                baudrate=self.baudrate,
                timeout=0,
                write_timeout=WRITE_TIMEOUT_S,
                exclusive=True,
            )
        except serial.SerialException as e:
            cause = e.__cause__ if isinstance(e.__cause__, OSError) else None
            if cause is None and isinstance(e, OSError) and e.errno is not None:
                cause = e
            if cause is not None:
                raise device_error(cause, f"serial port {self.path}", _CHECK) from None
            raise DeviceError(f"cannot open serial port {self.path}: {e}; check {_CHECK}") from None

    def _hang_up(self, why: object) -> None:
        log.warning(
            "serial port %s: the host hung up (%s); waiting for the next one", self.path, why
        )
        try:
            self._ser.close()
        except Exception:  # a port that is gone cannot be closed cleanly either
            pass
        self._ser = None

    def _reopen(self, timeout: float) -> bool:
        try:
            self._open()
        except DeviceError:
            time.sleep(max(timeout, 0.0))
            return False
        self.reopened += 1
        self._stalled = False
        log.info("serial port %s open again", self.path)
        return True

    def read(self, size: int, timeout: float) -> bytes:
        """At most ``size`` bytes: the first one waited for up to ``timeout`` seconds, then
        whatever else is already buffered; ``b""`` on timeout, and while the port is
        being opened again after a hang-up."""
        import serial

        if self._ser is None and not self._reopen(timeout):
            return b""
        try:
            self._ser.timeout = timeout
            first: bytes = self._ser.read(1)
            if not first:
                return b""
            self._ser.timeout = 0
            rest: bytes = self._ser.read(min(max(size - 1, 0), self._ser.in_waiting))
        except (serial.SerialException, OSError, termios.error) as e:
            self._hang_up(e)
            return b""
        return first + rest

    def write(self, data: bytes) -> None:
        """Write ``data`` and wait until it has been sent; a :class:`DeviceError` when the
        host is gone or has not read for :data:`WRITE_TIMEOUT_S` (the bytes are dropped)."""
        import serial

        if self._ser is None:
            raise DeviceError(f"{self.path}: no host connected")
        try:
            self._ser.write_timeout = 0 if self._stalled else WRITE_TIMEOUT_S
            self._ser.write(data)
            self._ser.flush()
            self._stalled = False
        except serial.SerialTimeoutException:
            self._stalled = True
            self._ser.reset_output_buffer()
            raise DeviceError(
                f"{self.path}: the host has not read for {WRITE_TIMEOUT_S:g} s"
            ) from None
        except (serial.SerialException, OSError, termios.error) as e:
            self._hang_up(e)
            raise DeviceError(f"writing {self.path} failed: {e}; check {_CHECK}") from None

    def close(self) -> None:
        """Close the serial device."""
        if self._ser is not None:
            self._ser.close()
            self._ser = None


class FdPort:
    """A serial port on an open file descriptor (a pty master, an inherited fd).

    ``read`` treats ``EIO`` (a pty whose other side is closed) as "nothing yet". A
    write the peer does not take within :data:`WRITE_TIMEOUT_S` is given up
    (:class:`~adaproj_edge.errors.DeviceError`), and so, at once, is every write after
    it until the peer reads again: a host that stops reading costs the device one wait,
    not one per reply. The descriptor is closed by :meth:`close` only if ``own`` is true.
    """

    def __init__(self, fd: int, *, own: bool = False) -> None:
        self.fd = fd
        self._own = own
        self._stalled = False  # the peer left a write waiting: drop without waiting

    def read(self, size: int, timeout: float) -> bytes:
        """At most ``size`` bytes once the descriptor is readable within ``timeout`` seconds;
        ``b""`` on timeout or ``EIO``."""
        try:
            ready, _, _ = select.select([self.fd], [], [], max(timeout, 0.0))
        except (OSError, ValueError) as e:
            raise DeviceError(f"waiting on serial fd {self.fd} failed: {e}") from None
        if not ready:
            return b""
        try:
            return os.read(self.fd, size)
        except OSError as e:
            if e.errno == errno.EIO:  # no host on the other side: wait, do not spin
                time.sleep(max(min(timeout, 0.05), 0.0))
                return b""
            raise device_error(e, f"serial fd {self.fd}", "the pty pair") from None

    def write(self, data: bytes) -> None:
        """Write all of ``data``; a :class:`DeviceError` when the peer reads nothing for
        :data:`WRITE_TIMEOUT_S` (what was not written is dropped)."""
        view = memoryview(data)
        while view:
            wait = 0.0 if self._stalled else WRITE_TIMEOUT_S
            _, ready, _ = select.select([], [self.fd], [], wait)
            if not ready:
                self._stalled = True
                raise DeviceError(
                    f"serial fd {self.fd}: the peer has not read for {WRITE_TIMEOUT_S:g} s"
                )
            self._stalled = False
            try:
                n = os.write(self.fd, view)
            except OSError as e:
                if e.errno in (errno.EAGAIN, errno.EINTR):
                    continue
                raise device_error(e, f"serial fd {self.fd}", "the pty pair") from None
            view = view[n:]

    def close(self) -> None:
        """Close the descriptor if the port owns it."""
        if self._own:
            os.close(self.fd)


@dataclass
class PtyPair:
    """A pseudo-terminal pair in raw mode: a real tty that needs no hardware.

    The device side (the SMP server) uses :attr:`master` through :class:`FdPort`; a
    client opens :attr:`path` exactly as it would open ``/dev/ttyACM0``. The slave
    descriptor stays open so the master never sees ``EIO`` between clients.
    """

    master: int
    slave: int
    path: str

    @classmethod
    def open(cls) -> PtyPair:
        """A new pty pair, its slave side in raw mode."""
        master, slave = os.openpty()
        tty.setraw(slave, termios.TCSANOW)
        return cls(master, slave, os.ttyname(slave))

    def port(self) -> FdPort:
        """The device side as a :class:`SerialPort`."""
        return FdPort(self.master)

    def close(self) -> None:
        """Close both descriptors (errors ignored)."""
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
