"""The Warp (DESIGN.md): a backward mesh map from projector pixels to content pixels."""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import atomic_savez, load_npz
from adaproj_edge.geometry.projector import Projector

MAX_GRID = 400


@dataclass(frozen=True)
class Grid:
    """A regular mesh of ``cols`` x ``rows`` cells over the projector frame."""

    cols: int = 20
    rows: int = 20

    def __post_init__(self) -> None:
        if not (1 <= self.cols <= MAX_GRID and 1 <= self.rows <= MAX_GRID):
            raise InputError(
                f"grid {self.cols}x{self.rows} is outside 1x1 .. {MAX_GRID}x{MAX_GRID}"
            )

    @classmethod
    def parse(cls, text: str) -> Grid:
        """``"20x20"`` (columns x rows of cells) -> Grid."""
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
        if not m:
            raise InputError(f"grid must look like 20x20 (columns x rows), got {text!r}")
        return cls(int(m.group(1)), int(m.group(2)))

    def __str__(self) -> str:
        return f"{self.cols}x{self.rows}"

    def vertices(self, projector: Projector) -> FloatArray:
        """Vertex positions (rows + 1, cols + 1, 2) on integer pixel centres."""
        if self.cols >= projector.width or self.rows >= projector.height:
            raise InputError(
                f"grid {self} is finer than the {projector.width}x{projector.height} frame"
            )
        xs = np.rint(np.linspace(0, projector.width - 1, self.cols + 1))
        ys = np.rint(np.linspace(0, projector.height - 1, self.rows + 1))
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)


@dataclass
class Warp:
    """Content coordinates ``image_xy`` (R, C, 2) of the grid vertices ``grid_uv`` (R, C, 2).

    NaN in ``image_xy`` marks vertices with no surface (they show black). ``map_xy``
    (H, W, 2) float32, when present, is the per-pixel map the renderer uses.
    """

    grid_uv: FloatArray
    image_xy: FloatArray
    content_size: tuple[int, int]
    projector: Projector
    meta: dict[str, Any] = field(default_factory=dict)
    map_xy: NDArray[np.float32] | None = None
    depth: FloatArray | None = None

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the warp file atomically."""
        meta = dict(self.meta)
        meta.update(
            content_width=self.content_size[0],
            content_height=self.content_size[1],
            width=self.projector.width,
            height=self.projector.height,
        )
        arrays: dict[str, Any] = {
            "grid_uv": self.grid_uv.astype(np.float32),
            "image_xy": self.image_xy.astype(np.float32),
            "K": self.projector.K,
            "meta": np.array(json.dumps(meta)),
        }
        if self.depth is not None:
            arrays["depth"] = self.depth.astype(np.float32)
        if self.map_xy is not None:
            arrays["map_xy"] = self.map_xy.astype(np.float32)
        atomic_savez(Path(path), **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Warp:
        """Read a warp file written by :meth:`save`."""
        arrays = load_npz(path, "warp file", ("grid_uv", "image_xy", "K", "meta"))
        try:
            meta = json.loads(str(arrays["meta"]))
            grid_uv = arrays["grid_uv"].astype(np.float64)
            image_xy = arrays["image_xy"].astype(np.float64)
            K = arrays["K"].astype(np.float64)
            depth = arrays["depth"].astype(np.float64) if "depth" in arrays else None
            map_xy = arrays["map_xy"].astype(np.float32) if "map_xy" in arrays else None
        except (ValueError, TypeError) as e:
            raise InputError(f"cannot read warp file {path}: {e}") from None
        if not isinstance(meta, dict):
            raise InputError(f"warp file {path}: meta must be a JSON object")
        if grid_uv.shape != image_xy.shape or grid_uv.ndim != 3 or grid_uv.shape[2] != 2:
            raise InputError(f"warp file {path}: grid_uv and image_xy must both be (R, C, 2)")
        try:
            projector = Projector(K, int(meta["width"]), int(meta["height"]))
            size = (int(meta["content_width"]), int(meta["content_height"]))
        except (KeyError, TypeError, ValueError):
            raise InputError(f"warp file {path}: meta lacks the frame or content size") from None
        return cls(grid_uv, image_xy, size, projector, meta, map_xy, depth)
