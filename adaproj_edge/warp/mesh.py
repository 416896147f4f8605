"""The surface as the warp sees it: grid vertices, their 3D points, usable triangles."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, TypeVar

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.creases import ruled_triangles, snapped_walls, unfold_measured
from adaproj_edge.geometry.developed import developed_lengths
from adaproj_edge.geometry.planes import on_planes, plane_equations
from adaproj_edge.geometry.ruled_crease import pixel_spans
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import (
    grid_triangles,
    planes_first,
    shapes_first,
    shapes_from_sides,
    triangle_shapes,
    unique_edges,
)
from adaproj_edge.warp.sampling import Sampling, base_sampling, probe_index
from adaproj_edge.warp.warpmap import Grid

T = TypeVar("T")

MIN_TRIANGLES = 8
# a side measured along the surface this much longer than its chord crosses a jump
# (a corrugation's bends lengthen a side by up to 3 % at the adaptive grid's cells)
STRETCH = 0.05


@dataclass
class Topology:
    """Which grid triangles the warp solves for, and everything that follows from that
    alone: compact vertex numbering, edges, boundary, and (memoised) solver structures.

    It depends on the surface only through which triangles are usable, so a device that
    re-estimates the surface of the same scene keeps meeting the same topology.
    """

    cand: IntArray  # (T, 3) grid vertex indices of the kept triangles
    rows: IntArray  # (T,) their indices among all grid triangles
    used: NDArray[np.bool_]
    index: IntArray
    verts: IntArray
    tris: IntArray
    edges: IntArray
    inverse: IntArray  # edge index of each triangle side, sides ordered (k -> k+1) by k
    boundary: IntArray
    memo: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_triangles(
        cls, cand: IntArray, rows: IntArray, n_vertices: int, grid_cols: int | None = None
    ) -> Topology:
        """The topology of triangles ``cand`` (T, 3) (grid vertex indices; ``rows`` (T,)
        their indices among all grid triangles) of a grid of ``n_vertices``.

        ``grid_cols``: the triangles are those of :func:`grid_triangles` for a grid of
        that many columns, whose sides are known without sorting them."""
        used = np.zeros(n_vertices, dtype=bool)
        used[cand.ravel()] = True
        index = np.full(n_vertices, -1, dtype=np.intp)
        verts = np.flatnonzero(used)
        index[verts] = np.arange(verts.size)
        tris = index[cand]
        if grid_cols is None:
            e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
            edges, inverse, counts = unique_edges(e, max(int(verts.size), 1))
        else:
            edges, inverse, counts = _grid_sides(cand, index, grid_cols, n_vertices)
        return cls(cand, rows, used, index, verts, tris, edges, inverse, edges[counts == 1])

    def remember(self, name: str, make: Callable[[], T]) -> T:
        """``make()`` once per topology (solver structures)."""
        if name not in self.memo:
            self.memo[name] = make()
        out: T = self.memo[name]
        return out


class WarpCache:
    """Topologies and meshes seen recently, so repeated warps of a scene skip the set-up
    work.

    Owned by the caller (the device keeps one); :func:`MeshGeometry.build` without one
    starts from scratch. Topologies are keyed by which grid triangles meet the surface;
    whole meshes (:meth:`mesh`: the adaptive mesh with its crease unfolding, and what is
    memoised on it, the guard's display samples among them) by the surface's own
    points, so a surface measured again, or from a moved device, is a new key.
    """

    def __init__(self, size: int = 8, meshes: int = 4) -> None:
        self.size = size
        self.mesh_size = meshes
        self._items: OrderedDict[bytes, Topology] = OrderedDict()
        self._meshes: OrderedDict[bytes, Any] = OrderedDict()
        self.hits = 0
        self.misses = 0
        self.mesh_hits = 0
        self.mesh_misses = 0

    def mesh(self, key: bytes, make: Callable[[], T]) -> T:
        """The cached mesh (or whatever ``make`` gives) under ``key``, made by ``make()``
        and kept (the least recently used one going beyond ``mesh_size``) when it is not
        there."""
        if key in self._meshes:
            self._meshes.move_to_end(key)
            self.mesh_hits += 1
            out: T = self._meshes[key]
            return out
        self.mesh_misses += 1
        made = make()
        if self.mesh_size > 0:
            self._meshes[key] = made
            while len(self._meshes) > self.mesh_size:
                self._meshes.popitem(last=False)
        return made

    def topology(self, key: bytes, make: Callable[[], Topology]) -> Topology:
        """The cached topology under ``key``, made by ``make()`` (and kept, the least recently
        used one going beyond ``size``) when it is not there."""
        if key in self._items:
            self._items.move_to_end(key)
            self.hits += 1
            return self._items[key]
        self.misses += 1
        topo = make()
        self._items[key] = topo
        while len(self._items) > self.size:
            self._items.popitem(last=False)
        return topo


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
    shapes : (T, 3, 2) each (unfolded) surface triangle in a 2D frame of its own plane
        (metres), oriented as the content is (y down).
    curved : (T,) bool, the triangles a curved crease runs through (their unfolding is
        only approximate: :mod:`~adaproj_edge.warp.adaptive` refines there).
    planar : (T,) bool, the triangles whose corners all lie on one of the planes the
        surface was snapped to (:func:`~adaproj_edge.geometry.planes.snap_planes`, listed
        in its meta): the warp keeps them nearly undistorted.
    folded : (T,) bool, the triangles unfolded about a crease (straight or curved); the
        others' shapes are their own corners' (on a mesh built ``along`` the surface,
        their sides' developed lengths').
    ruled : (T,) bool, those of them unfolded about a straight crease between curved
        sides (:mod:`~adaproj_edge.geometry.ruled_crease`).
    memo : what callers derive from this geometry alone, made once (:meth:`remember`;
        the upright angle's factors, the display's samples of
        :mod:`~adaproj_edge.warp.displayed`); where every grid triangle was kept and
        looked at for every kind of crease, ``"grid unfolding"``: the crease unfolding
        of the grid's triangles (:func:`~adaproj_edge.render.seams.grid_unfolding`).
    along : the chords each side was measured in on the surface's development (0: the
        shapes are their corners'; :meth:`build`).
    """

    grid: Grid
    grid_uv: FloatArray
    points: FloatArray
    topology: Topology
    coords: FloatArray
    lengths: FloatArray
    shapes: FloatArray
    curved: NDArray[np.bool_]
    folded: NDArray[np.bool_]
    ruled: NDArray[np.bool_]
    planar: NDArray[np.bool_]
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    along: int = 0

    def remember(self, name: str, make: Callable[[], T]) -> T:
        """``make()`` once per mesh (quantities of its geometry, not of a solve)."""
        if name not in self.memo:
            self.memo[name] = make()
        out: T = self.memo[name]
        return out

    @property
    def used(self) -> NDArray[np.bool_]:
        """(R*C,) bool, vertices of the kept triangles."""
        return self.topology.used

    @property
    def index(self) -> IntArray:
        """(R*C,) int, compact index of used vertices (-1 elsewhere)."""
        return self.topology.index

    @property
    def verts(self) -> IntArray:
        """(n,) grid index of each compact vertex."""
        return self.topology.verts

    @property
    def tris(self) -> IntArray:
        """(T, 3) compact vertex indices of the kept triangles."""
        return self.topology.tris

    @property
    def edges(self) -> IntArray:
        """(E, 2) undirected compact edges of the kept triangles."""
        return self.topology.edges

    @property
    def boundary(self) -> IntArray:
        """(B, 2) edges on the region's boundary (holes included)."""
        return self.topology.boundary

    @property
    def n(self) -> int:
        """Number of compact vertices."""
        return int(self.verts.size)

    @property
    def p(self) -> FloatArray:
        """(n, 3) points of the compact vertices."""
        return self.points[self.verts]

    @property
    def uv(self) -> FloatArray:
        """(n, 2) pixel positions of the compact vertices."""
        return self.grid_uv.reshape(-1, 2)[self.verts]

    def without_planes(self) -> MeshGeometry:
        """The mesh with no triangle :attr:`planar` (the solves' uniform weights)."""
        return replace(self, planar=np.zeros_like(self.planar), memo={})

    @property
    def planar_edges(self) -> NDArray[np.bool_]:
        """(E,) bool, the edges of :attr:`planar` triangles."""

        def make() -> NDArray[np.bool_]:
            out = np.zeros(self.edges.shape[0], dtype=bool)
            out[self.topology.inverse.reshape(3, -1)[:, self.planar].ravel()] = True
            return out

        return self.remember("planar edges", make)

    @property
    def curved_cells(self) -> IntArray:
        """Indices (row-major) of the grid cells a curved crease runs through."""
        out: IntArray = np.unique(self.topology.rows[self.curved] // 2)
        return out

    @property
    def pixel_areas(self) -> FloatArray:
        """(T,) area of each triangle in the projector frame (pixels)."""
        uv = self.uv[self.tris]
        d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        out: FloatArray = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
        return out

    @classmethod
    def build(
        cls,
        surface: Surface,
        grid: Grid,
        cache: WarpCache | None = None,
        grid_uv: FloatArray | None = None,
        may_rule: NDArray[np.bool_] | None = None,
        drop: NDArray[np.bool_] | None = None,
        along: int = 0,
    ) -> MeshGeometry:
        """Sample the surface at the grid and keep its largest edge-connected piece.

        ``grid_uv`` (rows + 1, cols + 1, 2) places the vertices elsewhere than
        :meth:`Grid.vertices` (a coarse grid on a subset of a fine grid's vertices).
        ``may_rule`` (2 rows cols,) bool, per grid triangle: where a straight crease
        between curved sides may be looked for (None: everywhere; see
        :func:`~adaproj_edge.geometry.creases.unfold_measured`). ``drop`` (2 rows
        cols,) bool, per grid triangle: triangles left out although they meet the
        surface (a repair's, :mod:`~adaproj_edge.warp.fallback`). ``along`` > 0: the
        triangles not unfolded about a crease take their shapes from their sides'
        lengths on the surface's development, each side measured in that many chords
        (:func:`~adaproj_edge.geometry.developed.developed_lengths`), not from their
        corners (a refined mesh's, :mod:`~adaproj_edge.warp.adaptive`)."""
        if grid_uv is None:
            sampling = base_sampling(grid, surface)
            grid_uv = sampling.grid_uv
        elif grid_uv.shape != (grid.rows + 1, grid.cols + 1, 2):
            raise ValueError(f"grid_uv {grid_uv.shape} does not fit grid {grid}")
        else:
            sampling = Sampling.of(surface, grid_uv)
        all_tris = grid_triangles(grid.rows, grid.cols)
        uv = grid_uv.reshape(-1, 2)
        # the surface at the vertices and at the crease probes of every triangle, at once
        sampled = sampling.points(surface)
        pts = sampled[: uv.shape[0]]
        # each triangle's probes (3, 4, T), component-first
        probes = np.take(sampled[uv.shape[0] :].T, probe_index(grid.rows, grid.cols), axis=1)
        # every grid triangle's corners, normal and area (NaN where not all seen)
        corners = np.take(pts.T, all_tris.T, axis=1)  # (3, 3, T) component-first
        normals, area2 = planes_first(corners)
        # A triangle must face the projector (it was seen) and not be degenerate.
        centre = (corners[:, 0] + corners[:, 1] + corners[:, 2]) / 3
        with np.errstate(invalid="ignore"):
            keep = (
                (normals[0] * centre[0] + normals[1] * centre[1] + normals[2] * centre[2] < 0)
                & np.isfinite(normals).all(axis=0)
                & np.isfinite(corners).all(axis=(0, 1))
            )
        if drop is not None:
            keep &= ~drop
        if keep.sum() < MIN_TRIANGLES:
            raise WarpError(
                f"only {int(keep.sum())} grid triangles meet the surface; point the projector "
                "at the surface or use a finer grid"
            )

        def make() -> Topology:
            rows = _largest_component(all_tris, np.flatnonzero(keep), grid.cols)
            return Topology.from_triangles(all_tris[rows], rows, pts.shape[0], grid.cols)

        key = f"{grid.cols}x{grid.rows}:".encode() + np.packbits(keep).tobytes()
        topo = make() if cache is None else cache.topology(key, make)
        rows = topo.rows
        # (on sensed depth, only with two snapped planes or more: as the display's
        # unfolding of the grid looks, render.seams.grid_unfolding)
        sides_known = ruled_triangles(surface, pts, all_tris)
        rule = may_rule if sides_known is None else sides_known
        if may_rule is not None and sides_known is not None:
            rule = may_rule & sides_known
        unfolding = unfold_measured(
            topo.cand,
            pts,
            pts[topo.cand],
            normals[:, rows],
            area2[rows],
            probes[:, :, rows],
            None if rule is None else rule[rows],
            snapped_walls(surface),
            pixel_spans(uv[topo.cand], pts[topo.cand]),
        )
        mine, mine_n = corners[:, :, rows], normals[:, rows]
        folded = np.flatnonzero(unfolding.folded)
        if folded.size:  # their unfolded corners, and planes
            mine[:, :, folded] = unfolding.points[folded].transpose(2, 1, 0)
            mine_n[:, folded] = planes_first(mine[:, :, folded])[0]
        coords, sides, shapes = shapes_first(mine, mine_n)
        if along:
            _measure_along(surface, grid_uv, topo, sides, coords, shapes, unfolding.folded, along)
        # edge lengths as the (unfolded) triangles have them (side k: k -> k + 1); an
        # edge shared by two triangles gets the mean of their two values
        n_edges = topo.edges.shape[0]
        sums = np.bincount(topo.inverse, weights=sides.ravel(), minlength=n_edges)
        counts = np.bincount(topo.inverse, minlength=n_edges)
        curved = unfolding.folded & (unfolding.softness > 0)
        folded_t = np.asarray(unfolding.folded, dtype=bool)
        ruled = np.asarray(unfolding.ruled, dtype=bool)
        planar = _planar(pts, topo.cand, plane_equations(surface.meta)) & ~folded_t
        memo: dict[str, Any] = {}
        if may_rule is None and rows.size == all_tris.shape[0]:
            # every grid triangle kept, each looked at for a straight crease between
            # curved sides: this is the grid's own unfolding (the display's, made from
            # the same corners and probes), kept for it
            memo["grid unfolding"] = unfolding
        return cls(
            grid,
            grid_uv,
            pts,
            topo,
            coords,
            sums / counts,
            shapes,
            curved,
            folded_t,
            ruled,
            planar,
            memo,
            along,
        )


def _measure_along(
    surface: Surface,
    grid_uv: FloatArray,
    topo: Topology,
    sides: FloatArray,
    coords: FloatArray,
    shapes: FloatArray,
    folded: NDArray[np.bool_],
    steps: int,
) -> None:
    """Replace, in place, the ``sides`` (3, T), ``coords`` (T, 3, 2) and ``shapes``
    (T, 3, 2) of the triangles not ``folded`` by those of their sides'
    :func:`~adaproj_edge.geometry.developed.developed_lengths` (``steps`` chords each),
    where they make a triangle. A side whose curve has no surface somewhere, or is more
    than :data:`STRETCH` longer or shorter than its chord (it crosses a jump, a
    silhouette, not a bend), keeps its chord."""
    uv = grid_uv.reshape(-1, 2)[topo.verts]
    ends = np.take(uv, topo.edges, axis=0)
    new = developed_lengths(surface, ends[:, 0], ends[:, 1], steps)[topo.inverse]
    new = new.reshape(3, -1)
    with np.errstate(invalid="ignore"):
        new = np.where(np.abs(new - sides) <= STRETCH * sides, new, sides)
    new_coords, new_shapes = shapes_from_sides(new)
    with np.errstate(invalid="ignore"):
        ok = ~np.asarray(folded, dtype=bool) & (new_shapes[:, 2, 1] > 0)
    sides[:, ok] = new[:, ok]
    coords[ok] = new_coords[ok]
    shapes[ok] = new_shapes[ok]


def _planar(pts: FloatArray, cand: IntArray, equations: FloatArray) -> NDArray[np.bool_]:
    """(T,) whether all three corners ``cand`` (T, 3) (indices into ``pts`` (N, 3)) of
    a triangle lie on one plane of ``equations`` (k, 4)."""
    if equations.shape[0] == 0:
        return np.zeros(cand.shape[0], dtype=bool)
    on = on_planes(pts, equations)[cand]  # (T, 3, k)
    out: NDArray[np.bool_] = np.all(on, axis=1).any(axis=1)
    return out


def planar_shapes(tri_pts: FloatArray) -> FloatArray:
    """Triangles (T, 3, 3) in 2D frames of their own planes (T, 3, 2): corner 0 at the
    origin, corner 1 on the +x axis, corner 2 on the side the content's y axis has
    (content y points down, as for the projector's pixels)."""
    return triangle_shapes(tri_pts)[2]


def _grid_sides(
    cand: IntArray, index: IntArray, cols: int, n_vertices: int
) -> tuple[IntArray, IntArray, IntArray]:
    """:func:`unique_edges` of the sides (k -> k + 1, k-major) of grid triangles ``cand``
    (T, 3) (grid vertex indices) of a grid of ``cols`` columns, whose vertices have the
    compact indices ``index`` (N,) (increasing with the grid index).

    A grid triangle's side from grid vertex ``lo`` (the lower) is horizontal, vertical or
    diagonal (``hi - lo`` is 1, cols + 1 or cols + 2): its number ``3 lo + kind`` orders
    the sides as their compact (lo, hi) pairs do, so marking the numbers present (no sort)
    gives the sorted unique edges."""
    a = cand.T
    b = a[[1, 2, 0]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    span = hi - lo
    number = (3 * lo + (span > 1) + (span > cols + 1)).ravel()
    present = np.zeros(3 * n_vertices, dtype=bool)
    present[number] = True
    inverse = (np.cumsum(present) - 1)[number]
    found = np.flatnonzero(present)
    low = found // 3
    high = low + np.array([1, cols + 1, cols + 2])[found % 3]
    edges = np.stack([index[low], index[high]], axis=1)
    counts = np.bincount(inverse, minlength=found.size)
    return edges, inverse, counts


def _largest_component(all_tris: IntArray, rows: IntArray, cols: int) -> IntArray:
    """The ``rows`` of ``all_tris`` (the triangles of a grid of ``cols`` columns) in the
    largest edge-connected piece of the triangles ``all_tris[rows]`` (by triangle count).

    Two triangles are joined when they share a side. Pieces that touch only at a vertex
    are apart: the warp's energy does not tie them (each may turn about the shared
    vertex), so the system of both together is singular."""
    if rows.size == all_tris.shape[0]:
        return rows  # the whole grid: one piece
    tris = all_tris[rows]
    # each side's number (as in _grid_sides): equal numbers are one side shared
    a = tris.T
    b = a[[1, 2, 0]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    span = hi - lo
    number = (3 * lo + (span > 1) + (span > cols + 1)).ravel()
    owner = np.tile(np.arange(rows.size), 3)
    order = np.argsort(number, kind="stable")
    number, owner = number[order], owner[order]
    pair = np.flatnonzero(number[1:] == number[:-1])
    graph = scipy.sparse.coo_matrix(
        (np.ones(pair.size), (owner[pair], owner[pair + 1])), shape=(rows.size, rows.size)
    )
    ncomp, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    if ncomp == 1:
        return rows
    keep: IntArray = rows[labels == int(np.argmax(np.bincount(labels)))]
    return keep
