"""The SMP server: OS, file-system and adaproj groups over a serial port.

:class:`Server` turns one request message into one reply (or into nothing, for what
is not a request); :func:`serve` runs it on a :class:`~adaproj_edge.hal.serial.SerialPort`.
Every request is answered: success, or an SMP error with a reason. Bad bytes and bad
requests are logged and answered (or dropped, when they are not even a frame); no
input makes the server raise. Logging comes in bursts (the first few refusals of a run
one by one, then a summary), and the routine "no" a host gets while it looks for
where to resume an upload (:data:`PROBES`) is neither a warning nor an error.

Groups
------
OS (0)
    echo (0), reset (5), MCUmgr parameters (6).
File system (8)
    upload/download (0), status (1), hash/checksum (2), supported hash types (3),
    close (4). Names are content-store names; see :func:`~adaproj_edge.link.store.check_name`.
adaproj (65)
    see :class:`~adaproj_edge.link.ids.AdaprojCommand`.

This file is about 420 lines on purpose: one class with one small handler per SMP
command, dispatched from one table, sharing the server's upload state and counters.
"""

from __future__ import annotations

import errno
import hashlib
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from smp.error import MGMT_ERR
from smp.file_management import FS_MGMT_ERR
from smp.header import CommandId, GroupId

from adaproj_edge.errors import (
    AdaprojError,
    ContentNotFoundError,
    DeviceError,
    InputError,
    QuotaError,
    UploadOffsetError,
)
from adaproj_edge.hal.serial import SerialPort
from adaproj_edge.link.burstlog import BurstLog
from adaproj_edge.link.device import Content, DeviceRuntime, Settings
from adaproj_edge.link.framing import FrameDecoder, encode_frame
from adaproj_edge.link.ids import ADAPROJ_GROUP, BUF_SIZE, AdaprojCommand
from adaproj_edge.link.message import (
    HEADER,
    Op,
    Request,
    SmpError,
    decode_body,
    field,
    optional,
    parse_header,
)
from adaproj_edge.link.store import ActiveRecord, ContentStore, check_name

log = logging.getLogger(__name__)

OS = int(GroupId.OS_MANAGEMENT)
FS = int(GroupId.FILE_MANAGEMENT)
OSC = CommandId.OSManagement
FSC = CommandId.FileManagement
Handler = Callable[[Request], dict[str, Any]]
HASH_TYPES = {"sha256": {"format": 1, "size": 32}, "crc32": {"format": 0, "size": 4}}
REPLY_MARGIN = 64
"""Bytes of a reply's header and CBOR keys next to a data chunk."""
PROBES = {
    (FS, FSC.FILE_STATUS, FS_MGMT_ERR.FILE_NOT_FOUND),
    (FS, FSC.FILE_HASH_CHECKSUM, FS_MGMT_ERR.FILE_NOT_FOUND),
    (FS, FSC.FILE_DOWNLOAD_UPLOAD, FS_MGMT_ERR.FILE_OFFSET_NOT_VALID),
}
"""(group, command, group error) of the answers a host gets while it finds where an
upload goes on: no such file yet, or "this offset does not continue the upload, go on
at ``len``". Counted as ``probes``, logged at DEBUG."""


class Server:
    """Answers SMP requests from the content store and the device runtime.

    Parameters
    ----------
    store : ContentStore
        Where uploads land.
    device : DeviceRuntime
        The running projector (or :class:`~adaproj_edge.link.device.StandaloneDevice`).
    buf_size : int
        The advertised SMP buffer: requests up to ``buf_size - 4`` bytes are taken.
    on_reset : callable, optional
        Called after the reply to an OS reset has been sent.

    Attributes
    ----------
    counters : dict
        ``requests`` handled, ``errors`` (refused), ``ignored`` (not requests) and
        ``probes`` (routine resume answers, :data:`PROBES`).
    decoder : FrameDecoder
        The wire decoder :func:`serve` feeds; its ``stats`` count the bad frames.
    """

    def __init__(
        self,
        store: ContentStore,
        device: DeviceRuntime,
        *,
        buf_size: int = BUF_SIZE,
        on_reset: Callable[[], None] | None = None,
    ) -> None:
        if not 64 <= buf_size <= 0xFFFF:
            raise ValueError(f"buf_size must be in 64..65535, not {buf_size}")
        self.store = store
        self.device = device
        self.buf_size = buf_size
        self.max_message = buf_size - 4
        self.on_reset = on_reset
        self.counters = {"requests": 0, "errors": 0, "ignored": 0, "probes": 0}
        self.decoder = FrameDecoder(self.max_message)
        self._refusals = BurstLog(log, "requests refused")
        self.after_reply: Callable[[], None] | None = None
        self._screenshot = b""
        A = AdaprojCommand
        self._handlers: dict[tuple[int, int, int], Handler] = {
            (OS, OSC.ECHO, Op.WRITE): self._echo,
            (OS, OSC.RESET, Op.WRITE): self._reset,
            (OS, OSC.MCUMGR_PARAMETERS, Op.READ): self._params,
            (FS, FSC.FILE_DOWNLOAD_UPLOAD, Op.WRITE): self._upload,
            (FS, FSC.FILE_DOWNLOAD_UPLOAD, Op.READ): self._download,
            (FS, FSC.FILE_STATUS, Op.READ): self._file_status,
            (FS, FSC.FILE_HASH_CHECKSUM, Op.READ): self._file_hash,
            (FS, FSC.SUPPORTED_FILE_HASH_CHECKSUM_TYPES, Op.READ): lambda r: {"types": HASH_TYPES},
            (FS, FSC.FILE_CLOSE, Op.WRITE): lambda r: {},
            (ADAPROJ_GROUP, A.LIST, Op.READ): self._list,
            (ADAPROJ_GROUP, A.ACTIVATE, Op.WRITE): self._activate,
            (ADAPROJ_GROUP, A.DELETE, Op.WRITE): self._delete,
            (ADAPROJ_GROUP, A.STATUS, Op.READ): self._status,
            (ADAPROJ_GROUP, A.SCREENSHOT, Op.READ): self._screenshot_chunk,
            (ADAPROJ_GROUP, A.UPLOAD_STATE, Op.READ): self._upload_state,
        }
        self.restore_active()

    # ---- dispatch ---------------------------------------------------------------

    def handle(self, message: bytes) -> bytes | None:
        """The reply to one SMP message, or ``None`` if it is not a request."""
        self.after_reply = None
        try:
            op, version, flags, length, group, seq, cmd = parse_header(message)
        except ValueError as e:
            self.counters["ignored"] += 1
            log.warning("ignored a message: %s", e)
            return None
        if op not in (Op.READ, Op.WRITE):
            self.counters["ignored"] += 1
            log.warning("ignored an SMP message with op %d (not a request)", op)
            return None
        req = Request(op, version, flags, group, seq, cmd, {})
        self.counters["requests"] += 1
        try:
            if version > 1:
                raise SmpError(MGMT_ERR.UNSUPPORTED_TOO_NEW, f"SMP version {version} is too new")
            if length != len(message) - HEADER.size:
                raise SmpError(
                    MGMT_ERR.EINVAL,
                    f"header says {length} body bytes, {len(message) - HEADER.size} came",
                )
            handler = self._handlers.get((group, cmd, op))
            if handler is None:
                raise SmpError(
                    MGMT_ERR.ENOTSUP, f"no {Op(op).name.lower()} command {cmd} in group {group}"
                )
            body = decode_body(message[HEADER.size :])
            req = Request(op, version, flags, group, seq, cmd, body)
            reply = req.reply(handler(req))
            self._refusals.ok()
            return reply
        except SmpError as e:
            return self._refuse(req, e)
        except Exception as e:  # the server must answer, whatever went wrong inside
            smp_error = self._translate(req, e)
            if smp_error.rc == MGMT_ERR.EUNKNOWN:
                log.exception("request %d/%d failed", group, cmd)
            return self._refuse(req, smp_error)

    def _refuse(self, req: Request, e: SmpError) -> bytes:
        if e.group is not None and (req.group, req.command, e.rc) in PROBES:
            self.counters["probes"] += 1
            log.debug("group %d command %d: %s", req.group, req.command, e)
        else:
            self.counters["errors"] += 1
            self._refusals.bad(
                f"{req.group}/{req.command} rc {e.rc}",
                "group %d command %d refused (rc %d): %s",
                req.group,
                req.command,
                e.rc,
                e,
            )
        return req.error(e)

    def _translate(self, req: Request, e: Exception) -> SmpError:
        """The SMP error for an exception raised by the store or the device."""
        fs = req.group == FS
        if isinstance(e, ContentNotFoundError):
            if fs:
                return SmpError(
                    FS_MGMT_ERR.FILE_NOT_FOUND, str(e), group=FS, legacy=MGMT_ERR.ENOENT
                )
            return SmpError(MGMT_ERR.ENOENT, str(e))
        if isinstance(e, UploadOffsetError):
            if fs and req.op == Op.READ:
                return SmpError(FS_MGMT_ERR.FILE_OFFSET_LARGER_THAN_FILE, str(e), group=FS)
            extra = {"len": e.expected} if fs else {}
            return SmpError(FS_MGMT_ERR.FILE_OFFSET_NOT_VALID, str(e), group=FS, extra=extra)
        if isinstance(e, QuotaError):
            return SmpError(MGMT_ERR.ENOMEM, str(e))
        if isinstance(e, InputError):
            return SmpError(MGMT_ERR.EINVAL, str(e))
        if isinstance(e, AdaprojError):
            return SmpError(MGMT_ERR.EBADSTATE, str(e))
        if isinstance(e, OSError):
            rc = MGMT_ERR.ENOMEM if e.errno in (errno.ENOSPC, errno.EDQUOT) else MGMT_ERR.EUNKNOWN
            return SmpError(rc, f"storage error: {e.strerror or e}")
        return SmpError(MGMT_ERR.EUNKNOWN, f"internal error ({type(e).__name__}); see the log")

    # ---- OS group -----------------------------------------------------------------

    def _echo(self, req: Request) -> dict[str, Any]:
        return {"r": field(req.body, "d", str)}

    def _reset(self, req: Request) -> dict[str, Any]:
        self.after_reply = self.on_reset
        log.info("reset requested")
        return {}

    def _params(self, req: Request) -> dict[str, Any]:
        return {"buf_size": self.buf_size, "buf_count": 1}

    # ---- file-system group ------------------------------------------------------

    def _upload(self, req: Request) -> dict[str, Any]:
        name = field(req.body, "name", str)
        off = field(req.body, "off", int)
        data = field(req.body, "data", bytes)
        if off == 0:
            total = optional(req.body, "len", int)
            if total is None:
                raise SmpError(MGMT_ERR.EINVAL, "field 'len' is required when 'off' is 0")
            received = self.store.begin(name, total, data)
        else:
            received = self.store.append(name, off, data)
        pending = self.store.pending_for(name)
        active = self.store.active()
        if pending is None and active is not None and check_name(name) in active.items():
            self.restore_active()  # a new version of what is shown: show it
        return {"off": received}

    def _download(self, req: Request) -> dict[str, Any]:
        off = field(req.body, "off", int)
        data, total = self.store.read(field(req.body, "name", str), off, self._chunk())
        return _chunk_reply(off, data, total)

    def _chunk(self) -> int:
        return self.max_message - REPLY_MARGIN

    def _file_status(self, req: Request) -> dict[str, Any]:
        return {"len": self.store.path(field(req.body, "name", str)).stat().st_size}

    def _file_hash(self, req: Request) -> dict[str, Any]:
        name = field(req.body, "name", str)
        kind = optional(req.body, "type", str) or "sha256"
        off = optional(req.body, "off", int) or 0
        size = optional(req.body, "len", int)
        if kind not in HASH_TYPES:
            raise SmpError(
                FS_MGMT_ERR.CHECKSUM_HASH_NOT_FOUND,
                f"no hash {kind!r}; use sha256 or crc32",
                group=FS,
                legacy=MGMT_ERR.EINVAL,
            )
        total = self.store.path(name).stat().st_size
        if total == 0:
            raise SmpError(FS_MGMT_ERR.FILE_EMPTY, f"{name} is empty", group=FS)
        if off >= total:
            raise SmpError(
                FS_MGMT_ERR.FILE_OFFSET_LARGER_THAN_FILE, f"offset {off} >= {total}", group=FS
            )
        output, n = self.store.digest(name, kind, off, size)
        reply: dict[str, Any] = {"type": kind, "len": n, "output": output}
        if off:
            reply["off"] = off
        return reply

    # ---- adaproj group ------------------------------------------------------------

    def _list(self, req: Request) -> dict[str, Any]:
        active = self.store.active()
        return {
            "items": [
                {
                    "name": i.name,
                    "len": i.size,
                    "w": i.width,
                    "h": i.height,
                    "kind": i.kind,
                    "dur": i.duration,
                }
                for i in self.store.items()
            ],
            "pending": [
                {"name": p.name, "off": p.received, "len": p.total} for p in self.store.pending()
            ],
            "active": active.to_json() if active else None,
            "used": self.store.used(),
            "quota": self.store.limits.quota,
        }

    def _activate(self, req: Request) -> dict[str, Any]:
        image = self.store.path(field(req.body, "image", str)).name
        mask_name = optional(req.body, "mask", str)
        mask = self.store.path(mask_name).name if mask_name is not None else None
        settings = Settings.parse(optional(req.body, "settings", dict) or {})
        record = ActiveRecord(image, mask, settings.to_dict())
        self.device.activate(self._content(record))
        self.store.set_active(record)
        return {"active": record.to_json()}

    def _content(self, record: ActiveRecord) -> Content:
        root = self.store.root
        return Content(
            root / record.image,
            root / record.mask if record.mask else None,
            Settings.parse(record.settings),
        )

    def restore_active(self) -> None:
        """Show what was active before the last shutdown (or crash), if it still loads."""
        record = self.store.active()
        if record is None:
            return
        try:
            self.device.activate(self._content(record))
        except AdaprojError as e:
            log.error("cannot show the previously active %s: %s", record.image, e)

    def _delete(self, req: Request) -> dict[str, Any]:
        self.store.delete(field(req.body, "name", str))
        return {}

    def _status(self, req: Request) -> dict[str, Any]:
        return {
            "device": self.device.status(),
            "store": {
                "items": len(self.store.sizes()),
                "used": self.store.used(),
                "quota": self.store.limits.quota,
            },
            "link": {**self.counters, "frames_dropped": dict(self.decoder.stats.dropped)},
        }

    def _screenshot_chunk(self, req: Request) -> dict[str, Any]:
        off = field(req.body, "off", int)
        if off == 0:
            self._screenshot = self.device.frame_png()
        elif off > len(self._screenshot):
            raise SmpError(MGMT_ERR.EINVAL, f"offset {off} is past the screenshot's end")
        data = self._screenshot[off : off + self._chunk()]
        return _chunk_reply(off, data, len(self._screenshot))

    def _upload_state(self, req: Request) -> dict[str, Any]:
        name = field(req.body, "name", str)
        p = self.store.pending_for(name)
        if p is None:
            return {"name": name, "off": 0, "len": 0, "sha": hashlib.sha256().digest()}
        part = self.store.incoming / f"{p.total}.{p.name}"
        with part.open("rb") as f:
            sha = hashlib.file_digest(f, "sha256").digest()
        return {"name": p.name, "off": p.received, "len": p.total, "sha": sha}


def _chunk_reply(off: int, data: bytes, total: int) -> dict[str, Any]:
    reply: dict[str, Any] = {"off": off, "data": data}
    if off == 0:
        reply["len"] = total
    return reply


def serve(
    port: SerialPort,
    server: Server,
    stop: threading.Event | None = None,
    *,
    poll: float = 0.1,
) -> None:
    """Answer requests on ``port`` until ``stop`` is set (or forever).

    Nothing the host does ends the loop: a reply the host does not take (it hung up,
    or stopped reading) is dropped with a log line, and the next request is served.

    Parameters
    ----------
    port : SerialPort
        The link to the host.
    server : Server
        What answers.
    stop : threading.Event, optional
        Set it to make the loop return within ``poll`` seconds.
    poll : float
        Longest wait for input before checking ``stop``.
    """
    log.info("SMP server up (buffer %d bytes)", server.buf_size)
    lost = BurstLog(log, "replies the host did not take", first=1)
    failed = BurstLog(log, "reads of the serial port failed", first=1)
    while stop is None or not stop.is_set():
        try:
            data = port.read(65536, poll)
            failed.ok()
        except DeviceError as e:  # the port's own trouble: wait, then try again
            failed.bad("read failed", "reading the serial port failed: %s", e)
            time.sleep(poll)
            continue
        for message in server.decoder.feed(data):
            reply = server.handle(message)
            if reply is not None:
                try:
                    port.write(encode_frame(reply))
                    lost.ok()
                except DeviceError as e:  # a host that hung up or stopped reading
                    lost.bad("not taken", "reply dropped: %s", e)
            if server.after_reply is not None:
                server.after_reply()
