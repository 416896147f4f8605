"""The host side: the adaproj group for ``smpclient``, and resumable uploads.

Needs the ``host`` extra (``smpclient``). Every function takes a connected
``smpclient.SMPClient``; :func:`connect` makes one for a serial port. Device errors
come back as :class:`~adaproj_edge.errors.LinkError` with the device's reason.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import os
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from typing import Any

from smp import error as smperror
from smp import file_management as smpfs
from smp import message as smpmsg
from smp.error import MGMT_ERR
from smp.file_management import FS_MGMT_ERR
from smpclient import SMPClient
from smpclient.generics import error, success
from smpclient.requests.file_management import FileHashChecksum, FileStatus
from smpclient.transport.serial import SMPSerialTransport

from adaproj_edge.errors import DeviceNotFoundError, LinkError
from adaproj_edge.link.ids import ADAPROJ_GROUP, AdaprojCommand

TIMEOUT_S = 5.0


# ---- the adaproj group's messages ----------------------------------------------------


class AdaprojErrorV1(smperror.ErrorV1):
    """A management error from the adaproj group (``rc`` and the reason ``rsn``)."""

    _GROUP_ID = ADAPROJ_GROUP


class AdaprojErrorV2(smperror.ErrorV2[MGMT_ERR]):
    _GROUP_ID = ADAPROJ_GROUP


class _Group:
    _ErrorV1 = AdaprojErrorV1
    _ErrorV2 = AdaprojErrorV2


class ListResponse(smpmsg.ReadResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.LIST

    items: list[dict[str, Any]]
    pending: list[dict[str, Any]]
    active: dict[str, Any] | None = None
    used: int
    quota: int


class ListRead(smpmsg.ReadRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.LIST
    _Response = ListResponse


class ActivateResponse(smpmsg.WriteResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.ACTIVATE

    active: dict[str, Any]


class ActivateWrite(smpmsg.WriteRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.ACTIVATE
    _Response = ActivateResponse

    image: str
    mask: str | None = None
    settings: dict[str, Any] | None = None


class DeleteResponse(smpmsg.WriteResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.DELETE


class DeleteWrite(smpmsg.WriteRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.DELETE
    _Response = DeleteResponse

    name: str


class StatusResponse(smpmsg.ReadResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.STATUS

    device: dict[str, Any]
    store: dict[str, Any]
    link: dict[str, Any]


class StatusRead(smpmsg.ReadRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.STATUS
    _Response = StatusResponse


class ScreenshotResponse(smpmsg.ReadResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.SCREENSHOT

    off: int
    data: bytes
    len: int | None = None


class ScreenshotRead(smpmsg.ReadRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.SCREENSHOT
    _Response = ScreenshotResponse

    off: int


class UploadStateResponse(smpmsg.ReadResponse):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.UPLOAD_STATE

    name: str
    off: int
    len: int
    sha: bytes


class UploadStateRead(smpmsg.ReadRequest, _Group):
    _GROUP_ID = ADAPROJ_GROUP
    _COMMAND_ID = AdaprojCommand.UPLOAD_STATE
    _Response = UploadStateResponse

    name: str


class FileUploadErrorV2(smpfs.FileSystemManagementErrorV2):
    """The file group's error; an offset error carries the device's ``len`` (Zephyr)."""

    len: int | None = None


class FileUploadResumable(smpfs.FileUploadRequest):
    """``FileUpload`` whose offset error keeps ``len``, the offset to resume at."""

    _Response = smpfs.FileUploadResponse
    _ErrorV1 = smpfs.FileSystemManagementErrorV1
    _ErrorV2 = FileUploadErrorV2


# ---- calls ----------------------------------------------------------------------------


def describe(response: Any) -> str:
    """One line for an error response: the code's name and the device's reason."""
    if isinstance(response, smperror.ErrorV1):
        reason = f": {response.rsn}" if response.rsn else ""
        return f"{MGMT_ERR(response.rc).name}{reason}"
    if isinstance(response, smperror.ErrorV2):
        rc = response.err.rc
        return f"{getattr(rc, 'name', rc)} (group {int(response.err.group)})"
    return repr(response)


async def send(client: SMPClient, message: Any, timeout_s: float = TIMEOUT_S) -> Any:
    """The response to request ``message``, success or error; :class:`LinkError` if none."""
    try:
        return await client.request(message, timeout_s=timeout_s)
    except TimeoutError:
        raise LinkError(
            f"no answer from the device on {client.address} within {timeout_s:g} s; "
            "is `adaproj link` (or the device) running on the other end?"
        ) from None
    except Exception as e:  # smpclient raises its own types for broken replies
        raise LinkError(f"bad reply from the device on {client.address}: {e}") from None


async def call(client: SMPClient, request: Any, timeout_s: float = TIMEOUT_S) -> Any:
    """The successful response to ``request``; :class:`LinkError` otherwise."""
    response = await send(client, request, timeout_s)
    if error(response):
        raise LinkError(f"device refused {type(request).__name__}: {describe(response)}")
    assert success(response)
    return response


@asynccontextmanager
async def connect(port: str, timeout_s: float = TIMEOUT_S) -> AsyncIterator[SMPClient]:
    """A connected client on serial ``port``, sized to the device's advertised buffer."""
    if not os.path.exists(port):
        raise DeviceNotFoundError(
            f"serial port {port} is not there; check the USB cable and `ls /dev/ttyACM*`"
        )
    logging.getLogger("smpclient").setLevel(logging.WARNING)  # its INFO lines are noise here
    client = SMPClient(SMPSerialTransport(), port, timeout_s=timeout_s)
    try:
        await client.connect()
    except (TimeoutError, OSError) as e:
        raise LinkError(f"cannot open {port}: {e}; is another program using it?") from None
    try:
        yield client
    finally:
        await client.disconnect()


Progress = Callable[[int, int], None]


async def resume_point(
    client: SMPClient, data: bytes, name: str, timeout_s: float = TIMEOUT_S
) -> int | None:
    """Where an upload of ``data`` as ``name`` can go on; ``None`` if already there.

    The device's pending upload is used only if its declared size matches and the
    SHA-256 of what it holds equals that of the same prefix of ``data``.
    """
    state = await call(client, UploadStateRead(name=name), timeout_s)
    if state.len == len(data) and 0 < state.off <= len(data):
        if hashlib.sha256(data[: state.off]).digest() == state.sha:
            return int(state.off)
    response = await send(client, FileStatus(name=name), timeout_s)
    if success(response) and response.len == len(data):
        digest = await call(client, FileHashChecksum(name=name, type="sha256"), timeout_s)
        if digest.output == hashlib.sha256(data).digest():
            return None
    return 0


async def upload(
    client: SMPClient,
    data: bytes,
    name: str,
    progress: Progress | None = None,
    *,
    resume: bool = True,
    timeout_s: float = TIMEOUT_S,
) -> int:
    """Upload ``data`` as item ``name``, resuming what the device already holds.

    Returns the offset the transfer started at (``len(data)`` when the device already
    had the file). Chunks fill the device's advertised buffer.
    """
    off = await resume_point(client, data, name, timeout_s) if resume else 0
    if off is None:
        if progress:
            progress(len(data), len(data))
        return len(data)
    start = off
    retries = 0
    acked = -1  # the offset the device last acknowledged; it commits when that is the end
    if progress:
        progress(off, len(data))
    while acked != len(data):
        total = len(data) if off == 0 else None
        probe = FileUploadResumable(name=name, off=off, data=b"", len=total)
        _, room = client.get_max_cbor_and_data_size(probe)
        chunk = data[off : off + max(room, 1)]
        request = FileUploadResumable(name=name, off=off, data=chunk, len=total)
        response = await send(client, request, timeout_s)
        if success(response):
            off = acked = response.off
            retries = 0
            if progress:
                progress(off, len(data))
            continue
        if (
            isinstance(response, FileUploadErrorV2)
            and response.err.rc == FS_MGMT_ERR.FILE_OFFSET_NOT_VALID
            and retries < 3
        ):
            retries += 1
            resumed = await resume_point(client, data, name, timeout_s)
            if resumed is None:
                if progress:
                    progress(len(data), len(data))
                break
            off = resumed
            continue
        raise LinkError(f"upload of {name} refused: {describe(response)}")
    return start


async def download_screenshot(client: SMPClient) -> bytes:
    """The frame the projector shows now, as PNG bytes."""
    first = await call(client, ScreenshotRead(off=0))
    total = int(first.len or 0)
    data = bytearray(first.data)
    while len(data) < total:
        chunk = await call(client, ScreenshotRead(off=len(data)))
        if not chunk.data:
            raise LinkError("the device sent an empty screenshot chunk")
        data += chunk.data
    return bytes(data)


def run(coro: Any) -> Any:
    """Run a coroutine for a command-line call."""
    return asyncio.run(coro)
