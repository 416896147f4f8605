"""A recorded calibration session as the procedure's devices (``adaproj calibrate
--replay``): the recorded camera frames, depth frames, IMU samples and patterns on
one virtual clock, and the capture settings the session was made with."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, field_errors
from adaproj_edge.hal.camera import CameraFrame, CameraSettings, ReplayCamera
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import ReplayDepthCamera
from adaproj_edge.hal.imu import ReplayImu
from adaproj_edge.procam.photometric import PRIMARY_FRAMES
from adaproj_edge.procam.plan import PlanSettings
from adaproj_edge.procam.procedure import (
    CaptureRun,
    Devices,
    Listener,
    ProcedureSettings,
    ReplayShow,
    capture_poses,
)
from adaproj_edge.session import schemas
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import PatternShown


@dataclass(frozen=True)
class RecordedCapture:
    """Everything needed to run the procedure again on a recording."""

    devices: Devices
    camera: CameraSettings
    max_poses: int
    min_poses: int
    nominal: Calibration
    attachments: dict[str, bytes]
    photometric: bool = False

    @property
    def settings(self) -> ProcedureSettings:
        """The procedure's settings as recorded (the pose counts it ran with)."""
        return ProcedureSettings(
            max_poses=self.max_poses,
            plan=PlanSettings(min_poses=self.min_poses),
            photometric=self.photometric,
        )


def run_recorded(rc: RecordedCapture, listener: Listener) -> CaptureRun:
    """The procedure on a recorded session, as it ran on the device."""
    p = rc.nominal.projector
    size = (p.width, p.height)
    return capture_poses(rc.devices, rc.camera, listener, rc.settings, size, rc.nominal.R_P_I)


def _json(attachments: dict[str, bytes], name: str, path: object) -> Any:
    raw = attachments.get(name)
    if raw is None:
        raise InputError(f"session {path} has no {name} (not a calibration session?)")
    try:
        return json.loads(raw)
    except ValueError as e:
        raise InputError(f"{path}:{name} is not valid JSON: {e}") from None


def recorded_capture(path: str | os.PathLike[str]) -> RecordedCapture:
    """The replay devices of calibration session ``path`` (read once, into memory);
    the nominal calibration is the session's own (the one the device had)."""
    ses = read_session(path)
    att = ses.attachments
    info = _json(att, schemas.CAPTURE_ATTACHMENT, path)
    cam_info = _json(att, schemas.CAMERA_ATTACHMENT, path)
    with field_errors(f"{path}:{schemas.CAPTURE_ATTACHMENT}"):
        cam = dict(info["camera"])
        known = {f.name for f in fields(CameraSettings)}
        camera = CameraSettings(**{k: v for k, v in cam.items() if k in known})
        max_poses, min_poses = int(info["max_poses"]), int(info["min_poses"])
        K = np.asarray(cam_info["K"], np.float64).reshape(3, 3)
        size = (int(cam_info["width"]), int(cam_info["height"]))
    if not 1 <= min_poses <= max_poses:
        raise InputError(f"{path}: capture.json asks for {min_poses}..{max_poses} poses")
    clock = VirtualClock()
    recs = ses.records
    shown = [r for r in recs if isinstance(r, PatternShown)]
    # a session that measured the surface's colour shows the primaries: replay it so
    photometric = any(r.name == PRIMARY_FRAMES[0][0] for r in shown)
    devices = Devices(
        ReplayShow(iter(shown), clock),
        ReplayCamera(K, size, [r for r in recs if isinstance(r, CameraFrame)], clock),
        ReplayDepthCamera(ses.calibration.depth, ses.depth, clock),
        ReplayImu(ses.imu, clock),
        clock,
    )
    return RecordedCapture(devices, camera, max_poses, min_poses, ses.calibration, att, photometric)
