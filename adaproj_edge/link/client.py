"""The host side of the link: requests, uploads and downloads that get through line noise.

Needs the ``host`` extra (``smpclient``). :func:`connect` opens a serial port as a
:class:`Link`; every other function takes a connected ``smpclient.SMPClient`` (a
:class:`Link` or a plain one). The device's refusals come back as
:class:`~adaproj_edge.errors.LinkError` with the device's reason.

Line noise
----------
A request damaged on the way is dropped by the device, so it gets no answer
(:class:`~adaproj_edge.errors.LinkTimeoutError` after ``timeout_s``); a damaged reply
cannot be read (:class:`~adaproj_edge.errors.LinkGarbledError`). Either way the client
starts afresh (:func:`resync`: the port is closed and opened again, which empties the
buffers so no stale piece of a reply is taken for the next one, and the device's
buffer size is asked for again) and sends the request again, up to ``tries`` times in
a row. An upload then asks the device where it stands and goes on from there; at the
end the device's SHA-256 of the item is compared with the file's. What happened is
told through ``notify`` (one line each), never as a dump of the frames.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import os
import time
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from smp import error as smperror
from smp.error import MGMT_ERR
from smp.file_management import FS_MGMT_ERR
from smpclient import SMPClient
from smpclient.generics import error, success
from smpclient.requests.file_management import FileHashChecksum, FileStatus
from smpclient.requests.os_management import MCUMgrParametersRead
from smpclient.transport import SMPTransportDisconnected
from smpclient.transport.serial import SMPSerialTransport

from adaproj_edge.errors import (
    DeviceNotFoundError,
    LinkError,
    LinkGarbledError,
    LinkTimeoutError,
)
from adaproj_edge.link.host_requests import (
    ActivateWrite,
    DeleteWrite,
    FileUploadErrorV2,
    FileUploadResumable,
    ListRead,
    ScreenshotRead,
    UploadStateRead,
)
from adaproj_edge.link.store import check_name

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
_NOISE = (LinkTimeoutError, LinkGarbledError)


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
    request is lost to noise it sends everything in frames of 256 bytes (about 1/80
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
            except _NOISE as e:
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
        except _NOISE as e:
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


# ---- content ---------------------------------------------------------------------------


async def resume_point(
    client: SMPClient, data: bytes, name: str, timeout_s: float = TIMEOUT_S
) -> int | None:
    """Where an upload of ``data`` as ``name`` can go on; ``None`` if already there.

    The device's pending upload is used only if its declared size matches and the
    SHA-256 of what it holds equals that of the same prefix of ``data``; a committed
    item counts as there only if its SHA-256 is that of ``data``. Each request is
    sent once (noise raises).
    """
    state = await _once(client, UploadStateRead(name=name), timeout_s)
    if state.len == len(data) and 0 < state.off <= len(data):
        if hashlib.sha256(data[: state.off]).digest() == state.sha:
            return int(state.off)
    response = await send(client, FileStatus(name=name), timeout_s)
    if success(response) and response.len == len(data):
        digest = await _once(client, FileHashChecksum(name=name, type="sha256"), timeout_s)
        if digest.output == hashlib.sha256(data).digest():
            return None
    return 0


async def _once(client: SMPClient, request: Any, timeout_s: float) -> Any:
    return await call(client, request, timeout_s, tries=1)


def _chunk(client: SMPClient, data: bytes, name: str, off: int) -> FileUploadResumable:
    """The upload request at ``off`` carrying as much data as the device's buffer takes."""
    total = len(data) if off == 0 else None
    probe = FileUploadResumable(name=name, off=off, data=b"", len=total)
    _, room = client.get_max_cbor_and_data_size(probe)
    return FileUploadResumable(name=name, off=off, data=data[off : off + max(room, 1)], len=total)


async def upload(
    client: SMPClient,
    data: bytes,
    name: str,
    progress: Progress | None = None,
    *,
    resume: bool = True,
    timeout_s: float = TIMEOUT_S,
    tries: int = TRIES,
    notify: Notify | None = None,
) -> int:
    """Upload ``data`` as item ``name``, resuming what the device holds, through noise.

    Parameters
    ----------
    client : SMPClient
        Connected; chunks fill the device's advertised buffer.
    data : bytes
        The file.
    name : str
        The item's name on the device.
    progress : callable, optional
        ``progress(done, total)`` after each acknowledged chunk.
    resume : bool
        Go on from what the device already holds (``False``: start at byte 0; after
        noise the upload still goes on from what this call has sent).
    timeout_s : float
        Longest wait for each answer.
    tries : int
        Failures (no answer, garbled answer) in a row before giving up; each
        acknowledged chunk starts the count again.
    notify : callable, optional
        Told, one line at a time, about each failure and where the upload goes on.

    Returns
    -------
    int
        The offset the transfer started at (``len(data)`` when the device already
        had the file).
    """
    total = len(data)
    report: Progress = progress or (lambda done, of: None)
    say: Notify = notify or (lambda line: None)
    off: int | None = None if resume else 0
    start: int | None = None
    failures = fixes = ends = 0
    broken = False
    while True:
        try:
            if broken:
                await resync(client)
                broken = False
            if off is None:
                found = await resume_point(client, data, name, timeout_s)
                if found is None:
                    report(total, total)
                    return total if start is None else start
                if ends:
                    if ends > 1:
                        raise LinkError(f"the device's copy of {name} differs from the file twice")
                    say(f"{name}: the device's copy differs from the file; sending it again")
                elif start is not None:
                    say(f"{name}: the device holds {found} of {total} bytes; going on from there")
                off = found
            if start is None:
                start = off
                report(off, total)
            response = await send(client, _chunk(client, data, name, off), timeout_s)
        except _NOISE as e:
            failures += 1
            where = (
                "while asking where the upload stands"
                if off is None
                else f"to the chunk at byte {off} of {total}"
            )
            if failures >= tries:
                raise type(e)(
                    f"upload of {name} stopped: {e} {where} ({tries} tries in a row); the "
                    "device keeps what it has received: the same command goes on from there"
                ) from None
            say(f"{name}: {e} {where}; reconnecting to go on (try {failures + 1} of {tries})")
            off, broken = None, True
            continue
        if success(response):
            off = int(response.off)
            failures = fixes = 0
            report(off, total)
            if off >= total:  # committed: check the device's copy, by its SHA-256
                ends += 1
                off = None
            continue
        offset_error = (
            isinstance(response, FileUploadErrorV2)
            and response.err.rc == FS_MGMT_ERR.FILE_OFFSET_NOT_VALID
        )
        if offset_error and fixes < 3:
            fixes += 1
            off = None
            continue
        raise LinkError(f"upload of {name} refused: {describe(response)}")


async def download_screenshot(client: SMPClient, **kw: Any) -> bytes:
    """The frame the projector shows now, as PNG bytes (``kw`` as for :func:`call`)."""
    first = await call(client, ScreenshotRead(off=0), **kw)
    size = int(first.len or 0)
    data = bytearray(first.data)
    while len(data) < size:
        chunk = await call(client, ScreenshotRead(off=len(data)), **kw)
        if not chunk.data:
            raise LinkError("the device sent an empty screenshot chunk")
        data += chunk.data
    return bytes(data)


async def delete(
    client: SMPClient,
    name: str,
    timeout_s: float = TIMEOUT_S,
    *,
    tries: int = TRIES,
    notify: Notify | None = None,
) -> None:
    """Remove item ``name``. When an answer is lost, the device's list tells whether
    the delete went through before it is sent again."""
    item = check_name(name)
    for attempt in range(1, tries + 1):
        try:
            await call(client, DeleteWrite(name=name), timeout_s, tries=1)
            return
        except _NOISE as e:
            if attempt == tries:
                raise
            if notify:
                notify(f"delete {item}: {e}; checking whether it went through")
            await resync(client)
        listed = await call(client, ListRead(), timeout_s, tries=tries, notify=notify)
        if item not in {i["name"] for i in listed.items}:
            return


async def activate(
    client: SMPClient,
    image: str,
    mask: str | None = None,
    settings: dict[str, Any] | None = None,
    *,
    keep_mask: bool = True,
    **kw: Any,
) -> dict[str, Any]:
    """Show ``image``; returns the device's active record.

    Without ``mask`` and with ``keep_mask``, an image that is already shown keeps
    the mask it is shown with (so changing its settings does not drop its mask);
    another image is shown without one. ``kw`` as for :func:`call`.
    """
    if mask is None and keep_mask:
        active = (await call(client, ListRead(), **kw)).active or {}
        if active.get("image") == check_name(image) and active.get("mask"):
            mask = str(active["mask"])
    request = ActivateWrite(image=image, mask=mask, settings=settings)
    active_now: dict[str, Any] = (await call(client, request, **kw)).active
    return active_now


def run(coro: Any) -> Any:
    """Run a coroutine for a command-line call."""
    return asyncio.run(coro)
