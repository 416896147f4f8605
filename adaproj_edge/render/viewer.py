"""What a person standing in front of the surface sees: the viewer simulator.

Every surface point (one per projector pixel) is lit by its projector pixel; a pinhole
viewer camera at ``eye`` looking at ``target`` sees the nearest lit point along each of
its rays (a z-buffer over the splatted points). Surface the projector does not light
shows dim gray, so the shape of the surface stays visible.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.irradiance import Vignetting, relative_irradiance
from adaproj_edge.geometry.surface import Surface

UNLIT = 45

DEFAULT_VIEWER = (0.8, -0.15, 0.1)
"""A person 0.8 m to the right of the projector, a little above it (frame P, metres)."""


@dataclass(frozen=True)
class Viewer:
    """A pinhole camera in frame P: position ``eye``, looking at ``target``, y down."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    width: int = 640
    height: int = 400
    fov_deg: float = 50.0

    def rotation(self) -> FloatArray:
        """Rows: the camera's x (right), y (down), z (forward) axes in frame P."""
        z = np.asarray(self.target, float) - np.asarray(self.eye, float)
        z /= np.linalg.norm(z)
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return np.stack([x, y, z])

    def project(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Pixel coordinates (..., 2) and depths (...) of points (..., 3)."""
        f = 0.5 * self.width / np.tan(np.deg2rad(self.fov_deg) / 2)
        pc = (points - np.asarray(self.eye)) @ self.rotation().T
        with np.errstate(divide="ignore", invalid="ignore"):
            u = f * pc[..., 0] / pc[..., 2] + (self.width - 1) / 2
            v = f * pc[..., 1] / pc[..., 2] + (self.height - 1) / 2
        return np.stack([u, v], axis=-1), pc[..., 2]


def view(surface: Surface, frame: NDArray[np.uint8], viewer: Viewer) -> NDArray[np.uint8]:
    """The picture (h, w, 3) the viewer sees of ``frame`` projected on ``surface``."""
    dense = surface.dense()
    pts = dense.points.reshape(-1, 3).astype(np.float64)
    colour = frame.reshape(-1, frame.shape[2] if frame.ndim == 3 else 1)
    if colour.shape[1] == 1:
        colour = np.repeat(colour, 3, axis=1)
    uv, depth = viewer.project(pts)
    ok = np.isfinite(uv).all(axis=1) & (depth > 0)
    uv = np.where(ok[:, None], uv, -1.0)
    px = np.rint(uv[:, 0]).astype(np.int64)
    py = np.rint(uv[:, 1]).astype(np.int64)
    ok &= (px >= 0) & (px < viewer.width) & (py >= 0) & (py < viewer.height)
    key = (py * viewer.width + px)[ok]
    d = depth[ok]
    c = colour[ok]
    order = np.lexsort((d, key))  # per viewer pixel, nearest first
    first = np.unique(key[order], return_index=True)[1]
    sel = order[first]
    img = np.zeros((viewer.height * viewer.width, 3), dtype=np.uint8)
    hit = np.zeros(viewer.height * viewer.width, dtype=np.uint8)
    lit = np.maximum(c[sel], UNLIT)
    img[key[sel]] = lit
    hit[key[sel]] = 1
    picture = img.reshape(viewer.height, viewer.width, 3)
    hit2d = hit.reshape(viewer.height, viewer.width)
    # close the pinholes between splatted points
    holes = (cv2.dilate(hit2d, np.ones((3, 3), np.uint8)) > 0) & (hit2d == 0)
    if np.any(holes):
        filled = cv2.inpaint(picture, holes.astype(np.uint8), 1, cv2.INPAINT_TELEA)
        picture[holes] = filled[holes]
    return picture


def lit_frame(
    surface: Surface,
    frame: NDArray[np.uint8],
    gamma: float = 2.2,
    vignetting: Vignetting | None = None,
) -> NDArray[np.uint8]:
    """``frame`` (H, W[, 3]) as bright as it looks on ``surface``: each pixel's value
    scaled by ``(E / E_ref) ** (1 / gamma)``, ``E`` its relative irradiance and
    ``E_ref`` the surface's 99.9th percentile (the same for every frame on this
    surface, so a plain and a compensated frame compare). A Lambertian surface looks
    the same from everywhere, so :func:`view` of the result shows the falloff."""
    p = surface.projector
    dense = surface.dense()
    e = relative_irradiance(dense.points.astype(np.float64), p, p.pixel_grid(), vignetting)
    ref = float(np.nanpercentile(e, 99.9)) if np.any(np.isfinite(e)) else 1.0
    scale = np.power(np.clip(np.nan_to_num(e / ref, nan=1.0), 0.0, 1.0), 1.0 / gamma)
    if frame.ndim == 3:
        scale = scale[..., None]
    return np.asarray(np.clip(np.rint(frame * scale), 0, 255), dtype=np.uint8)


def viewer_for(surface: Surface, eye: tuple[float, float, float]) -> Viewer:
    """A viewer at ``eye`` looking at the surface point at the frame's centre."""
    p = surface.projector
    centre = surface.points_at(np.array([[(p.width - 1) / 2, (p.height - 1) / 2]]))[0]
    if not np.all(np.isfinite(centre)):
        valid = surface.points[surface.valid]
        centre = valid.mean(axis=0) if valid.size else np.array([0.0, 0.0, 1.5])
    return Viewer(eye, (float(centre[0]), float(centre[1]), float(centre[2])))
