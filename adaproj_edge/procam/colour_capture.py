"""The surface's colour measured again on its own: the runtime's colour gesture.

Five frames -- black, white and the three primaries -- are shown and captured (about
0.2 s each with the board's display and camera latencies), with a depth frame before
and after. No Gray code: each camera pixel is mapped to its projector pixel through
the calibration in use (the depth behind it, ``T_P_D`` and the projector's intrinsics
and lens, :func:`through_geometry`). That is exact enough: a calibration good to a
fraction of a projector pixel (its reprojection RMS) and depth good to a few
millimetres at 1.5 m (a parallax of well under a pixel over the camera-projector
baseline) place a camera pixel within the measurement's cells (2 projector pixels),
whose colour is smoothed over two of them anyway
(:mod:`adaproj_edge.render.reflectance`).

Refused, with the reason (the measurement in use stays): saturated or dark captures,
white and the primaries disagreeing (:func:`~adaproj_edge.render.reflectance.measure`),
no depth, or the surface moved more than :data:`MOVED_M` between the depth frames
before and after the captures.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import cv2
import numpy as np

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.camera import Camera, CameraSettings
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.depth import DepthCamera
from adaproj_edge.procam.pairs import depth_at_camera
from adaproj_edge.procam.photometric import (
    PRIMARY_FRAMES,
    Measured,
    measure_pose,
    primary_frame,
    to_projector,
)
from adaproj_edge.procam.procedure import Devices, Listener, ShowLog, capture_frame

MOVED_M = 0.02
"""The median change of depth (metres) between the depth frames before and after the
captures beyond which the device moved during them."""


@dataclass(frozen=True)
class GeometricMap:
    """Camera pixels (h, w) mapped to projector positions ``x``, ``y`` (NaN: none)
    through the calibration; ``cell_x``, ``cell_y``: the projector pixels between
    neighbouring camera pixels (what a camera pixel stands for). Fits
    :func:`~adaproj_edge.procam.photometric.to_projector` like a Gray-code decode."""

    x: FloatArray
    y: FloatArray
    valid: BoolArray
    cell_x: float
    cell_y: float


def through_geometry(
    depth_m: FloatArray, camera_K: FloatArray, camera_size: tuple[int, int], cal: Calibration
) -> tuple[GeometricMap, FloatArray]:
    """Each camera pixel's projector position, from the depth behind it (frame D, any
    size of the camera's field of view), and its distance (h, w, metres, NaN: none)
    from the projector's centre."""
    w, h = camera_size
    z = depth_at_camera(np.asarray(depth_m, np.float64), (w, h))
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(camera_K).T
    T = cal.T_P_D
    pts = (rays * z[..., None]) @ T[:3, :3].T + T[:3, 3]
    ok = (z > 0) & np.isfinite(z) & (pts[..., 2] > 0)
    flat = np.where(ok[..., None], pts, 1.0).reshape(-1, 1, 3)
    p = cal.projector
    zero = np.zeros(3)
    uv, _ = cv2.projectPoints(flat, zero, zero, p.K, np.asarray(cal.distortion, np.float64))
    uv = uv.reshape(h, w, 2)
    ok &= (uv[..., 0] >= 0) & (uv[..., 0] < p.width) & (uv[..., 1] >= 0) & (uv[..., 1] < p.height)
    x, y = np.where(ok, uv[..., 0], np.nan), np.where(ok, uv[..., 1], np.nan)
    both = ok[:, 1:] & ok[:, :-1]
    step = np.hypot(np.diff(x, axis=1), np.diff(y, axis=1))[both]
    cell = float(np.median(step)) if step.size else 1.0
    dist = np.where(ok, np.linalg.norm(pts, axis=-1), np.nan)
    return GeometricMap(x, y, ok, cell, cell), dist


def measure_colour(
    show: ShowLog,
    camera: Camera,
    depth: DepthCamera,
    clock: Clock,
    cam: CameraSettings,
    calibration: Calibration,
    listener: Listener,
    scale: int = 2,
) -> Measured:
    """Show black, white and the primaries, capture them and measure the surface's
    colour (see the module's description).

    Raises
    ------
    CalibrationError
        A refused capture; the message says what to redo.
    """
    p = calibration.projector
    size = (p.width, p.height)
    dev = Devices(show, camera, depth, _NoImu(), clock)
    before = _depth(depth)
    frames = [("black", np.zeros((p.height, p.width, 3), np.uint8))]
    frames.append(("white", np.full((p.height, p.width, 3), 255, np.uint8)))
    frames += [(name, primary_frame(j, size)) for j, (name, _) in enumerate(PRIMARY_FRAMES)]
    images = [
        capture_frame(dev, cam, listener, 0, i, n, f).image for i, (n, f) in enumerate(frames)
    ]
    after = _depth(depth)
    both = (before > 0) & (after > 0) & np.isfinite(before) & np.isfinite(after)
    if np.count_nonzero(both) < 0.1 * both.size:
        raise CalibrationError("the depth camera sees no surface: aim at a wall")
    moved = float(np.median(np.abs(after[both] - before[both])))
    if moved > MOVED_M:
        raise CalibrationError(
            f"the device moved {moved * 100:.0f} cm during the captures: hold it still"
        )
    mapped, dist = through_geometry(after, camera.intrinsics, camera.size, calibration)
    response = measure_pose(images[0], images[1], images[2:], mapped, size, scale)
    cells = to_projector(np.nan_to_num(dist), mapped, size, scale)
    return Measured(response, np.where(response.valid, cells, np.nan), size)


def _depth(depth: DepthCamera, frames: int = 3) -> FloatArray:
    """The median of the next ``frames`` depth frames (metres, NaN: none)."""
    got = []
    for _ in range(100 * frames):
        f = depth.read()
        if f is not None:
            got.append(f.metres())
            if len(got) == frames:
                with warnings.catch_warnings():  # pixels no frame saw stay NaN
                    warnings.simplefilter("ignore", RuntimeWarning)
                    out: FloatArray = np.nanmedian(np.stack(got), axis=0)
                return out
    raise CalibrationError("the depth camera sends nothing")


class _NoImu:
    """The colour captures read no IMU."""

    def read(self) -> None:
        return None

    def close(self) -> None:
        return None
