"""Writing a session: one MCAP file, written as it is recorded.

The file is written in place (not atomically): if the power goes while recording,
everything up to the last complete chunk is on storage and replays. Call
:meth:`SessionWriter.flush` for a durability point (closes the chunk and fsyncs).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import TracebackType
from typing import IO

from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.writer import CompressionType, Writer

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.camera import CameraFrame
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.session import schemas as s
from adaproj_edge.session.codec import Record, encode, sensor_time, topic_of

CHUNK_SIZE = 256 * 1024


class SessionWriter:
    """Records in receive order; the calibration goes in first, as an attachment.

    Parameters
    ----------
    path : path of the ``.mcap`` file to create
    calibration : the device calibration at recording time
    metadata : free-form strings stored in the ``session`` metadata record
    start_ns : time stamp of the attachments (the recording's start)
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        calibration: Calibration,
        metadata: dict[str, str] | None = None,
        start_ns: int = 0,
    ) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: IO[bytes] = open(self.path, "wb")
        except OSError as e:
            raise InputError(f"cannot create session file {self.path}: {e.strerror}") from None
        self._mcap = Writer(self._file, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        self._mcap.start(profile=s.PROFILE, library="adaproj-edge")
        self._channels: dict[str, int] = {}
        self._sequence: dict[str, int] = {}
        self.count = 0
        self.attach(
            s.CALIBRATION_ATTACHMENT, "application/json", calibration.to_json().encode(), start_ns
        )
        self._mcap.add_metadata("session", dict(metadata or {}))
        self.flush()

    def _channel(self, topic: str) -> int:
        if topic not in self._channels:
            if topic in s.PROTOBUF_TOPICS:
                sid = self._mcap.register_schema(
                    "foxglove.RawImage", "protobuf", s.file_descriptor_set(RawImage.DESCRIPTOR.file)
                )
                enc = "protobuf"
            else:
                name, data = s.JSON_SCHEMAS[topic]
                sid = self._mcap.register_schema(name, "jsonschema", data)
                enc = "json"
            self._channels[topic] = self._mcap.register_channel(topic, enc, sid)
            self._sequence[topic] = 0
        return self._channels[topic]

    def write(self, rec: Record) -> None:
        """Append one record (depth frame, IMU sample, button event, serial bytes, pose)."""
        topic = topic_of(rec)
        cid = self._channel(topic)
        seq = rec.sequence if isinstance(rec, DepthFrame | CameraFrame) else self._sequence[topic]
        self._sequence[topic] += 1
        self._mcap.add_message(cid, rec.receive_ns, encode(rec), sensor_time(rec), seq)
        self.count += 1

    def attach(self, name: str, media_type: str, data: bytes, t_ns: int = 0) -> None:
        self._mcap.add_attachment(t_ns, t_ns, name, media_type, data)

    def attach_json(self, name: str, obj: object, t_ns: int = 0) -> None:
        self.attach(name, "application/json", json.dumps(obj).encode(), t_ns)

    def flush(self) -> None:
        """Close the current chunk and make everything so far durable."""
        self._mcap.flush()  # type: ignore[no-untyped-call]
        os.fsync(self._file.fileno())

    def close(self) -> None:
        """Write the summary and close the file."""
        if self._file.closed:
            return
        self._mcap.finish()  # type: ignore[no-untyped-call]
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
