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

from adaproj_edge import checks
from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import atomic_savez, load_npz
from adaproj_edge.geometry.calibration import field_errors
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
        """Read a warp file written by :meth:`save`.

        Every array and field is checked (shapes, finiteness, the grid a rising tensor
        grid over the frame, sizes in range), so a damaged or foreign file is an
        :class:`InputError` here, never a failure later in the renderer.
        """
        arrays = load_npz(path, "warp file", ("grid_uv", "image_xy", "K", "meta"))
        with field_errors(f"warp file {path}"):
            meta = json.loads(str(arrays["meta"]))
            if not isinstance(meta, dict):
                raise InputError("meta must be a JSON object")
            projector = Projector(
                _array(arrays, "K", np.float64),
                checks.integer(meta.get("width"), "meta width", 2, MAX_FRAME),
                checks.integer(meta.get("height"), "meta height", 2, MAX_FRAME),
            )
            size = (
                checks.integer(meta.get("content_width"), "meta content_width", 1, MAX_FRAME),
                checks.integer(meta.get("content_height"), "meta content_height", 1, MAX_FRAME),
            )
            grid_uv = _array(arrays, "grid_uv", np.float64)
            _check_grid(grid_uv, projector)
            rows, cols = grid_uv.shape[:2]
            image_xy = _array(arrays, "image_xy", np.float64, (rows, cols, 2), nan=True)
            depth = None
            if "depth" in arrays:
                depth = _array(arrays, "depth", np.float64, (rows, cols), nan=True)
            map_xy = None
            if "map_xy" in arrays:
                frame = (projector.height, projector.width, 2)
                map_xy = _array(arrays, "map_xy", np.float32, frame, nan=True)
        return cls(grid_uv, image_xy, size, projector, meta, map_xy, depth)


MAX_FRAME = 16384
"""Pixels a side of a projector frame or a content item, at most, in a warp file."""


def _array(
    arrays: dict[str, NDArray[Any]],
    key: str,
    dtype: type[np.floating[Any]],
    shape: tuple[int, ...] | None = None,
    *,
    nan: bool = False,
) -> NDArray[Any]:
    """``arrays[key]`` as ``dtype``, of ``shape`` when given, finite (or NaN with ``nan``)."""
    a = arrays[key]
    if a.dtype.kind not in "fiu":
        raise InputError(f"{key} must hold numbers, not {a.dtype}")
    a = a.astype(dtype)
    if shape is not None and a.shape != shape:
        raise InputError(f"{key} must be {shape}, not {a.shape}")
    bad = np.isinf(a) if nan else ~np.isfinite(a)
    if bad.any() or (nan and np.nanmax(np.abs(a), initial=0.0) > 1e9):
        raise InputError(f"{key} holds values that are not finite numbers")
    return a


def _check_grid(grid_uv: FloatArray, projector: Projector) -> None:
    """Refuse a ``grid_uv`` that is not a rising tensor grid of at least 2x2 vertices
    from the frame's first pixel to its last."""
    if grid_uv.ndim != 3 or grid_uv.shape[2] != 2:
        raise InputError(f"grid_uv must be (R, C, 2), not {grid_uv.shape}")
    rows, cols = grid_uv.shape[:2]
    if not (2 <= rows <= MAX_GRID + 1 and 2 <= cols <= MAX_GRID + 1):
        raise InputError(
            f"grid_uv has {rows}x{cols} vertices; 2x2 .. {MAX_GRID + 1}x{MAX_GRID + 1} expected"
        )
    xs, ys = grid_uv[0, :, 0], grid_uv[:, 0, 1]
    tensor = np.array_equal(grid_uv[..., 0], np.broadcast_to(xs, (rows, cols))) and (
        np.array_equal(grid_uv[..., 1], np.broadcast_to(ys[:, None], (rows, cols)))
    )
    rising = bool(np.all(np.diff(xs) > 0) and np.all(np.diff(ys) > 0))
    spans = (xs[0], xs[-1], ys[0], ys[-1]) == (0, projector.width - 1, 0, projector.height - 1)
    if not (tensor and rising and spans):
        raise InputError(
            "grid_uv must be a rising grid of vertices from the frame's first pixel to "
            f"its last ({projector.width}x{projector.height})"
        )
