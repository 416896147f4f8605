"""Where a grid samples the surface: its vertices and its triangles' crease probes.

:meth:`~adaproj_edge.warp.mesh.MeshGeometry.build` samples the surface at the grid's
vertices and at the :func:`~adaproj_edge.geometry.creases.crease_probes` of every
triangle. A probe on a side is shared by the two triangles of that side, so each is
sampled once (:func:`probes`, indexed per triangle by :func:`probe_index`). The base
grid's sampling (its rays and the lattice's bilinear
:class:`~adaproj_edge.geometry.surface.Stencil`) depends on the grid, the projector and
the lattice's shape alone: :func:`base_sampling` makes it once for them, and only the
gather of the depths is done per surface.
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.surface import Stencil, Surface
from adaproj_edge.warp.warpmap import Grid


@dataclass(frozen=True)
class Sampling:
    """Where a grid samples the surface (its vertices, then :func:`probes`): their rays
    and the lattice's :class:`~adaproj_edge.geometry.surface.Stencil` there."""

    grid_uv: FloatArray
    rays: FloatArray
    stencil: Stencil

    @classmethod
    def of(cls, surface: Surface, grid_uv: FloatArray) -> Sampling:
        """The sampling of ``surface``'s lattice by the grid of vertices ``grid_uv``."""
        uv = np.concatenate([grid_uv.reshape(-1, 2), probes(grid_uv)])
        return cls(grid_uv, surface.projector.rays(uv), surface.stencil(uv))

    def points(self, surface: Surface) -> FloatArray:
        """``surface.points_at`` the sampled pixels (M, 3), the same values."""
        out: FloatArray = self.rays * self.stencil.depth(surface.points)[:, None]
        return out


SAMPLINGS: OrderedDict[tuple[Any, ...], Sampling] = OrderedDict()  # the last few made


def base_sampling(grid: Grid, surface: Surface) -> Sampling:
    """The :class:`Sampling` of :meth:`Grid.vertices`: it depends on the grid, the
    projector and the lattice's shape alone, so it is made once for them (read-only)."""
    p = surface.projector
    key = (grid, p.width, p.height, p.K.tobytes(), surface.shape)
    out = SAMPLINGS.get(key)
    if out is None:
        grid_uv = grid.vertices(p)
        out = Sampling.of(surface, grid_uv)
        for a in (grid_uv, out.rays, out.stencil.at, out.stencil.weights):
            a.flags.writeable = False
        SAMPLINGS[key] = out
        while len(SAMPLINGS) > 8:
            SAMPLINGS.popitem(last=False)
    else:
        SAMPLINGS.move_to_end(key)
    return out


def probes(grid_uv: FloatArray) -> FloatArray:
    """Where the grid's triangles are probed for creases, each point once (P, 2).

    The midpoints of the horizontal, vertical and diagonal sides, then each cell's two
    centroids; :func:`probe_index` says which are each triangle's
    :func:`~adaproj_edge.geometry.creases.crease_probes` (a side's midpoint is the
    same whichever triangle adds its ends; a centroid adds them in its corners' order).
    """
    a, b = grid_uv[:-1, :-1], grid_uv[:-1, 1:]  # a cell's corners: a b
    d, e = grid_uv[1:, :-1], grid_uv[1:, 1:]  #                      d e
    return np.concatenate(
        [
            ((grid_uv[:, :-1] + grid_uv[:, 1:]) / 2).reshape(-1, 2),
            ((grid_uv[:-1] + grid_uv[1:]) / 2).reshape(-1, 2),
            ((a + e) / 2).reshape(-1, 2),
            ((a + b + e) / 3).reshape(-1, 2),  # triangle (a, b, e)
            ((a + e + d) / 3).reshape(-1, 2),  # triangle (a, e, d)
        ]
    )


@functools.lru_cache(maxsize=16)
def probe_index(rows: int, cols: int) -> IntArray:
    """Index (4, T) into :func:`probes` of probe k of :func:`grid_triangles`' triangle
    t (read-only: made once per grid size)."""
    r, c = np.mgrid[0:rows, 0:cols]
    horizontal = r * cols + c  # the side from (r, c) to (r, c + 1)
    vertical = (rows + 1) * cols + r * (cols + 1) + c  # from (r, c) to (r + 1, c)
    diagonal = (rows + 1) * cols + rows * (cols + 1) + r * cols + c
    centroid = diagonal + rows * cols
    index = np.empty((4, rows * cols, 2), dtype=np.intp)
    # (a, b, e): sides a-b, b-e, e-a; (a, e, d): a-e, e-d, d-a
    index[:, :, 0] = np.stack([horizontal, vertical + 1, diagonal, centroid]).reshape(4, -1)
    index[:, :, 1] = np.stack(
        [diagonal, horizontal + cols, vertical, centroid + rows * cols]
    ).reshape(4, -1)
    out = index.reshape(4, -1)
    out.flags.writeable = False
    return out
