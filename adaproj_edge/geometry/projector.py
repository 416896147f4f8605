"""The pinhole projector model (frame P, OpenCV convention: x right, y down, z forward)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError

DEFAULT_WIDTH = 1280
DEFAULT_HEIGHT = 800


@dataclass(frozen=True)
class Projector:
    """Intrinsics ``K`` (3, 3) and resolution ``width`` x ``height`` in pixels.

    Pixel centres sit at integer coordinates.
    """

    K: FloatArray
    width: int = DEFAULT_WIDTH
    height: int = DEFAULT_HEIGHT

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64)
        if K.shape != (3, 3):
            raise InputError(f"projector intrinsics K must be a 3x3 matrix, got shape {K.shape}")
        if not np.all(np.isfinite(K)):
            raise InputError("projector intrinsics K hold a NaN or an infinite value")
        if K[0, 0] <= 0 or K[1, 1] <= 0 or K[2, 2] != 1.0:
            raise InputError("projector intrinsics must have positive focal lengths and K[2,2] = 1")
        if self.width < 2 or self.height < 2:
            raise InputError(f"projector resolution {self.width}x{self.height} is too small")
        object.__setattr__(self, "K", K)

    @classmethod
    def default(cls, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT) -> Projector:
        """A WXGA pico-projector with a throw ratio of about 1.4 (horizontal FOV ~39 deg)."""
        f = 1.4 * width
        K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
        return cls(K=K, width=width, height=height)

    def rays(self, uv: FloatArray) -> FloatArray:
        """Ray directions with z = 1 for pixel coordinates ``uv`` (..., 2) -> (..., 3)."""
        uv = np.asarray(uv, dtype=np.float64)
        h = np.concatenate([uv, np.ones((*uv.shape[:-1], 1))], axis=-1)
        d: FloatArray = h @ np.linalg.inv(self.K).T
        return d / d[..., 2:3]

    def project(self, points: FloatArray) -> FloatArray:
        """Pixel coordinates (..., 2) of 3D points (..., 3) in frame P."""
        p = np.asarray(points, dtype=np.float64) @ self.K.T
        with np.errstate(divide="ignore", invalid="ignore"):
            return p[..., :2] / p[..., 2:3]

    def pixel_grid(self) -> FloatArray:
        """Coordinates (H, W, 2) of every pixel centre."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        return np.stack([u, v], axis=-1)
