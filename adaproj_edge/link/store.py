"""The content store: images, video clips and masks people upload, kept safe across
power loss.

Layout of the store directory::

    photo.png, clip.mp4        committed items (PNG or JPEG; MP4, AVI or MKV), flat,
                               validated names
    .incoming/<len>.<name>     an upload in progress; <len> is its declared size
    .active.json               what the projector shows (see :class:`ActiveRecord`)

An upload appends to its file in ``.incoming`` and fsyncs it before the chunk is
acknowledged, so whatever was acknowledged survives a crash and the upload resumes at
the file's size. When the last byte is there, the whole file is checked as content (an
image: decoded whole; a clip: :func:`~adaproj_edge.content.video.check_video`) and only
then renamed over the committed name, and both directories are fsynced.
A failed, refused or interrupted upload never touches committed items or the active
record.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import stat
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from adaproj_edge.content.video import VIDEO_EXTENSIONS, is_video_name, probe
from adaproj_edge.errors import (
    ContentError,
    ContentNotFoundError,
    ImageError,
    InputError,
    QuotaError,
    UploadOffsetError,
    VideoError,
)
from adaproj_edge.fileio import atomic_write_bytes, fsync_dir
from adaproj_edge.fileio import image_size as header_size
from adaproj_edge.link.contentcheck import HEAD, check_content, check_content_head
from adaproj_edge.link.contentcheck import Limits as Limits  # re-exported: the store's limits

log = logging.getLogger(__name__)

NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
EXTENSIONS = IMAGE_EXTENSIONS + VIDEO_EXTENSIONS
MAX_PENDING = 4
"""Uploads kept for resuming at once; a fifth drops the oldest."""


@dataclass(frozen=True)
class ItemInfo:
    """A committed item: name, size in bytes, its pixel size (from the header or the
    clip's probe) and, for a clip, its length in seconds (None for an image)."""

    name: str
    size: int
    width: int
    height: int
    duration: float | None = None

    @property
    def kind(self) -> str:
        """``"video"`` or ``"image"``."""
        return "video" if is_video_name(self.name) else "image"


@dataclass(frozen=True)
class Pending:
    """An upload in progress: bytes received so far of the declared ``total``."""

    name: str
    received: int
    total: int


@dataclass(frozen=True)
class ActiveRecord:
    """What the projector shows: an item (``image``: a picture or a clip), an optional
    mask, and the settings."""

    image: str
    mask: str | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"image": self.image, "mask": self.mask, "settings": self.settings}

    def items(self) -> tuple[str, ...]:
        """The store items it uses."""
        return (self.image,) if self.mask is None else (self.image, self.mask)


def check_name(raw: str) -> str:
    """The store name for a client's ``raw`` name, or :class:`ContentError`.

    One leading ``/`` is allowed (MCUmgr clients send absolute paths); what remains
    must be a plain file name of letters, digits, ``._-`` (not starting with a dot)
    ending in ``.png``, ``.jpg``, ``.jpeg`` (images) or ``.mp4``, ``.avi``, ``.mkv``
    (clips). Anything else, ``..`` and ``/`` in particular, is refused.
    """
    name = raw[1:] if raw.startswith("/") else raw
    if not NAME_RE.fullmatch(name) or ".." in name:
        shown = raw if len(raw) <= 80 else raw[:77] + "..."
        raise ContentError(
            f"name {shown!r} is not allowed: use a plain file name (letters, digits, '._-', "
            "at most 64 characters, no directories)"
        )
    if not name.lower().endswith(EXTENSIONS):
        raise ContentError(f"name {name!r} is not allowed: only {', '.join(EXTENSIONS)} files")
    return name


class ContentStore:
    """The store directory; see the module docstring for the layout and guarantees.

    Parameters
    ----------
    root : Path
        The store directory (created if missing).
    limits : Limits
        What is accepted.
    """

    def __init__(self, root: str | os.PathLike[str], limits: Limits | None = None) -> None:
        self.root = Path(root)
        self.limits = limits or Limits()
        self.incoming = self.root / ".incoming"
        self.incoming.mkdir(parents=True, exist_ok=True)
        for stale in self.root.glob(".*.tmp"):  # an atomic write cut short by a crash
            stale.unlink(missing_ok=True)
        self._recover()

    def _recover(self) -> None:
        """Finish what a crash interrupted: commit whole uploads, drop impossible ones."""
        for p in self.pending():
            if p.received > p.total:
                self._partial(p).unlink(missing_ok=True)
            elif p.received == p.total:
                try:
                    self._commit(p.name, self._partial(p))
                except InputError as e:
                    log.warning("dropped the finished upload of %s: %s", p.name, e)

    # ---- committed items ------------------------------------------------------

    def path(self, raw: str) -> Path:
        """The committed file for ``raw``; :class:`ContentNotFoundError` if none."""
        name = check_name(raw)
        p = self.root / name
        if not p.is_file():
            raise ContentNotFoundError(f"no item {name!r} on the device")
        return p

    def sizes(self) -> dict[str, int]:
        """Name and size of every committed item (from ``stat`` alone)."""
        out = {}
        for p in sorted(self.root.iterdir()):
            try:
                check_name(p.name)
                st = p.stat()
            except (ContentError, OSError):
                continue
            if stat.S_ISREG(st.st_mode):
                out[p.name] = st.st_size
        return out

    def items(self) -> list[ItemInfo]:
        """Every committed item, by name, with its pixel size (an image's header, a
        clip's probe) and a clip's duration."""
        out = []
        for name, size in self.sizes().items():
            if is_video_name(name):
                try:
                    info = probe(self.root / name, name)
                except VideoError:
                    out.append(ItemInfo(name, size, 0, 0, 0.0))
                    continue
                out.append(ItemInfo(name, size, info.width, info.height, info.duration))
                continue
            try:
                with (self.root / name).open("rb") as f:
                    head = f.read(65536)
            except OSError:
                continue
            w, h = header_size(head) or (0, 0)
            out.append(ItemInfo(name, size, w, h))
        return out

    def used(self) -> int:
        """Bytes counted against the quota: items plus declared pending sizes."""
        return sum(self.sizes().values()) + sum(p.total for p in self.pending())

    def read(self, raw: str, off: int, size: int) -> tuple[bytes, int]:
        """Up to ``size`` bytes of an item from ``off``, and the item's length."""
        p = self.path(raw)
        with p.open("rb") as f:
            total = os.fstat(f.fileno()).st_size
            if off > total:
                raise UploadOffsetError(f"offset {off} is past the end ({total} bytes)", total)
            f.seek(off)
            return f.read(size), total

    def digest(self, raw: str, kind: str, off: int = 0, size: int | None = None) -> tuple[Any, int]:
        """(``sha256`` bytes or ``crc32`` int, bytes hashed) of part of an item."""
        p = self.path(raw)
        h = hashlib.sha256()
        crc = 0
        n = 0
        with p.open("rb") as f:
            f.seek(off)
            left = size if size is not None else -1
            while left != 0:
                block = f.read(65536 if left < 0 else min(left, 65536))
                if not block:
                    break
                n += len(block)
                left = left - len(block) if left > 0 else left
                if kind == "sha256":
                    h.update(block)
                else:
                    crc = zlib.crc32(block, crc)
        return (h.digest() if kind == "sha256" else crc), n

    def delete(self, raw: str) -> None:
        """Remove a committed item (refused while it is active)."""
        p = self.path(raw)
        active = self.active()
        if active is not None and p.name in active.items():
            raise ContentError(f"{p.name!r} is being shown; activate something else first")
        p.unlink()
        fsync_dir(self.root)

    # ---- uploads --------------------------------------------------------------

    def pending(self) -> list[Pending]:
        """Uploads in progress, oldest first."""
        out = []
        paths = sorted(self.incoming.iterdir(), key=lambda q: q.stat().st_mtime_ns)
        for p in paths:
            total, _, name = p.name.partition(".")
            if total.isdigit() and NAME_RE.fullmatch(name):
                out.append(Pending(name, p.stat().st_size, int(total)))
        return out

    def pending_for(self, raw: str) -> Pending | None:
        """The upload in progress for ``raw``, if there is one."""
        name = check_name(raw)
        return next((p for p in self.pending() if p.name == name), None)

    def _partial(self, p: Pending) -> Path:
        return self.incoming / f"{p.total}.{p.name}"

    def begin(self, raw: str, total: int, data: bytes) -> int:
        """Start (or restart) an upload of ``total`` bytes with its first chunk.

        Everything that can be refused up front is refused before a byte is written:
        the name, the size, the quota, and the start of the data (PNG/JPEG magic, and
        for a PNG the pixel count in its header; a clip's container).
        """
        name = check_name(raw)
        lim = self.limits
        if total <= 0:
            kind = "a video" if is_video_name(name) else "an image"
            raise ImageError(f"{name}: an empty file is not {kind}")
        if total > lim.max_file:
            raise QuotaError(f"{name} is {total} bytes; one item may be at most {lim.max_file}")
        if len(data) >= min(HEAD, total):
            check_content_head(data[:HEAD], name, lim)
        old = self.pending_for(name)
        if old is not None:
            self._partial(old).unlink(missing_ok=True)
        items = self.sizes()
        if name not in items and len(items) >= lim.max_items:
            raise QuotaError(f"the device holds {len(items)} items, the most it keeps")
        used = sum(items.values()) - items.get(name, 0) + sum(p.total for p in self.pending())
        if used + total > lim.quota:
            raise QuotaError(
                f"{name} ({total} bytes) does not fit: {used} of {lim.quota} bytes are in use"
            )
        for stale in self.pending()[: max(0, len(self.pending()) - MAX_PENDING + 1)]:
            log.info("dropping the oldest pending upload %s", stale.name)
            self._partial(stale).unlink(missing_ok=True)
        part = Pending(name, 0, total)
        with self._partial(part).open("wb") as f:
            os.fsync(f.fileno())
        fsync_dir(self.incoming)
        return self.append(name, 0, data)

    def append(self, raw: str, off: int, data: bytes) -> int:
        """Add a chunk at ``off``; returns the bytes received. Commits at the end.

        The chunk is on disk (fsynced) when this returns. ``off`` must be the number
        of bytes received so far, else :class:`UploadOffsetError` says where to go on.
        """
        name = check_name(raw)
        p = self.pending_for(name)
        if p is None:
            raise UploadOffsetError(f"no upload of {name!r} in progress; start at offset 0", 0)
        if off != p.received:
            raise UploadOffsetError(
                f"{name}: offset {off} does not continue the {p.received} bytes received",
                p.received,
            )
        end = off + len(data)
        if end > p.total:
            raise ContentError(f"{name}: {end} bytes is more than the {p.total} declared")
        part = self._partial(p)
        if off < HEAD and data:
            head = (part.read_bytes() + data)[:HEAD]
            if len(head) >= min(HEAD, p.total):
                self._refuse_on(lambda: check_content_head(head, name, self.limits), part)
        with part.open("ab") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        received = off + len(data)
        if received == p.total:
            self._commit(name, part)
        return received

    def _refuse_on(self, check: Callable[[], None], part: Path) -> None:
        try:
            check()
        except InputError:
            part.unlink(missing_ok=True)
            fsync_dir(self.incoming)
            raise

    def _commit(self, name: str, part: Path) -> None:
        self._refuse_on(lambda: check_content(part, name, self.limits), part)
        size = part.stat().st_size
        os.replace(part, self.root / name)
        fsync_dir(self.root)
        fsync_dir(self.incoming)
        log.info("committed %s (%d bytes)", name, size)

    # ---- what is shown ----------------------------------------------------------

    def active(self) -> ActiveRecord | None:
        """The active record, or ``None`` if nothing was ever activated."""
        try:
            raw = json.loads((self.root / ".active.json").read_text())
            return ActiveRecord(raw["image"], raw.get("mask"), dict(raw.get("settings") or {}))
        except (OSError, ValueError, KeyError, TypeError):
            return None

    def set_active(self, record: ActiveRecord) -> None:
        """Record what is shown (atomically; the items must exist)."""
        self.path(record.image)
        if record.mask is not None:
            self.path(record.mask)
        atomic_write_bytes(self.root / ".active.json", json.dumps(record.to_json()).encode())
