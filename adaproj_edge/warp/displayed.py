"""What the full-grid display shows of a warp, sampled: the guard's measure there.

The per-pixel display (:func:`~adaproj_edge.render.maps.map_from_warp` with the surface)
maps each pixel through its own surface point, projected onto its mesh triangle's plane
and blended with the neighbour's near an edge (:mod:`adaproj_edge.render.seams`). Where
the surface bends within a cell (relief finer than the grid) this differs from the mesh's
own piecewise map by a few percent in angle error, enough to turn the guard's decision
(issue 13: ``bumps`` with a quarter subject showed 1.02x the conformal warp's angle
error while the mesh said 0.96x). :class:`DisplaySamples` holds the display's weights at
every :data:`STEP`-th pixel (they depend on the mesh and the surface alone, not on where
the vertices go) and scores any positions of the mesh the way the display shows them:
per small triangle of the sample lattice, the Jacobian content -> surface, its angle
error and log size, counted where its content is salient. The guard builds it only for
a close call (:data:`~adaproj_edge.warp.guard.SURE`) or a crease through the subject:
about 30 ms CPU for the bumps' or the cylinder on a floor's refined grids (81x57,
118x49).

At a crease the map has a kink: a lattice triangle across it does not count. Its
samples on either side, in the creased mesh triangle too, do: the display unfolds them
onto their side's plane, an isometry of the surface there, so what they show is the
display's own distortion (on a floor seen grazing it is most of the subject's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.creases import CREASE_COS, Unfolding
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import triangle_normals
from adaproj_edge.render.maps import PixelLayout
from adaproj_edge.render.seams import grid_unfolding, surface_weights
from adaproj_edge.warp.mesh import MeshGeometry

STEP = 8  # sample every STEP-th pixel along x and y (the seams' band is 12 px wide)
# a triangle whose 3D corners differ from its unfolded shape by this much (relative) has
# a crease through it
UNFOLDED = 1e-6


@dataclass(frozen=True)
class DisplaySamples:
    """The display's weights at a lattice of sample pixels, and the lattice's triangles.

    Attributes
    ----------
    corners : (K, N) compact mesh vertex indices of each sample's weights.
    weights : (K, N) the weights (0 where unused).
    tris : (M, 3) sample indices of the lattice triangles that count.
    gram : (3, M) the entries 00, 01 and 11 of ``dX^T dX`` of each lattice triangle (its
        edges on the surface).
    """

    corners: NDArray[np.intp]
    weights: FloatArray
    tris: NDArray[np.intp]
    gram: FloatArray

    @classmethod
    def of(cls, mesh: MeshGeometry, surface: Surface) -> DisplaySamples:
        """The samples of ``mesh`` built from ``surface``; memoised on ``mesh`` (the
        first surface given counts: the mesh was built from it)."""
        return mesh.remember("display_samples", lambda: cls.build(mesh, surface))

    @classmethod
    def build(cls, mesh: MeshGeometry, surface: Surface, step: int = STEP) -> DisplaySamples:
        """The samples of ``mesh`` (of ``surface``) at every ``step``-th pixel."""
        proj = surface.projector
        ys = np.arange(0, proj.height, step, dtype=np.float64)
        xs = np.arange(0, proj.width, step, dtype=np.float64)
        uv = np.stack(np.meshgrid(xs, ys), axis=-1)
        points = surface.points_at(uv)
        depth = mesh.points[:, 2].copy()
        depth[~mesh.used] = np.nan
        depth = depth.reshape(mesh.grid_uv.shape[:2])
        layout = PixelLayout.build(mesh.grid_uv, proj, step)
        layout = layout.onto_mesh(mesh.grid_uv, proj, depth, step)
        bary = np.stack([layout.l0, layout.l1, layout.l2])
        folded = _folded(mesh)
        # the creases unfolded once: for the weights and to find the samples' sides (the
        # mesh's own when it is the whole grid's: made from the same corners and probes;
        # the weights need it with or without a creased mesh triangle, and making it
        # again was most of this build on a bumpy wall)
        unfolding: Unfolding | None = mesh.memo.get("grid unfolding")
        if unfolding is None and folded.any():
            unfolding = grid_unfolding(mesh.grid_uv, depth, proj, surface)
        grid_corners, w = surface_weights(
            mesh.grid_uv, depth, proj, surface, layout.tri, bary, points, unfolding
        )
        # the display's grid vertices as the mesh's compact vertices
        compact = mesh.index[grid_corners.reshape(grid_corners.shape[0], -1)]
        w = w.reshape(w.shape[0], -1)
        w = np.where(compact >= 0, w, np.nan)  # a corner without surface: no sample
        shown: NDArray[np.bool_] = np.asarray(
            np.isfinite(w).all(axis=0) & np.isfinite(points.reshape(-1, 3)).all(axis=1)
        )
        rows, cols = layout.tri.shape
        idx = np.arange(rows * cols).reshape(rows, cols)
        a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
        tris = np.concatenate(
            [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
        )
        tris = tris[shown[tris].all(axis=1)]
        if unfolding is not None and folded.any():
            # the map has a kink at a crease: a lattice triangle across it does not count
            across = _across_crease(unfolding, layout.tri, points, tris, folded)
            tris = tris[~across]
        return cls(np.where(compact >= 0, compact, 0), np.nan_to_num(w), tris, _gram(points, tris))

    def content(self, content_xy: FloatArray) -> FloatArray:
        """Content positions (N, 2) of the samples for vertex positions (n, 2)."""
        return np.stack(self._content(content_xy), axis=1)

    def _content(self, content_xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`content` as its x and y (N,) (a coordinate at a time: the same sums,
        in the same order, at a quarter of the cost of gathering rows)."""
        cx, cy = np.ascontiguousarray(content_xy[:, 0]), np.ascontiguousarray(content_xy[:, 1])
        w, k = self.weights, self.corners
        x, y = w[0] * cx[k[0]], w[0] * cy[k[0]]
        for j in range(1, w.shape[0]):
            x += w[j] * cx[k[j]]
            y += w[j] * cy[k[j]]
        return x, y

    def distortion(
        self, content_xy: FloatArray, content_map: ContentMap
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Angle error, log size and salient weight (M,) of the lattice triangles for
        vertex positions ``content_xy`` (n, 2); folded triangles weigh 0, and the
        measures of a triangle of weight 0 are 0 (not computed)."""
        x, y = self._content(content_xy)
        t0, t1, t2 = self.tris[:, 0], self.tris[:, 1], self.tris[:, 2]
        x0, x1, x2, y0, y1, y2 = x[t0], x[t1], x[t2], y[t0], y[t1], y[t2]
        a, c_, b, d = x1 - x0, y1 - y0, x2 - x0, y2 - y0  # dq = [[a, b], [c_, d]]
        det = a * d - b * c_
        good = det > 0
        centroids = np.stack([(x0 + x1 + x2) / 3.0, (y0 + y1 + y2) / 3.0], axis=1)
        weight = content_map.weights(centroids).astype(np.float64) * good
        # the Jacobians only where they count (the subject is a part of the frame): a
        # triangle of weight 0 adds a 0 to the weighted sums either way
        angle, log_size = np.zeros(det.size), np.zeros(det.size)
        k = np.flatnonzero(weight)
        a, b, c_, d, det = a[k], b[k], c_[k], d[k], det[k]
        # J = dX dq^-1; J^T J = dq^-T (dX^T dX) dq^-1, with dq^-1 = [[d, -b], [-c_, a]] / det
        m00, m01, m11 = self.gram[:, k]
        g00 = m00 * d * d - 2 * m01 * d * c_ + m11 * c_ * c_
        g11 = m00 * b * b - 2 * m01 * a * b + m11 * a * a
        tr = (g00 + g11) / (det * det)
        dg = np.maximum((m00 * m11 - m01 * m01) / (det * det), 1e-300)  # det(J^T J)
        disc = np.sqrt(np.maximum(0.25 * tr * tr - dg, 0.0))
        l1 = 0.5 * tr + disc
        l2 = np.maximum(0.5 * tr - disc, 1e-300)
        angle[k] = np.sqrt(l1 / l2) - 1.0
        log_size[k] = 0.25 * np.log(dg)
        return angle, log_size, weight


def _gram(points: FloatArray, tris: NDArray[np.intp]) -> FloatArray:
    """The entries 00, 01, 11 (3, M) of ``dX^T dX`` of the triangles ``tris`` (M, 3) of
    ``points`` (..., 3): their edges from corner 0 dotted, a coordinate at a time (the
    sums of ``einsum("tca,tcb->tab")`` in its order, at an eighth of its cost)."""
    x = points.reshape(-1, 3).T
    i0, i1, i2 = tris[:, 0], tris[:, 1], tris[:, 2]
    e1 = [x[c][i1] - x[c][i0] for c in range(3)]
    e2 = [x[c][i2] - x[c][i0] for c in range(3)]
    out: FloatArray = np.stack(
        [
            e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2],
            e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2],
            e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2],
        ]
    )
    return out


def creased(mesh: MeshGeometry) -> NDArray[np.bool_]:
    """Whether a crease runs through each mesh triangle (T,): its 3D corners differ from
    its unfolded shape by more than :data:`UNFOLDED` (memoised on ``mesh``)."""

    def make() -> NDArray[np.bool_]:
        out = np.zeros(mesh.tris.shape[0], dtype=bool)
        # only an unfolded triangle's shape can differ from its corners (the others'
        # shapes are made from them): the rest is not looked at
        f = np.flatnonzero(mesh.folded)
        if f.size:
            shapes, corners3 = mesh.shapes[f], mesh.p[mesh.tris[f]]
            shape_len = np.linalg.norm(shapes - np.roll(shapes, -1, axis=1), axis=2)
            tri_len = np.linalg.norm(corners3 - np.roll(corners3, -1, axis=1), axis=2)
            out[f] = np.any(np.abs(tri_len - shape_len) > UNFOLDED * shape_len, axis=1)
        return out

    return mesh.remember("creased", make)


def _folded(mesh: MeshGeometry) -> NDArray[np.bool_]:
    """:func:`creased` per grid triangle (``grid_triangles`` order; False without one)."""
    out = np.zeros(2 * mesh.grid.rows * mesh.grid.cols, dtype=bool)
    out[mesh.topology.rows] = creased(mesh)
    return out


def _across_crease(
    unfolding: Unfolding,
    tri: NDArray[np.intp],
    points: FloatArray,
    tris: NDArray[np.intp],
    folded: NDArray[np.bool_],
) -> NDArray[np.bool_]:
    """Which lattice triangles ``tris`` (M, 3) lie across a crease: one of their samples
    is in a grid triangle ``folded`` (per grid triangle) and two of them lie on planes
    further apart than a crease's (``CREASE_COS``). A sample's plane is its grid
    triangle's ``tri``, or in a folded one the plane of the crease's side it lies nearer
    to (``unfolding``: the grid triangles', as the display unfolds them).

    Samples within a folded triangle on one side of its crease still count: the display
    maps them through their side's plane, which the surface leaves only by an isometry
    (the tests' scorer leaves out only its triangles across the crease, too)."""
    t = tri.reshape(-1)
    x = points.reshape(-1, 3)
    normal = triangle_normals(unfolding.points)[t]
    f = unfolding.folded[t]
    tf, xf = t[f], x[f]
    da = np.abs(np.sum((xf - unfolding.point_a[tf]) * unfolding.normal_a[tf], axis=1))
    db = np.abs(np.sum((xf - unfolding.point_b[tf]) * unfolding.normal_b[tf], axis=1))
    normal[f] = np.where((db < da)[:, None], unfolding.normal_b[tf], unfolding.normal_a[tf])
    # (a coordinate at a time: the sums of np.sum(..., axis=1) in its order, at a
    # fraction of the cost of the (M, 3, 3) gather)
    nt = normal.T
    n = [[nt[j][tris[:, i]] for j in range(3)] for i in range(3)]  # corner i, coordinate j
    cos = np.minimum.reduce(
        [
            np.abs(
                n[i][0] * n[(i + 1) % 3][0]
                + n[i][1] * n[(i + 1) % 3][1]
                + n[i][2] * n[(i + 1) % 3][2]
            )
            for i in range(3)
        ]
    )
    with np.errstate(invalid="ignore"):
        apart = ~(cos >= CREASE_COS)  # NaN (no plane): apart too
    out: NDArray[np.bool_] = (folded | unfolding.folded)[t][tris].any(axis=1) & apart
    return out
