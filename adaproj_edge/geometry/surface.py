"""The Surface: the projector-space point map (DESIGN.md, "Surface").

For each projector pixel (or each node of a regular lattice over the projector frame)
the 3D point in frame P where that pixel's ray meets the surface, NaN where it meets
nothing. File: ``.npz`` with ``points`` (H, W, 3) float32, ``K`` (3, 3) float64 and
``meta`` (a JSON string).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import SurfaceError
from adaproj_edge.fileio import atomic_savez, load_npz
from adaproj_edge.geometry.projector import Projector

MIN_VALID_FRACTION = 0.05


@dataclass(frozen=True)
class Stencil:
    """Bilinear sampling of a lattice's depths at fixed pixels (:meth:`Surface.depth_at`).

    Attributes
    ----------
    at : (4, N) flat indices of the four neighbours' depths in ``points.reshape(-1)``
        (top-left, top-right, bottom-left, bottom-right).
    weights : (4, N) their bilinear weights; ``heavy`` (4, N): weights above 1e-9 (the
        others are left out).
    outside : (N,) the pixel is outside the frame.
    gx, gy, x0, y0 : (N,) lattice coordinates and the top-left neighbour (which of the
        four is nearest).
    shape : the pixels' array shape.
    """

    at: IntArray
    weights: FloatArray
    heavy: NDArray[np.bool_]
    outside: NDArray[np.bool_]
    gx: FloatArray
    gy: FloatArray
    x0: IntArray
    y0: IntArray
    shape: tuple[int, ...]

    @classmethod
    def of(cls, uv: FloatArray, lattice: tuple[int, int], scale: tuple[float, float]) -> Stencil:
        """The stencil of pixels ``uv`` (..., 2) on a lattice of ``(h, w)`` nodes,
        ``scale`` (x, y) projector pixels apart."""
        uv = np.asarray(uv, dtype=np.float64)
        shape = uv.shape[:-1]
        uv = uv.reshape(-1, 2)
        sx, sy = scale
        h, w = lattice
        gx = uv[:, 0] / sx
        gy = uv[:, 1] / sy
        inside = (gx >= -0.5) & (gx <= w - 0.5) & (gy >= -0.5) & (gy <= h - 0.5)
        gx = np.clip(gx, 0.0, w - 1.0)
        gy = np.clip(gy, 0.0, h - 1.0)
        x0 = np.minimum(np.floor(gx).astype(np.intp), w - 2)
        y0 = np.minimum(np.floor(gy).astype(np.intp), h - 2)
        fx = gx - x0
        fy = gy - y0
        at = np.array([[0], [3], [3 * w], [3 * w + 3]]) + (3 * (y0 * w + x0) + 2)
        gx1, gy1 = 1 - fx, 1 - fy
        weights = np.stack([gx1 * gy1, fx * gy1, gx1 * fy, fx * fy])
        return cls(at, weights, weights > 1e-9, ~inside, gx, gy, x0, y0, shape)

    def depth(self, points: NDArray[np.float32]) -> FloatArray:
        """The depths of lattice ``points`` (h, w, 3) at the stencil's pixels."""
        zz = np.take(points.reshape(-1), self.at)  # (4, N) float32
        seen = np.isfinite(zz)
        ok = seen & self.heavy
        # summed in the neighbours' order (as adding them one by one)
        num = np.where(ok, zz * self.weights, 0.0).sum(axis=0)
        den = np.where(ok, self.weights, 0.0).sum(axis=0)
        bad = self.outside | (den <= 0)
        # the nearest node, one of the four, must be valid (checked where one is not)
        some = np.flatnonzero(~seen.all(axis=0))
        if some.size:
            nx = np.rint(self.gx[some]).astype(np.intp) - self.x0[some]
            ny = np.rint(self.gy[some]).astype(np.intp) - self.y0[some]
            bad[some] |= ~seen[2 * ny + nx, some]
        with np.errstate(invalid="ignore", divide="ignore"):
            out: FloatArray = num / den
        out[bad] = np.nan
        return out.reshape(self.shape)


@dataclass(frozen=True)
class Surface:
    """A point map in frame P.

    Parameters
    ----------
    points : (h, w, 3) float array
        Points in metres, NaN where the ray meets nothing. When ``(h, w)`` differs
        from the projector resolution the nodes form a regular lattice whose corners
        are the corner pixel centres of the frame.
    projector : Projector
        Intrinsics and resolution of the projector frame.
    meta : dict
        Free-form description (name of an analytic surface, source, ...).
    """

    points: NDArray[np.float32]
    projector: Projector
    meta: dict[str, Any] = field(default_factory=dict)
    # nodes whose ray meets the surface, counted once (a warp checks it on every call)
    _valid_count: int = field(init=False, repr=False, compare=False, default=0)

    def __post_init__(self) -> None:
        pts = np.asarray(self.points)
        if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[0] < 2 or pts.shape[1] < 2:
            raise SurfaceError(f"surface points must have shape (H, W, 3), got {pts.shape}")
        pts = pts.astype(np.float32, copy=False)
        bad = ~np.all(np.isfinite(pts), axis=2)
        behind = np.zeros_like(bad)
        behind[~bad] = pts[~bad][:, 2] <= 0.0
        if np.any(behind):
            pts = pts.copy()
            bad |= behind
        if np.any(bad):
            pts = pts.copy()
            pts[bad] = np.nan
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "_valid_count", int(bad.size - np.count_nonzero(bad)))

    # ------------------------------------------------------------------ queries
    @property
    def shape(self) -> tuple[int, int]:
        """Lattice size ``(h, w)``."""
        return int(self.points.shape[0]), int(self.points.shape[1])

    @property
    def valid(self) -> NDArray[np.bool_]:
        """(h, w) mask of nodes whose ray meets the surface."""
        return np.asarray(np.isfinite(self.points[..., 2]))

    @property
    def valid_fraction(self) -> float:
        """Fraction of nodes whose ray meets the surface."""
        h, w = self.shape
        return float(self._valid_count / (h * w))

    def lattice_scale(self) -> tuple[float, float]:
        """Projector pixels per lattice step along x and y."""
        h, w = self.shape
        return (self.projector.width - 1) / (w - 1), (self.projector.height - 1) / (h - 1)

    def depth_at(self, uv: FloatArray) -> FloatArray:
        """Depth (z in frame P) at projector pixel coordinates ``uv`` (..., 2).

        Bilinear in the lattice, using only valid neighbours; NaN where the nearest
        node is invalid or ``uv`` is outside the frame.
        """
        return self.stencil(uv).depth(self.points)

    def stencil(self, uv: FloatArray) -> Stencil:
        """What :meth:`depth_at` ``uv`` computes from ``uv`` alone: the same for every
        surface of this lattice (shape, projector), so a caller may keep it."""
        return Stencil.of(uv, self.shape, self.lattice_scale())

    def points_at(self, uv: FloatArray) -> FloatArray:
        """3D points (..., 3) on the rays of pixels ``uv`` (..., 2); NaN where none."""
        return self.projector.rays(uv) * self.depth_at(uv)[..., None]

    def dense(self) -> Surface:
        """The same surface resampled at every projector pixel."""
        p = self.projector
        if self.shape == (p.height, p.width):
            return self
        pts = self.points_at(p.pixel_grid()).astype(np.float32)
        return Surface(pts, p, dict(self.meta))

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the ``.npz`` file atomically (temporary file, fsync, rename)."""
        meta = dict(self.meta)
        meta.update(width=self.projector.width, height=self.projector.height)
        atomic_savez(
            Path(path), points=self.points, K=self.projector.K, meta=np.array(json.dumps(meta))
        )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Surface:
        """Read and validate a Surface file."""
        path = Path(path)
        arrays = load_npz(path, "surface file", ("points", "K"), SurfaceError)
        points = arrays["points"]
        K = arrays["K"]
        try:
            meta = json.loads(str(arrays["meta"])) if "meta" in arrays else {}
            K = K.astype(np.float64)
        except (ValueError, TypeError) as e:
            raise SurfaceError(f"surface file {path}: unreadable meta or K: {e}") from None
        if not isinstance(meta, dict):
            raise SurfaceError(f"surface file {path}: meta must be a JSON object")
        if points.ndim != 3 or points.shape[-1] != 3:
            raise SurfaceError(f"surface file {path}: points must be (H, W, 3), got {points.shape}")
        try:
            width = int(meta.get("width") or points.shape[1])
            height = int(meta.get("height") or points.shape[0])
        except (TypeError, ValueError):
            raise SurfaceError(f"surface file {path}: meta width/height are not numbers") from None
        return cls(points, Projector(K, width, height), meta)

    def check_usable(self, min_fraction: float = MIN_VALID_FRACTION) -> None:
        """Raise :class:`SurfaceError` when too little of the frame meets the surface."""
        if self.valid_fraction < min_fraction:
            raise SurfaceError(
                f"only {100 * self.valid_fraction:.1f} % of the projector frame meets the "
                f"surface (at least {100 * min_fraction:.0f} % is needed)"
            )
