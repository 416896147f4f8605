"""The host side of the link: uploads, downloads and content commands through noise.

Needs the ``host`` extra (``smpclient``). Every function takes a connected
``smpclient.SMPClient`` (a :class:`~adaproj_edge.link.connection.Link` from
:func:`connect`, or a plain one). An upload that meets line noise (see
:mod:`adaproj_edge.link.connection`) asks the device where it stands and goes on
from there; at the end the device's SHA-256 of the item is compared with the file's.
"""

from __future__ import annotations

import hashlib
from typing import Any

from smp.file_management import FS_MGMT_ERR
from smpclient import SMPClient
from smpclient.generics import success
from smpclient.requests.file_management import FileHashChecksum, FileStatus

from adaproj_edge.errors import LinkError
from adaproj_edge.link.connection import (
    NOISE,
    TIMEOUT_S,
    TRIES,
    Link,
    Notify,
    Progress,
    call,
    connect,
    describe,
    resync,
    run,
    send,
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

__all__ = [
    "ActivateWrite",
    "Link",
    "Progress",
    "activate",
    "call",
    "connect",
    "delete",
    "download_screenshot",
    "resume_point",
    "run",
    "send",
    "upload",
]


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
        except NOISE as e:
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
        except NOISE as e:
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
