"""Topics, schemas and encodings of a session MCAP file.

==================  ======================  =======================================
topic               encoding / schema       payload
==================  ======================  =======================================
``/depth/image``    protobuf                ``foxglove.RawImage``: ``16UC1`` mm,
                    ``foxglove.RawImage``   0 = invalid; ``timestamp`` = sensor time
``/imu``            json ``adaproj.Imu``    sensor_ns, receive_ns, accel (m/s^2),
                                            gyro (rad/s), temperature_c
``/button``         json ``adaproj.Button`` sensor_ns, receive_ns, code, pressed
``/serial/rx``      json ``adaproj.Serial`` receive_ns, data (base64), from the host
``/serial/tx``      json ``adaproj.Serial`` the same, to the host
``/truth/pose``     json ``adaproj.Pose``   simulated sessions: T_W_P
``/camera/image``   protobuf                calibration sessions: the structured-
                    ``foxglove.RawImage``   light camera, ``mono8``; ``timestamp``
                                            = start of exposure; ``frame_id`` holds
                                            exposure (us) and ISO
``/calibration/     json                    calibration sessions: each pattern
pattern``           ``adaproj.Pattern``     shown (t_ns, pose, index, name)
==================  ======================  =======================================

Every message's ``log_time`` is its receive time and ``publish_time`` its sensor time
(int ns, the device's monotonic clock). Attachments: ``calibration.json`` (always,
written first) and, in simulated sessions, ``truth-surface.json`` plus the mesh, and
``truth-calibration.json`` when the simulated device's true rig differs from the
calibration it records (calibration sessions, and sessions for the calibration
payoff). Calibration sessions also attach ``camera.json`` (the camera's
intrinsics and size) and ``capture.json`` (the board's capture settings).
"""

from __future__ import annotations

import json
from typing import Any

from google.protobuf import descriptor_pb2  # type: ignore[import-untyped]
from google.protobuf.descriptor import FileDescriptor  # type: ignore[import-untyped]

DEPTH = "/depth/image"
IMU = "/imu"
BUTTON = "/button"
SERIAL_RX = "/serial/rx"
SERIAL_TX = "/serial/tx"
TRUTH_POSE = "/truth/pose"
CAMERA = "/camera/image"
PATTERN = "/calibration/pattern"
CALIBRATION_ATTACHMENT = "calibration.json"
TRUTH_SURFACE_ATTACHMENT = "truth-surface.json"
TRUTH_RIG_ATTACHMENT = "truth-calibration.json"
CAMERA_ATTACHMENT = "camera.json"
CAPTURE_ATTACHMENT = "capture.json"
PROTOBUF_TOPICS = (DEPTH, CAMERA)
PROFILE = "adaproj-session/1"
DEPTH_FRAME_ID = "depth"


def _object(name: str, props: dict[str, Any]) -> tuple[str, bytes]:
    schema = {
        "$schema": "http://json-schema.org/draft-07/schema#",
        "title": name,
        "type": "object",
        "properties": props,
        "required": sorted(props),
    }
    return name, json.dumps(schema).encode()


_INT = {"type": "integer"}
_VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
JSON_SCHEMAS: dict[str, tuple[str, bytes]] = {
    IMU: _object(
        "adaproj.Imu",
        {
            "sensor_ns": _INT,
            "receive_ns": _INT,
            "accel": _VEC3,
            "gyro": _VEC3,
            "temperature_c": {"type": "number"},
        },
    ),
    BUTTON: _object(
        "adaproj.Button",
        {"sensor_ns": _INT, "receive_ns": _INT, "code": _INT, "pressed": {"type": "boolean"}},
    ),
    SERIAL_RX: _object(
        "adaproj.Serial",
        {"receive_ns": _INT, "data": {"type": "string", "contentEncoding": "base64"}},
    ),
    TRUTH_POSE: _object(
        "adaproj.Pose",
        {
            "t_ns": _INT,
            "position": _VEC3,
            "quaternion": {"type": "array", "items": {"type": "number"}, "minItems": 4},
        },
    ),
    PATTERN: _object(
        "adaproj.Pattern",
        {"t_ns": _INT, "pose": _INT, "index": _INT, "name": {"type": "string"}},
    ),
}
JSON_SCHEMAS[SERIAL_TX] = JSON_SCHEMAS[SERIAL_RX]


def file_descriptor_set(fd: FileDescriptor) -> bytes:
    """The serialized ``FileDescriptorSet`` of ``fd`` and its dependencies (MCAP schema)."""
    fds = descriptor_pb2.FileDescriptorSet()
    seen: set[str] = set()

    def add(f: FileDescriptor) -> None:
        if f.name in seen:
            return
        for dep in f.dependencies:
            add(dep)
        seen.add(f.name)
        proto = descriptor_pb2.FileDescriptorProto()
        f.CopyToProto(proto)
        fds.file.append(proto)

    add(fd)
    return bytes(fds.SerializeToString())
