"""The surface as the warp sees it: grid vertices, their 3D points, usable triangles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from numpy.typing import NDArray

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.creases import unfold_creases
from adaproj_edge.geometry.projector import FloatArray
from adaproj_edge.geometry.rectangle import boundary_edges
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import conformal_coords, grid_triangles, triangle_normals
from adaproj_edge.warp.mesh import Grid

IntArray = NDArray[np.intp]

MIN_TRIANGLES = 8


@dataclass(frozen=True)
class MeshGeometry:
    """The part of the grid the warp solves for.

    Attributes
    ----------
    grid : Grid
    grid_uv : (R, C, 2) vertex pixel positions.
    points : (R*C, 3) vertex points in frame P (NaN where no surface).
    used : (R*C,) bool, vertices of the kept triangles.
    index : (R*C,) int, compact index of used vertices (-1 elsewhere).
    verts : (n,) grid index of each compact vertex.
    tris : (T, 3) compact vertex indices of the kept triangles.
    coords : (T, 3, 2) conformal (alpha, beta) of each triangle role.
    edges : (E, 2) undirected compact edges of the kept triangles.
    lengths : (E,) edge lengths on the surface (metres).
    boundary : (B, 2) edges on the region's boundary (holes included).
    """

    grid: Grid
    grid_uv: FloatArray
    points: FloatArray
    used: NDArray[np.bool_]
    index: IntArray
    verts: IntArray
    tris: IntArray
    coords: FloatArray
    edges: IntArray
    lengths: FloatArray
    boundary: IntArray

    @property
    def n(self) -> int:
        return int(self.verts.size)

    @property
    def p(self) -> FloatArray:
        """(n, 3) points of the compact vertices."""
        return self.points[self.verts]

    @property
    def uv(self) -> FloatArray:
        """(n, 2) pixel positions of the compact vertices."""
        return self.grid_uv.reshape(-1, 2)[self.verts]

    @classmethod
    def build(cls, surface: Surface, grid: Grid) -> MeshGeometry:
        """Sample the surface at the grid and keep its largest connected piece."""
        grid_uv = grid.vertices(surface.projector)
        pts = surface.points_at(grid_uv).reshape(-1, 3)
        all_tris = grid_triangles(grid.rows, grid.cols)
        ok = np.all(np.isfinite(pts[all_tris]).all(axis=2), axis=1)
        tri_pts = pts[all_tris[ok]]
        normals = triangle_normals(tri_pts)
        facing = np.all(np.isfinite(normals), axis=1)
        # A triangle must face the projector (it was seen) and not be degenerate.
        centroid = tri_pts.mean(axis=1)
        facing &= np.sum(normals * centroid, axis=1) < 0
        cand = all_tris[ok][facing]
        if cand.shape[0] < MIN_TRIANGLES:
            raise WarpError(
                f"only {cand.shape[0]} grid triangles meet the surface; point the projector "
                "at the surface or use a finer grid"
            )
        cand = _largest_component(cand, pts.shape[0])
        used = np.zeros(pts.shape[0], dtype=bool)
        used[cand.ravel()] = True
        index = np.full(pts.shape[0], -1, dtype=np.intp)
        verts = np.flatnonzero(used)
        index[verts] = np.arange(verts.size)
        tris = index[cand]
        e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
        e, inverse = np.unique(np.sort(e, axis=1), axis=0, return_inverse=True)
        tri_pts = unfold_creases(surface, grid_uv.reshape(-1, 2)[cand], cand, pts).points
        coords = conformal_coords(tri_pts)
        # edge lengths as the (unfolded) triangles have them; an edge shared by two
        # triangles gets the mean of their two values
        tri_len = np.linalg.norm(tri_pts - np.roll(tri_pts, -1, axis=1), axis=2)  # edge k: k->k+1
        sums = np.bincount(inverse, weights=tri_len.T.ravel(), minlength=e.shape[0])
        counts = np.bincount(inverse, minlength=e.shape[0])
        lengths = sums / counts
        return cls(
            grid, grid_uv, pts, used, index, verts, tris, coords, e, lengths, boundary_edges(tris)
        )


def _largest_component(tris: IntArray, n_vertices: int) -> IntArray:
    """The triangles of the largest vertex-connected component (by triangle count)."""
    t = tris.shape[0]
    rows = np.repeat(np.arange(t), 3)
    inc = scipy.sparse.csr_matrix((np.ones(3 * t), (rows, tris.ravel())), shape=(t, n_vertices))
    adj = inc @ inc.T
    ncomp, labels = scipy.sparse.csgraph.connected_components(adj, directed=False)
    if ncomp == 1:
        return tris
    counts = np.bincount(labels)
    keep: IntArray = tris[labels == int(np.argmax(counts))]
    return keep
