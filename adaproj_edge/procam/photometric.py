"""Photometric captures: what the calibration camera sees of the projector's black,
white and primaries, mapped to projector pixels through a pose's Gray-code
correspondences, and the surface's measured response
(:mod:`adaproj_edge.render.reflectance`).

Black and white are the Gray-code sequence's own first two captures; the three
primaries (full blue, green, red) are three more frames, so a pose measures its
surface's colour with five frames in all. A camera pixel decoded to projector
position (x, y) adds its value to the projector cell of 1/``scale`` of the frame
holding (x, y); a cell's value is the mean of its camera pixels. Cells no camera pixel
decoded to (the camera resolves the projector more coarsely than the cells) take the
weighted mean of their decoded neighbours within about one decoded cell; farther ones
stay NaN (not measured).

A measured response belongs to the surface it was measured on: it is kept with that
pose's distance to the surface per projector cell (:class:`Measured`, saved beside
the calibration as ``OUT.photometric.npz``) and holds only while the surface the
device sees stays there (:meth:`Measured.holds_on`); the geometric gain stays either
way.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray, Image
from adaproj_edge.errors import AdaprojError, InputError
from adaproj_edge.fileio import atomic_savez, load_npz
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.procam.graycode import Decoded
from adaproj_edge.procam.pairs import depth_at_camera
from adaproj_edge.render.reflectance import (
    PRIMARY_WEIGHTS,
    ReflectanceSettings,
    Response,
    measure,
)

log = logging.getLogger(__name__)

PRIMARY_FRAMES: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("blue", (255, 0, 0)),
    ("green", (0, 255, 0)),
    ("red", (0, 0, 255)),
)
"""The three captures added to a pose's Gray-code sequence: name and BGR value."""


def primary_frame(index: int, size: tuple[int, int]) -> Image:
    """Primary ``index`` of :data:`PRIMARY_FRAMES` as a (h, w, 3) BGR frame of ``size``
    (w, h) (a read-only view)."""
    w, h = size
    return np.broadcast_to(np.asarray(PRIMARY_FRAMES[index][1], np.uint8), (h, w, 3))


class CellMap(Protocol):
    """Where each camera pixel lands in the projector: a Gray-code
    :class:`~adaproj_edge.procam.graycode.Decoded`, or a map through the calibration
    (:class:`~adaproj_edge.procam.colour_capture.GeometricMap`)."""

    @property
    def valid(self) -> BoolArray:
        """(h, w): mapped."""

    @property
    def x(self) -> FloatArray:
        """(h, w) projector x, NaN where not mapped."""

    @property
    def y(self) -> FloatArray:
        """(h, w) projector y, NaN where not mapped."""

    @property
    def cell_x(self) -> float:
        """Projector pixels along x a camera pixel stands for."""

    @property
    def cell_y(self) -> float:
        """Projector pixels along y a camera pixel stands for."""


def to_projector(
    image: NDArray[np.uint8] | FloatArray,
    decoded: CellMap,
    projector_size: tuple[int, int],
    scale: int = 2,
) -> FloatArray:
    """The camera ``image`` (h, w) mapped to projector cells: (H // scale, W // scale)
    float, the mean of the camera pixels decoded into each cell, NaN where none
    (see the module's description).

    Raises
    ------
    InputError
        The image is not the decoded captures' size.
    """
    if image.shape != decoded.valid.shape:
        raise InputError(f"capture {image.shape} is not the decoded size {decoded.valid.shape}")
    pw, ph = projector_size
    w, h = max(pw // scale, 1), max(ph // scale, 1)
    ok = decoded.valid
    ix = np.clip((decoded.x[ok] * (w / pw)).astype(np.int64), 0, w - 1)
    iy = np.clip((decoded.y[ok] * (h / ph)).astype(np.int64), 0, h - 1)
    key = iy * w + ix
    values = np.asarray(image, np.float64)[ok]
    sums = np.bincount(key, weights=values, minlength=w * h).reshape(h, w)
    counts = np.bincount(key, minlength=w * h).reshape(h, w).astype(np.float64)
    # the camera resolves cells of decoded.cell_* projector pixels: cells between the
    # decoded ones are filled from them (a Gaussian of that width, normalised)
    sigma = max(decoded.cell_x * w / pw, decoded.cell_y * h / ph, 0.5)
    mean = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    hit = (counts > 0).astype(np.float64)
    near = cv2.GaussianBlur(hit, (0, 0), sigma)
    spread = cv2.GaussianBlur(mean * hit, (0, 0), sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        filled = spread / near
    typical = float(np.median(near[counts > 0])) if np.any(counts > 0) else 1.0
    reach = near > 0.25 * typical  # inside the decoded area, not beyond its edge
    out: FloatArray = np.where(counts > 0, mean, np.where(reach, filled, np.nan))
    return out


def measure_pose(
    black: Image,
    white: Image,
    primaries: Sequence[Image],
    decoded: CellMap,
    projector_size: tuple[int, int],
    scale: int = 2,
    weights: Sequence[float] = PRIMARY_WEIGHTS,
    settings: ReflectanceSettings | None = None,
) -> Response:
    """The surface's :class:`~adaproj_edge.render.reflectance.Response` at one pose
    from its grey captures of black, white and the three primaries (camera images)
    and its decoded Gray code.

    Raises
    ------
    CalibrationError
        Saturated, dark or inconsistent captures (see
        :func:`~adaproj_edge.render.reflectance.measure`).
    """
    maps = [to_projector(c, decoded, projector_size, scale) for c in (black, white, *primaries)]
    return measure(maps[0], maps[1], maps[2:], weights, settings)


MOVED_M = 0.03
"""The median change (metres) of the distance to the surface, over the measured
cells, beyond which the device has moved off the surface its colour was measured on."""


@dataclass(frozen=True)
class Measured:
    """A surface's measured response and the distance (h, w, metres from the
    projector's centre, NaN: none) of the surface behind each of its cells when it was
    measured."""

    response: Response
    distance_m: FloatArray
    projector_size: tuple[int, int]

    def holds_on(self, surface: Surface, moved_m: float = MOVED_M) -> str | None:
        """None when ``surface`` (the device's now) is still the measured one: over at
        least half of the measured cells, the median |change of distance| is at most
        ``moved_m``; else why not."""
        p = surface.projector
        if (p.width, p.height) != self.projector_size:
            return f"measured for a {self.projector_size} frame, not {p.width}x{p.height}"
        h, w = self.distance_m.shape
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        sx, sy = p.width / w, p.height / h
        uv = np.stack([(u + 0.5) * sx - 0.5, (v + 0.5) * sy - 0.5], axis=-1)
        now = np.linalg.norm(surface.points_at(uv), axis=-1)
        was = np.isfinite(self.distance_m)
        both = was & np.isfinite(now)
        if 2 * int(np.count_nonzero(both)) < int(np.count_nonzero(was)):
            return "the device moved off the surface its colour was measured on"
        change = float(np.median(np.abs(now[both] - self.distance_m[both])))
        if change > moved_m:
            return f"the device moved {change * 100:.0f} cm from where the colour was measured"
        return None

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write it as ``.npz`` (atomically)."""
        r = self.response
        meta = json.dumps({"projector_size": list(self.projector_size)})
        atomic_savez(
            path,
            mix=r.mix,
            ambient=r.ambient,
            valid=r.valid,
            distance_m=self.distance_m,
            meta=meta,
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Measured:
        """Read a file :meth:`save` wrote (a clear error for anything else)."""
        names = ("mix", "ambient", "valid", "distance_m", "meta")
        z = load_npz(path, "photometric measurement", names)
        mix = np.asarray(z["mix"], np.float32)
        ambient = np.asarray(z["ambient"], np.float32)
        valid = np.asarray(z["valid"], bool)
        dist = np.asarray(z["distance_m"], np.float64)
        h, w = valid.shape if valid.ndim == 2 else (0, 0)
        if mix.shape != (h, w, 3, 3) or ambient.shape != (h, w, 3) or dist.shape != (h, w):
            raise InputError(f"{path}: the photometric arrays do not fit together")
        try:
            size = tuple(int(v) for v in json.loads(str(z["meta"]))["projector_size"])
        except (ValueError, KeyError, TypeError):
            raise InputError(f"{path}: its meta has no projector_size") from None
        if len(size) != 2:
            raise InputError(f"{path}: its meta has no projector_size")
        return cls(Response(mix, ambient, valid), dist, (size[0], size[1]))


def surface_distance(
    depth_m: FloatArray,
    camera_K: FloatArray,
    T_P_D: FloatArray,
    decoded: Decoded,
    projector_size: tuple[int, int],
    scale: int = 2,
) -> FloatArray:
    """The distance from the projector's centre (h, w, metres, NaN: none) of the
    surface behind each projector cell, from a pose's depth (frame D, any size of the
    camera's field of view), the camera's intrinsics at the decoded captures' size,
    the rig's ``T_P_D`` and the pose's decode."""
    h, w = decoded.valid.shape
    z = depth_at_camera(np.asarray(depth_m, np.float64), (w, h))
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(camera_K).T
    pts = rays * z[..., None]
    pts_p = pts @ T_P_D[:3, :3].T + T_P_D[:3, 3]
    dist = np.where(z > 0, np.linalg.norm(pts_p, axis=-1), np.nan)
    ok = replace(decoded, code_x=np.where(np.isfinite(dist), decoded.code_x, -1).astype(np.int32))
    return to_projector(np.nan_to_num(dist), ok, projector_size, scale)


def photometric_path(calibration: str | os.PathLike[str]) -> Path:
    """``OUT.photometric.npz`` beside the calibration ``OUT.toml``."""
    p = Path(calibration)
    return p.with_name(p.stem + ".photometric.npz")


def load_beside(calibration: str | os.PathLike[str]) -> Measured | None:
    """The measurement written beside the calibration file, None when there is none
    or it cannot be used (the reason logged: the geometric gain serves)."""
    path = photometric_path(calibration)
    if not path.is_file():
        return None
    try:
        return Measured.load(path)
    except AdaprojError as e:
        log.warning("surface colour not compensated: %s", e)
        return None
