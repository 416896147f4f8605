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
import os
import select
import termios
import tty
from dataclasses import dataclass
from typing import Any, Protocol

from adaproj_edge.errors import DeviceError
from adaproj_edge.hal.oserrors import device_error

DEVICE_PORT = "/dev/ttyGS0"
"""The gadget's ACM port on the device (see ``hw/gadget/``)."""

_CHECK = "the USB gadget (hw/gadget/adaproj-gadget.sh) and the udev rule in hw/udev/"


class SerialPort(Protocol):
    """A byte stream to the host computer.

    ``read`` returns at most ``size`` bytes: what has arrived, as soon as at least one
    byte is there, or ``b""`` when ``timeout`` seconds pass with nothing. ``write``
    sends all of ``data`` or raises :class:`~adaproj_edge.errors.DeviceError`.
    Neither call raises for an absent peer (an unplugged cable): a read just times out.
    """

    def read(self, size: int, timeout: float) -> bytes: ...

    def write(self, data: bytes) -> None: ...

    def close(self) -> None: ...


class PySerialPort:
    """A real serial device through pyserial (``/dev/ttyGS0``, ``/dev/ttyACM0``, a pty).

    Parameters
    ----------
    path : str
        The device file.
    baudrate : int
        Ignored by USB ACM and ptys; matters for a real UART.
    """

    def __init__(self, path: str, baudrate: int = 115200) -> None:
        import serial

        self.path = path
        try:
            self._ser: Any = serial.Serial(path, baudrate=baudrate, timeout=0, exclusive=True)
        except serial.SerialException as e:
            cause = e.__cause__ if isinstance(e.__cause__, OSError) else None
            if cause is None and isinstance(e, OSError) and e.errno is not None:
                cause = e
            if cause is not None:
                raise device_error(cause, f"serial port {path}", _CHECK) from None
            raise DeviceError(f"cannot open serial port {path}: {e}; check {_CHECK}") from None

    def read(self, size: int, timeout: float) -> bytes:
        import serial

        try:
            self._ser.timeout = timeout
            first: bytes = self._ser.read(1)
            if not first:
                return b""
            self._ser.timeout = 0
            rest: bytes = self._ser.read(min(max(size - 1, 0), self._ser.in_waiting))
        except serial.SerialException as e:
            raise DeviceError(f"reading {self.path} failed: {e}; check {_CHECK}") from None
        return first + rest

    def write(self, data: bytes) -> None:
        import serial

        try:
            self._ser.write(data)
            self._ser.flush()
        except serial.SerialException as e:
            raise DeviceError(f"writing {self.path} failed: {e}; check {_CHECK}") from None

    def close(self) -> None:
        self._ser.close()


class FdPort:
    """A serial port on an open file descriptor (a pty master, an inherited fd).

    ``read`` treats ``EIO`` (a pty whose other side is closed) as "nothing yet".
    The descriptor is closed by :meth:`close` only if ``own`` is true.
    """

    def __init__(self, fd: int, *, own: bool = False) -> None:
        self.fd = fd
        self._own = own

    def read(self, size: int, timeout: float) -> bytes:
        try:
            ready, _, _ = select.select([self.fd], [], [], max(timeout, 0.0))
        except (OSError, ValueError) as e:
            raise DeviceError(f"waiting on serial fd {self.fd} failed: {e}") from None
        if not ready:
            return b""
        try:
            return os.read(self.fd, size)
        except OSError as e:
            if e.errno == errno.EIO:
                return b""
            raise device_error(e, f"serial fd {self.fd}", "the pty pair") from None

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            _, ready, _ = select.select([], [self.fd], [], 5.0)
            if not ready:
                raise DeviceError(f"serial fd {self.fd}: the peer has not read for 5 s")
            try:
                n = os.write(self.fd, view)
            except OSError as e:
                if e.errno in (errno.EAGAIN, errno.EINTR):
                    continue
                raise device_error(e, f"serial fd {self.fd}", "the pty pair") from None
            view = view[n:]

    def close(self) -> None:
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
        master, slave = os.openpty()
        tty.setraw(slave, termios.TCSANOW)
        return cls(master, slave, os.ttyname(slave))

    def port(self) -> FdPort:
        """The device side as a :class:`SerialPort`."""
        return FdPort(self.master)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> PtyPair:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
