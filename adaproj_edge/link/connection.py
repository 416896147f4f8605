"""The host's connection to the device: a client that learns the buffer and gets
through line noise.

Needs the ``host`` extra (``smpclient``). :func:`connect` opens a serial port as a
:class:`Link`; :func:`send` sends a request once, :func:`ask` and :func:`call` send it
again while the line loses or garbles it. The device's refusals come back as
:class:`~adaproj_edge.errors.LinkError` with the device's reason.

A request damaged on the way is dropped by the device, so it gets no answer
(:class:`~adaproj_edge.errors.LinkTimeoutError` after ``timeout_s``); a damaged reply
cannot be read (:class:`~adaproj_edge.errors.LinkGarbledError`). Either way the client
starts afresh (:func:`resync`: the port is closed and opened again, which empties the
buffers so no stale piece of a reply is taken for the next one, and the device's
buffer size is asked for again) and the request goes again, up to ``tries`` times in
a row. What happened is told through ``notify`` (one line each), never as a dump of
the frames.
"""

from __future__ import annotations

import asyncio
import logging
import os
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from smp import error as smperror
from smp.error import MGMT_ERR
from smpclient import SMPClient
from smpclient.generics import error, success
from smpclient.requests.os_management import MCUMgrParametersRead
from smpclient.transport import SMPTransportDisconnected
from smpclient.transport.serial import SMPSerialTransport

from adaproj_edge.errors import (
    DeviceNotFoundError,
    LinkError,
    LinkGarbledError,
    LinkTimeoutError,
)

TIMEOUT_S = 5.0
"""Longest wait for the answer to one request."""
HELLO_S = 1.0
"""Wait for the answer to the MCUmgr-parameters request at connect (immediate on a
live device; asked again until ``timeout_s`` has passed, at least 3 times)."""
OPEN_S = 2.0
"""Longest wait for the serial port to open."""
TRIES = 5
"""Requests sent in a row without a (readable) answer before the host gives up."""
REASON_CHARS = 160
"""Longest piece of a library's error message quoted in ours."""

Notify = Callable[[str], None]
Progress = Callable[[int, int], None]
NOISE = (LinkTimeoutError, LinkGarbledError)
"""The failures a request may meet on a noisy line (sending it again may help)."""


def _short(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= REASON_CHARS else text[: REASON_CHARS - 3] + "..."


class _Shorten(logging.Filter):
    """Cuts ``smpclient``'s log lines (a timeout line quotes the whole request)."""

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        if len(text) > 2 * REASON_CHARS:
            record.msg = f"{text[: 2 * REASON_CHARS]}... ({len(text)} characters)"
            record.args = None
        return True


def quiet_smpclient() -> None:
    """Keep ``smpclient``'s own log lines out of the way: we report what happened.

    With the root logger at DEBUG (``adaproj -v``) they stay, cut to a few hundred
    characters each.
    """
    logger = logging.getLogger("smpclient")
    verbose = logging.getLogger().getEffectiveLevel() <= logging.DEBUG
    logger.setLevel(logging.DEBUG if verbose else logging.CRITICAL)
    if not any(isinstance(f, _Shorten) for f in logger.filters):
        logger.addFilter(_Shorten())


class Link(SMPClient):
    """An ``SMPClient`` on a serial port that always learns the device's buffer size.

    ``smpclient`` asks for the MCUmgr parameters once at connect; when that one
    request is lost to noise it sends everything in frames of 256 bytes (about 1/100
    of the throughput of the device's 32 KiB buffer) for the whole session. A Link
    asks again until the device answers, and fails with a message that says how long
    it waited when it never does.

    Parameters
    ----------
    port : str
        The serial device (``/dev/ttyACM0``, a pty).
    timeout_s : float
        Longest wait for an answer to a request; at connect, how long the device may
        take to answer at all.

    Attributes
    ----------
    buf_size : int or None
        The buffer the device advertised (``None``: it has no parameters command).
    hellos : int
        Parameter requests sent over the Link's life (one per connect when the line
        is clean).
    """

    def __init__(self, port: str, timeout_s: float = TIMEOUT_S) -> None:
        self.transport = SMPSerialTransport()
        super().__init__(self.transport, port, timeout_s)
        self.timeout_s = timeout_s
        self.buf_size: int | None = None
        self.hellos = 0

    async def connect(self, connect_timeout_s: float | None = None) -> None:
        """Open the port, then ask for the device's buffer size until it answers."""
        await self._open()
        hello_s = min(HELLO_S, self.timeout_s)
        patience = max(self.timeout_s, 3 * hello_s)
        t0 = time.monotonic()
        tries = 0
        while True:
            tries += 1
            self.hellos += 1
            try:
                r = await send(self, MCUMgrParametersRead(), hello_s)
            except NOISE as e:
                waited = time.monotonic() - t0
                if waited >= patience:
                    raise LinkTimeoutError(
                        f"no answer from the device on {self.address} within {waited:.0f} s "
                        f"({tries} tries); is `adaproj link` (or the device) running on the "
                        "other end?"
                    ) from None
                if isinstance(e, LinkGarbledError):
                    await self.transport.disconnect()
                    await self._open()
                continue
            if success(r):
                self.buf_size = int(r.buf_size)
                self.transport.initialize(self.buf_size)
            return  # an error answer: no parameters command; the transport keeps its size

    async def _open(self) -> None:
        try:
            await self.transport.connect(self.address, OPEN_S)
        except TimeoutError:
            raise LinkError(f"cannot open {self.address}; is another program using it?") from None


@asynccontextmanager
async def connect(port: str, timeout_s: float = TIMEOUT_S) -> AsyncIterator[Link]:
    """A connected :class:`Link` on serial ``port``, sized to the device's buffer."""
    if not os.path.exists(port):
        raise DeviceNotFoundError(
            f"serial port {port} is not there; check the USB cable and `ls /dev/ttyACM*`"
        )
    quiet_smpclient()
    link = Link(port, timeout_s)
    try:
        await link.connect()
        yield link
    finally:
        await link.disconnect()


async def resync(client: SMPClient) -> None:
    """Start ``client`` afresh after a lost or garbled reply: close, open, hello."""
    await client.disconnect()
    try:
        await client.connect()
    except LinkError:
        raise
    except TimeoutError:
        raise LinkTimeoutError(f"no answer from the device on {client.address}") from None
    except Exception as e:  # a plain SMPClient's first request met a garbled reply
        raise LinkGarbledError(f"garbled reply on {client.address} ({_short(e)})") from None


# ---- requests --------------------------------------------------------------------------


def describe(response: Any) -> str:
    """One line for an error response: the code's name and the device's reason."""
    if isinstance(response, smperror.ErrorV1):
        reason = f": {response.rsn}" if response.rsn else ""
        return f"{MGMT_ERR(response.rc).name}{reason}"
    if isinstance(response, smperror.ErrorV2):
        rc = response.err.rc
        return f"{getattr(rc, 'name', rc)} (group {int(response.err.group)})"
    return _short(Exception(repr(response)))


async def send(client: SMPClient, message: Any, timeout_s: float = TIMEOUT_S) -> Any:
    """The response to request ``message`` (success or error), sent once.

    Raises
    ------
    LinkTimeoutError
        No answer within ``timeout_s``.
    LinkGarbledError
        An answer that cannot be read.
    LinkError
        The port went away.
    """
    try:
        return await client.request(message, timeout_s=timeout_s)
    except TimeoutError:
        raise LinkTimeoutError(
            f"no answer from the device on {client.address} within {timeout_s:g} s"
        ) from None
    except SMPTransportDisconnected as e:
        raise LinkError(f"lost {client.address} ({_short(e)}); check the USB cable") from None
    except Exception as e:  # smpclient raises many types for a damaged reply
        raise LinkGarbledError(
            f"garbled reply from the device on {client.address} ({_short(e)})"
        ) from None


async def ask(
    client: SMPClient,
    request: Any,
    timeout_s: float = TIMEOUT_S,
    *,
    tries: int = TRIES,
    notify: Notify | None = None,
) -> Any:
    """The response to ``request``, sent again after a :func:`resync` while the line
    loses or garbles it, ``tries`` times at most."""
    t0 = time.monotonic()
    attempt = 1
    while True:
        try:
            return await send(client, request, timeout_s)
        except NOISE as e:
            what = type(request).__name__
            if attempt >= tries:
                if tries == 1:
                    raise
                raise type(e)(
                    f"{what}: {e}; {tries} tries in {time.monotonic() - t0:.0f} s"
                ) from None
            attempt += 1
            if notify:
                notify(f"{what}: {e}; sending it again ({attempt} of {tries})")
            await resync(client)


async def call(
    client: SMPClient,
    request: Any,
    timeout_s: float = TIMEOUT_S,
    *,
    tries: int = TRIES,
    notify: Notify | None = None,
) -> Any:
    """The successful response to ``request`` (see :func:`ask`); :class:`LinkError` if
    the device refuses it."""
    response = await ask(client, request, timeout_s, tries=tries, notify=notify)
    if error(response):
        raise LinkError(f"device refused {type(request).__name__}: {describe(response)}")
    assert success(response)
    return response


def run(coro: Any) -> Any:
    """Run a coroutine for a command-line call."""
    return asyncio.run(coro)
