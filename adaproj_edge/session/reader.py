"""Reading a session, including one cut short by a power loss or damaged on its card.

The reader streams the file from the start (it never needs the summary at the end)
through :func:`~adaproj_edge.session.mcapscan.scan_records`, which checks every
declared size against the file and every chunk against its CRC: a file that stops
mid-way yields every message of its complete chunks and then reports ``truncated``; a
damaged chunk (a flipped bit, a size that lies) is skipped and reading goes on with
the next good one, and the scan says so (:attr:`Scan.damaged`); the channels a damaged
chunk declared are then taken from the file's summary. A message that does
not decode is skipped the same way. Bytes after the file's end (garbage appended) are
counted, not read (:attr:`Scan.trailing_bytes`); :meth:`Scan.damage` says what is
wrong in words.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas as s
from adaproj_edge.session.codec import Record, decode
from adaproj_edge.session.mcapscan import Cut, Damage, scan_records, summary_channels
from adaproj_edge.session.records import SerialTraffic, TruthPose

KEEP_DAMAGE = 8
"""Damaged parts described one by one in :attr:`Scan.damaged` (all are counted)."""


@dataclass
class Scan:
    """What a pass over the file saw besides messages."""

    attachments: dict[str, bytes] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    truncated: bool = False
    complete: bool = False
    trailing_bytes: int = 0
    size: int = 0
    read_bytes: int = 0
    damaged: list[str] = field(default_factory=list)
    damaged_count: int = 0
    skipped_bytes: int = 0
    cut: str = ""

    def note_damage(self, what: str, skipped: int = 0) -> None:
        """Count one damaged part (``skipped`` bytes of the file passed over)."""
        self.damaged_count += 1
        self.skipped_bytes += skipped
        if len(self.damaged) < KEEP_DAMAGE:
            self.damaged.append(what)

    def damage(self) -> str | None:
        """What is wrong with the file, in words (None: a whole, clean file)."""
        parts = []
        if self.damaged_count:
            more = self.damaged_count - len(self.damaged)
            parts.append(
                f"{self.damaged_count} damaged part(s) skipped ({self.skipped_bytes} of "
                f"{self.size} bytes): "
                + "; ".join(self.damaged)
                + (f"; and {more} more" if more > 0 else "")
            )
        if self.truncated or not self.complete:
            cut = f" ({self.cut})" if self.cut else ""
            parts.append(
                f"the file is cut short: it ends after {self.size} bytes without its closing "
                f"records{cut} (power loss or an interrupted copy?); read up to the cut"
            )
        elif self.trailing_bytes:
            parts.append(
                f"{self.trailing_bytes} unexpected bytes after the end of the file, ignored"
            )
        return "; ".join(parts) or None

    def report(self) -> dict[str, Any]:
        """The file's state, for summaries: size, complete, truncated, damaged parts,
        trailing bytes."""
        return {
            "bytes": self.size,
            "complete": self.complete and not self.truncated,
            "truncated": self.truncated or not self.complete,
            "damaged_parts": self.damaged_count,
            "trailing_bytes": self.trailing_bytes,
            "damage": self.damage(),
        }


def _open(path: Path) -> IO[bytes]:
    try:
        return open(path, "rb")
    except FileNotFoundError:
        raise InputError(f"session file not found: {path}") from None
    except OSError as e:
        raise InputError(f"cannot read session file {path}: {e.strerror}") from None


def iter_records(
    path: str | os.PathLike[str], topics: set[str] | None = None, scan: Scan | None = None
) -> Iterator[Record]:
    """Records of ``topics`` (all when None) in file order, which is receive order.

    Stops quietly where the file is cut (``scan.truncated`` then says so) and skips
    what is damaged (``scan.damaged``).
    """
    path = Path(path)
    scan = scan if scan is not None else Scan()
    channels: dict[int, str] = {}
    summary: dict[int, str] | None = None  # the summary's channels, read when needed
    with _open(path) as f:
        scan.size = os.fstat(f.fileno()).st_size
        try:
            records = scan_records(f, scan.size)
            first = next(records, None)
        except InputError as e:
            why = f" ({e})" if str(e) else ""
            raise InputError(f"{path} is not an MCAP session file{why}") from None
        if not isinstance(first, Header):
            raise InputError(f"{path} is not an MCAP session file (no header record)")
        for r in itertools.chain([first], records):
            if isinstance(r, Damage):
                scan.note_damage(str(r), r.end - r.start)
            elif isinstance(r, Cut):
                scan.truncated = True
                scan.cut = r.reason
                scan.read_bytes = r.at
            elif isinstance(r, Channel):
                channels[r.id] = r.topic
            elif isinstance(r, Message):
                if r.channel_id not in channels and summary is None:
                    summary = {k: c.topic for k, c in summary_channels(f, scan.size).items()}
                    channels = summary | channels
                topic = channels.get(r.channel_id)
                if topic is not None and (topics is None or topic in topics):
                    try:
                        rec = decode(topic, r.data, r.log_time, r.sequence)
                    except InputError as e:
                        scan.note_damage(str(e))
                        continue
                    if rec is not None:
                        yield rec
            elif isinstance(r, Attachment):
                scan.attachments[r.name] = bytes(r.data)
            elif isinstance(r, Metadata):
                scan.metadata[r.name] = dict(r.metadata)
            elif isinstance(r, Footer):
                scan.complete = True
        if scan.complete:
            scan.read_bytes = f.tell()
            scan.trailing_bytes = scan.size - scan.read_bytes


def read_calibration(path: str | os.PathLike[str]) -> Calibration:
    """The calibration attachment, read from the head of the file."""
    scan = Scan()
    for _ in iter_records(path, topics=set(), scan=scan):
        pass
    return _calibration(scan, Path(path))


def _calibration(scan: Scan, path: Path) -> Calibration:
    raw = scan.attachments.get(s.CALIBRATION_ATTACHMENT)
    if raw is None:
        why = scan.damage() or "the file holds none"
        raise InputError(f"session {path} has no {s.CALIBRATION_ATTACHMENT}: {why}")
    return Calibration.from_json(raw, f"{path}:{s.CALIBRATION_ATTACHMENT}")


@dataclass
class Session:
    """A whole session in memory (for tests, tools and short recordings)."""

    calibration: Calibration
    depth: list[DepthFrame]
    imu: list[ImuSample]
    button: list[ButtonEvent]
    serial: list[SerialTraffic]
    truth_poses: list[TruthPose]
    attachments: dict[str, bytes]
    metadata: dict[str, dict[str, str]]
    truncated: bool
    records: list[Record]

    def truth_surface_spec(self) -> dict[str, Any] | None:
        """The truth surface attachment (simulated sessions), or None."""
        raw = self.attachments.get(s.TRUTH_SURFACE_ATTACHMENT)
        return None if raw is None else dict(json.loads(raw))


def read_session(path: str | os.PathLike[str]) -> Session:
    """Read every record of a session; a cut file gives what it holds."""
    scan = Scan()
    recs = list(iter_records(path, scan=scan))
    return Session(
        calibration=_calibration(scan, Path(path)),
        depth=[r for r in recs if isinstance(r, DepthFrame)],
        imu=[r for r in recs if isinstance(r, ImuSample)],
        button=[r for r in recs if isinstance(r, ButtonEvent)],
        serial=[r for r in recs if isinstance(r, SerialTraffic)],
        truth_poses=[r for r in recs if isinstance(r, TruthPose)],
        attachments=scan.attachments,
        metadata=scan.metadata,
        truncated=scan.truncated or not scan.complete,
        records=recs,
    )
