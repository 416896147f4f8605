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
pose's depth (:class:`Measured`, saved beside the calibration as
``OUT.photometric.npz``) and holds only while the depth the device sees stays that
surface (:meth:`Measured.holds_for`); the geometric gain stays either way.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import atomic_savez, load_npz
from adaproj_edge.procam.graycode import Decoded
from adaproj_edge.render.reflectance import (
    PRIMARY_WEIGHTS,
    ReflectanceSettings,
    Response,
    measure,
)

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


def to_projector(
    image: NDArray[np.uint8] | FloatArray,
    decoded: Decoded,
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
    decoded: Decoded,
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
"""The median depth change (metres) beyond which the device has moved off the surface
its colour was measured on."""


@dataclass(frozen=True)
class Measured:
    """A surface's measured response and the depth (h, w, metres, NaN: none) the
    device saw of it when it was measured."""

    response: Response
    depth_m: FloatArray
    projector_size: tuple[int, int]

    def holds_for(self, depth_m: FloatArray, moved_m: float = MOVED_M) -> bool:
        """Whether a depth image (any size) still shows the measured surface: the
        median |change| over the pixels valid in both is at most ``moved_m`` and they
        overlap over at least half of the measured ones."""
        now = np.asarray(depth_m, np.float32)
        h, w = self.depth_m.shape
        if now.shape != (h, w):
            now = np.asarray(cv2.resize(now, (w, h), interpolation=cv2.INTER_NEAREST), np.float32)
        was = np.isfinite(self.depth_m) & (self.depth_m > 0)
        both = was & np.isfinite(now) & (now > 0)
        if 2 * int(np.count_nonzero(both)) < int(np.count_nonzero(was)):
            return False
        return float(np.median(np.abs(now[both] - self.depth_m[both]))) <= moved_m

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write it as ``.npz`` (atomically)."""
        r = self.response
        meta = json.dumps({"projector_size": list(self.projector_size)})
        atomic_savez(
            path, mix=r.mix, ambient=r.ambient, valid=r.valid, depth_m=self.depth_m, meta=meta
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Measured:
        """Read a file :meth:`save` wrote (a clear error for anything else)."""
        z = load_npz(
            path, "photometric measurement", ("mix", "ambient", "valid", "depth_m", "meta")
        )
        mix = np.asarray(z["mix"], np.float32)
        ambient = np.asarray(z["ambient"], np.float32)
        valid = np.asarray(z["valid"], bool)
        depth = np.asarray(z["depth_m"], np.float64)
        h, w = valid.shape if valid.ndim == 2 else (0, 0)
        if mix.shape != (h, w, 3, 3) or ambient.shape != (h, w, 3) or depth.ndim != 2:
            raise InputError(f"{path}: the photometric arrays do not fit together")
        try:
            size = tuple(int(v) for v in json.loads(str(z["meta"]))["projector_size"])
        except (ValueError, KeyError, TypeError):
            raise InputError(f"{path}: its meta has no projector_size") from None
        if len(size) != 2:
            raise InputError(f"{path}: its meta has no projector_size")
        return cls(Response(mix, ambient, valid), depth, (size[0], size[1]))
