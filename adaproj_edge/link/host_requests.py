"""The adaproj group's requests and responses for ``smpclient`` (the host side).

Each request class names its response and its two error shapes, as ``smpclient``
expects; :mod:`adaproj_edge.link.ids` has the numbers both ends agree on. The file
group's upload request is here too, with an error that keeps Zephyr's ``len`` (the
offset to resume at).
"""

from __future__ import annotations

from typing import Any

from smp import error as smperror
from smp import file_management as smpfs
from smp import message as smpmsg
from smp.error import MGMT_ERR

from adaproj_edge.link.ids import ADAPROJ_GROUP, AdaprojCommand


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
