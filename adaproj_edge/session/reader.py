"""Reading a session, including one cut short by a power loss.

The reader streams the file from the start (it never needs the summary at the end):
a file that stops mid-way yields every message of its complete chunks and then
reports ``truncated``; chunk CRCs are checked, so a torn chunk is dropped, never
misread. Bytes after the file's end (garbage appended) are counted, not read
(:attr:`Scan.trailing_bytes`); :meth:`Scan.damage` says what is wrong in words.
"""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import zstandard
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Message, Metadata
from mcap.stream_reader import StreamReader

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas as s
from adaproj_edge.session.codec import Record, decode
from adaproj_edge.session.records import SerialTraffic, TruthPose

# What a torn file can raise from inside the mcap reader.
_TORN = (McapError, struct.error, ValueError, EOFError, zstandard.ZstdError, UnicodeDecodeError)


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

    def damage(self) -> str | None:
        """What is wrong with the file, in words (None: a whole, clean file)."""
        if self.truncated or not self.complete:
            return (
                f"the file is cut short: it ends after {self.size} bytes without its closing "
                "records (power loss or an interrupted copy?); read up to the cut"
            )
        if self.trailing_bytes:
            return f"{self.trailing_bytes} unexpected bytes after the end of the file, ignored"
        return None

    def report(self) -> dict[str, Any]:
        """The file's state, for summaries: size, complete, truncated, trailing bytes."""
        return {
            "bytes": self.size,
            "complete": self.complete and not self.truncated,
            "truncated": self.truncated or not self.complete,
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

    Stops quietly where the file is cut; ``scan.truncated`` then says so.
    """
    path = Path(path)
    scan = scan if scan is not None else Scan()
    channels: dict[int, str] = {}
    seen_header = False
    with _open(path) as f:
        scan.size = os.fstat(f.fileno()).st_size
        records = StreamReader(f, validate_crcs=True).records
        while True:
            try:
                r: Any = next(records)
            except StopIteration:
                scan.read_bytes = f.tell()
                if scan.complete:
                    scan.trailing_bytes = scan.size - scan.read_bytes
                break
            except _TORN as e:
                if not seen_header:
                    why = f" ({e})" if str(e) else ""
                    raise InputError(f"{path} is not an MCAP session file{why}") from None
                scan.truncated = True
                scan.read_bytes = f.tell()
                break
            seen_header = True
            if isinstance(r, Channel):
                channels[r.id] = r.topic
            elif isinstance(r, Message):
                topic = channels.get(r.channel_id)
                if topic is not None and (topics is None or topic in topics):
                    rec = decode(topic, r.data, r.log_time, r.sequence)
                    if rec is not None:
                        yield rec
            elif isinstance(r, Attachment):
                scan.attachments[r.name] = bytes(r.data)
            elif isinstance(r, Metadata):
                scan.metadata[r.name] = dict(r.metadata)
            elif isinstance(r, Footer):
                scan.complete = True


def read_calibration(path: str | os.PathLike[str]) -> Calibration:
    """The calibration attachment, read from the head of the file."""
    scan = Scan()
    for _ in iter_records(path, topics=set(), scan=scan):
        pass
    return _calibration(scan, Path(path))


def _calibration(scan: Scan, path: Path) -> Calibration:
    raw = scan.attachments.get(s.CALIBRATION_ATTACHMENT)
    if raw is None:
        raise InputError(f"session {path} has no {s.CALIBRATION_ATTACHMENT} (cut before it?)")
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
