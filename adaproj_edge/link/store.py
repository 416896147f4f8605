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
import shutil
import stat
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from adaproj_edge.content.intake import read_content
from adaproj_edge.content.video import VIDEO_EXTENSIONS, is_video_name, probe
from adaproj_edge.errors import (
    AdaprojError,
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
        """The record as a JSON-ready map (``image``, ``mask``, ``settings``)."""
        return {"image": self.image, "mask": self.mask, "settings": self.settings}

    def items(self) -> tuple[str, ...]:
        """The store items it uses."""
        return (self.image,) if self.mask is None else (self.image, self.mask)

    @classmethod
    def from_json(cls, raw: Any) -> ActiveRecord:
        """The record in a JSON value read back from storage, checked as strictly as a
        host's request: :class:`ContentError` says what is wrong."""
        if not isinstance(raw, dict):
            raise ContentError(f"the record must be a JSON object, not {type(raw).__name__}")
        unknown = set(raw) - {"image", "mask", "settings"}
        if unknown:
            raise ContentError(f"unknown keys {sorted(map(str, unknown))}")
        image, mask, settings = raw.get("image"), raw.get("mask"), raw.get("settings")
        if not isinstance(image, str):
            raise ContentError(f"image must be an item's name, not {image!r:.40}")
        if mask is not None and not isinstance(mask, str):
            raise ContentError(f"mask must be an item's name or null, not {mask!r:.40}")
        if settings is None:
            settings = {}
        if not isinstance(settings, dict) or not all(isinstance(k, str) for k in settings):
            raise ContentError(f"settings must be a JSON object, not {settings!r:.40}")
        return cls(check_name(image), None if mask is None else check_name(mask), settings)


def _parse_partial(file_name: str) -> tuple[int, str] | None:
    """(declared size, item name) of an upload's file in ``.incoming``, or None."""
    total, _, name = file_name.partition(".")
    if not (total.isdigit() and total.isascii() and len(total) <= 20):
        return None
    try:
        return int(total), check_name(name)
    except ContentError:
        return None


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
        self._ignored_active: bytes | None = None
        self.incoming.mkdir(parents=True, exist_ok=True)
        for stale in self.root.glob(".*.tmp"):  # an atomic write cut short by a crash
            stale.unlink(missing_ok=True)
        self._recover()

    def _recover(self) -> None:
        """Finish what a crash interrupted: commit whole uploads, drop impossible ones
        (and files in ``.incoming`` that are not an upload's)."""
        for f in self._incoming_files():
            parsed = _parse_partial(f.name)
            if (
                parsed is None
                or f.is_symlink()
                or not f.is_file()
                or parsed[0] > self.limits.max_file
            ):
                log.warning("removing %s from the uploads in progress: not an upload", f.name)
                if f.is_dir() and not f.is_symlink():
                    shutil.rmtree(f, ignore_errors=True)
                else:
                    f.unlink(missing_ok=True)
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
        """Uploads in progress, oldest first (files in ``.incoming`` that are not an
        upload's, by their name, are left out)."""
        out = []
        for p in self._incoming_files():
            parsed = _parse_partial(p.name)
            if parsed is not None:
                out.append(Pending(parsed[1], p.stat().st_size, parsed[0]))
        return out

    def _incoming_files(self) -> list[Path]:
        files = []
        for p in self.incoming.iterdir():
            try:
                files.append((p.stat().st_mtime_ns, p))
            except OSError:
                continue
        return [p for _, p in sorted(files)]

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
        for a PNG the pixel count in its header; a clip's container). Pending uploads
        never keep a new one out: the oldest are dropped until it fits beside the
        committed items and at most :data:`MAX_PENDING` uploads are kept. A first chunk
        that is refused leaves nothing behind.
        """
        name = check_name(raw)
        lim = self.limits
        if total <= 0:
            kind = "a video" if is_video_name(name) else "an image"
            raise ImageError(f"{name}: an empty file is not {kind}")
        if total > lim.max_file:
            raise QuotaError(f"{name} is {total} bytes; one item may be at most {lim.max_file}")
        if len(data) > total:
            raise ContentError(f"{name}: {len(data)} bytes is more than the {total} declared")
        if len(data) >= min(HEAD, total):
            check_content_head(data[:HEAD], name, lim)
        items = self.sizes()
        if name not in items and len(items) >= lim.max_items:
            raise QuotaError(f"the device holds {len(items)} items, the most it keeps")
        committed = sum(items.values()) - items.get(name, 0)
        if committed + total > lim.quota:
            raise QuotaError(
                f"{name} ({total} bytes) does not fit: {committed} of {lim.quota} bytes are "
                "in use by items"
            )
        others = [p for p in self.pending() if p.name != name]
        old = self.pending_for(name)
        if old is not None:
            self._partial(old).unlink(missing_ok=True)
        while others and (
            len(others) >= MAX_PENDING
            or committed + sum(p.total for p in others) + total > lim.quota
        ):
            stale = others.pop(0)
            log.info("dropping the oldest pending upload %s to make room", stale.name)
            self._partial(stale).unlink(missing_ok=True)
        part = self._partial(Pending(name, 0, total))
        with part.open("wb") as f:
            os.fsync(f.fileno())
        fsync_dir(self.incoming)
        try:
            return self.append(name, 0, data)
        except BaseException:
            part.unlink(missing_ok=True)  # not acknowledged: no trace of it
            fsync_dir(self.incoming)
            raise

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
        self._refuse_on(lambda: self._check_shown(name, part), part)
        size = part.stat().st_size
        os.replace(part, self.root / name)
        fsync_dir(self.root)
        fsync_dir(self.incoming)
        log.info("committed %s (%d bytes)", name, size)

    def _check_shown(self, name: str, part: Path) -> None:
        """Refuse a new version of a shown item that could not be shown in its place:
        the pair (image or clip, mask) is read as the device reads it, with ``part``
        standing for ``name``, so what is shown is never replaced by something that
        is not. A pair whose other item is missing is not checked (nothing to keep)."""
        active = self.active()
        if active is None or name not in active.items():
            return
        image, mask = (
            None if n is None else part if n == name else self.root / n
            for n in (active.image, active.mask)
        )
        assert image is not None
        if not all(p.is_file() for p in (image, mask) if p is not None):
            return
        try:
            read_content(image, mask)
        except AdaprojError as e:
            pair = (
                f"with the mask {active.mask}"
                if name == active.image
                else (f"as the mask of {active.image}")
            )
            raise ContentError(
                f"{name} is being shown {pair}, and this version cannot be ({e}); the "
                "shown one is kept: activate something else first"
            ) from None

    # ---- what is shown ----------------------------------------------------------

    def active(self) -> ActiveRecord | None:
        """The active record, or ``None`` if nothing was ever activated or the record
        cannot be used (unreadable, or not a record: logged once, ignored)."""
        path = self.root / ".active.json"
        try:
            text = path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as e:
            self._ignore_active(b"", f"cannot read it: {e.strerror or e}")
            return None
        try:
            return ActiveRecord.from_json(json.loads(text))
        except (ValueError, RecursionError) as e:  # not JSON (UnicodeDecodeError too)
            self._ignore_active(text, f"not JSON ({type(e).__name__})")
        except ContentError as e:
            self._ignore_active(text, str(e))
        return None

    def _ignore_active(self, text: bytes, reason: str) -> None:
        if text != self._ignored_active:
            self._ignored_active = text
            log.warning("ignoring %s: %s", self.root / ".active.json", reason)

    def set_active(self, record: ActiveRecord) -> None:
        """Record what is shown (atomically; the items must exist)."""
        self.path(record.image)
        if record.mask is not None:
            self.path(record.mask)
        atomic_write_bytes(self.root / ".active.json", json.dumps(record.to_json()).encode())
