"""Encoding of each record type into a session message, and back."""

from __future__ import annotations

import base64
import json
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from google.protobuf.message import DecodeError  # type: ignore[import-untyped]

from adaproj_edge.errors import InputError
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.camera import CameraFrame
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.session import schemas as s
from adaproj_edge.session.records import PatternShown, SerialTraffic, TruthPose

Record = (
    DepthFrame | ImuSample | ButtonEvent | SerialTraffic | TruthPose | CameraFrame | PatternShown
)
CAMERA_FRAME_ID = "camera"


def topic_of(rec: Record) -> str:
    if isinstance(rec, DepthFrame):
        return s.DEPTH
    if isinstance(rec, ImuSample):
        return s.IMU
    if isinstance(rec, ButtonEvent):
        return s.BUTTON
    if isinstance(rec, SerialTraffic):
        return s.SERIAL_RX if rec.direction == "rx" else s.SERIAL_TX
    if isinstance(rec, CameraFrame):
        return s.CAMERA
    if isinstance(rec, PatternShown):
        return s.PATTERN
    return s.TRUTH_POSE


def sensor_time(rec: Record) -> int:
    if isinstance(rec, SerialTraffic):
        return rec.receive_ns
    if isinstance(rec, TruthPose | PatternShown):
        return rec.t_ns
    return rec.sensor_ns


def _json(d: dict[str, Any]) -> bytes:
    return json.dumps(d, separators=(",", ":")).encode()


def _raw_image(sensor_ns: int, frame_id: str, pixels: Any, encoding: str, depth: int) -> bytes:
    h, w = pixels.shape
    img = RawImage(
        frame_id=frame_id, width=w, height=h, encoding=encoding, step=depth * w,
        data=pixels.tobytes(),
    )  # fmt: skip
    img.timestamp.seconds, img.timestamp.nanos = divmod(sensor_ns, 1_000_000_000)
    return bytes(img.SerializeToString())


def encode(rec: Record) -> bytes:
    """The message payload of ``rec`` on its topic."""
    if isinstance(rec, DepthFrame):
        return _raw_image(rec.sensor_ns, s.DEPTH_FRAME_ID, rec.depth_mm.astype("<u2"), "16UC1", 2)
    if isinstance(rec, CameraFrame):
        frame_id = f"{CAMERA_FRAME_ID}?exposure_us={rec.exposure_us}&iso={rec.iso}"
        return _raw_image(rec.sensor_ns, frame_id, rec.image.astype(np.uint8), "mono8", 1)
    if isinstance(rec, PatternShown):
        return _json({"t_ns": rec.t_ns, "pose": rec.pose, "index": rec.index, "name": rec.name})
    if isinstance(rec, ImuSample):
        return _json(
            {
                "sensor_ns": rec.sensor_ns,
                "receive_ns": rec.receive_ns,
                "accel": list(rec.accel),
                "gyro": list(rec.gyro),
                "temperature_c": rec.temperature_c,
            }
        )
    if isinstance(rec, ButtonEvent):
        return _json(
            {
                "sensor_ns": rec.sensor_ns,
                "receive_ns": rec.receive_ns,
                "code": rec.code,
                "pressed": rec.pressed,
            }
        )
    if isinstance(rec, SerialTraffic):
        return _json({"receive_ns": rec.receive_ns, "data": base64.b64encode(rec.data).decode()})
    return _json(
        {"t_ns": rec.t_ns, "position": list(rec.position), "quaternion": list(rec.quaternion)}
    )


def _camera_settings(frame_id: str) -> tuple[int, int]:
    """Exposure (us) and ISO from a camera image's ``frame_id``."""
    name, _, query = frame_id.partition("?")
    fields = dict(kv.split("=", 1) for kv in query.split("&") if "=" in kv)
    if name != CAMERA_FRAME_ID:
        raise ValueError(f"camera frame_id {frame_id!r}")
    return int(fields.get("exposure_us", 0)), int(fields.get("iso", 0))


def _vec(v: Any, n: int) -> Any:
    if not isinstance(v, list) or len(v) != n:
        raise ValueError(f"expected a list of {n} numbers")
    return tuple(float(x) for x in v)


def decode(topic: str, data: bytes, log_time: int, sequence: int) -> Record | None:
    """The record of a message, None for topics this version does not know."""
    try:
        if topic == s.DEPTH:
            img = RawImage()
            img.ParseFromString(data)
            if img.encoding != "16UC1" or img.step != 2 * img.width:
                raise ValueError(f"depth image encoding {img.encoding!r} step {img.step}")
            depth = np.frombuffer(img.data, "<u2").reshape(img.height, img.width)
            sensor = img.timestamp.seconds * 1_000_000_000 + img.timestamp.nanos
            return DepthFrame(sensor, log_time, sequence, depth.astype(np.uint16))
        if topic == s.CAMERA:
            img = RawImage()
            img.ParseFromString(data)
            if img.encoding != "mono8" or img.step != img.width:
                raise ValueError(f"camera image encoding {img.encoding!r} step {img.step}")
            pixels = np.frombuffer(img.data, np.uint8).reshape(img.height, img.width)
            sensor = img.timestamp.seconds * 1_000_000_000 + img.timestamp.nanos
            exposure, iso = _camera_settings(img.frame_id)
            return CameraFrame(sensor, log_time, sequence, pixels.copy(), exposure, iso)
        if topic not in s.JSON_SCHEMAS:
            return None
        d = json.loads(data)
        if topic == s.IMU:
            return ImuSample(
                int(d["sensor_ns"]),
                int(d["receive_ns"]),
                _vec(d["accel"], 3),
                _vec(d["gyro"], 3),
                float(d["temperature_c"]),
            )
        if topic == s.BUTTON:
            return ButtonEvent(
                int(d["sensor_ns"]), int(d["receive_ns"]), int(d["code"]), bool(d["pressed"])
            )
        if topic in (s.SERIAL_RX, s.SERIAL_TX):
            direction = "rx" if topic == s.SERIAL_RX else "tx"
            return SerialTraffic(int(d["receive_ns"]), direction, base64.b64decode(d["data"]))
        if topic == s.PATTERN:
            return PatternShown(int(d["t_ns"]), int(d["pose"]), int(d["index"]), str(d["name"]))
        return TruthPose(int(d["t_ns"]), _vec(d["position"], 3), _vec(d["quaternion"], 4))
    except (KeyError, TypeError, ValueError, DecodeError) as e:
        raise InputError(f"malformed {topic} message at {log_time} ns: {e}") from None
