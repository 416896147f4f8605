"""The straightforward implementations, kept as yardsticks for the fast engine.

:data:`REFERENCE` has the same energies as :mod:`adaproj_edge.warp.solve`, assembled
the way the paper describes its implementation: every iteration loops over the terms,
collects sparse triplets, forms the normal equations and calls
``scipy.sparse.linalg.spsolve``. It is readable and obviously right, and slow; tests
check that the fast solver gives the same answer.

:func:`paper_warp` is the paper as written, end to end (§4, Algorithm 1): E_a alone and
then E' = E_a + lambda E_r with two corner vertices pinned at (0, 0) and (1, gamma)
(eq. 7), the similarity that makes the content the maximal inscribed rectangle
(§4.1, same orientation), then the alternation of eq. 8-9 (boundary fixed, the
regulariser toward the last iterate) solved with ``spsolve`` at every step until the
mean vertex motion is below the tolerance (0.05 content pixels) or after 10 steps.
``tools/bench_warp.py`` times :func:`~adaproj_edge.warp.planner.compute_warp` against it
(``compute_warp(..., WarpSettings(alternation="paper"), REFERENCE)`` runs it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.rectangle import inscribed_rectangle
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import Backend, WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.solve import (
    ContentAwareWeights,
    _pin_positions,
    directed,
    edge_directions,
    gauge_vertices,
)
from adaproj_edge.warp.warpmap import Grid


class _Assembler:
    """Collects weighted residual rows ``sqrt(w) (sum_k c_k x_k - r)``."""

    def __init__(self) -> None:
        self.rows: list[int] = []
        self.cols: list[int] = []
        self.vals: list[float] = []
        self.rhs: list[float] = []

    def row(self, weight: float, coeffs: list[tuple[int, float]], rhs: float = 0.0) -> None:
        r = len(self.rhs)
        sw = float(np.sqrt(weight))
        for c, v in coeffs:
            self.rows.append(r)
            self.cols.append(c)
            self.vals.append(sw * v)
        self.rhs.append(sw * rhs)

    def solve(self, n: int, fixed: dict[int, float]) -> FloatArray:
        a = scipy.sparse.csr_matrix((self.vals, (self.rows, self.cols)), shape=(len(self.rhs), n))
        b = np.asarray(self.rhs)
        x = np.zeros(n)
        for k, v in fixed.items():
            x[k] = v
        free = np.array([k for k in range(n) if k not in fixed])
        b = b - a @ x
        af = a[:, free]
        normal = (af.T @ af).tocsc()
        x[free] = scipy.sparse.linalg.spsolve(normal, af.T @ b)
        return x


class _Mesh(Protocol):
    """What the term-by-term assembly reads of a mesh."""

    @property
    def tris(self) -> IntArray: ...

    @property
    def coords(self) -> FloatArray: ...

    @property
    def edges(self) -> IntArray: ...

    @property
    def lengths(self) -> FloatArray: ...


@dataclass(frozen=True)
class PaperMesh:
    """The grid mesh as the paper sets it up (§3.2), independently of the engine's
    :class:`~adaproj_edge.warp.mesh.MeshGeometry`: the surface at the grid vertices, the
    triangles whose corners all meet it, ``alpha, beta`` of eq. 2 for every role, the
    edges and their lengths on the surface, the boundary edges."""

    verts: IntArray  # (n,) grid index of each vertex
    tris: IntArray  # (T, 3) vertex indices
    coords: FloatArray  # (T, 3, 2) alpha, beta per role
    edges: IntArray  # (E, 2)
    lengths: FloatArray  # (E,)
    boundary: IntArray  # (B, 2)

    @property
    def n(self) -> int:
        """Number of mesh vertices."""
        return int(self.verts.size)


def paper_mesh(surface: Surface, grid: Grid) -> PaperMesh:
    """Set up the mesh of ``grid`` on ``surface`` straightforwardly (numpy over all
    triangles at once; no crease unfolding, which the paper does not have)."""
    uv = grid.vertices(surface.projector)
    points = surface.points_at(uv).reshape(-1, 3)
    cols = grid.cols + 1
    r, c = np.mgrid[0 : grid.rows, 0 : grid.cols]
    a = (r * cols + c).ravel()
    b, d, e = a + 1, a + cols, a + cols + 1
    cand = np.concatenate([np.stack([a, b, e], 1), np.stack([a, e, d], 1)])  # diagonal split
    p = points[cand]
    normal = -np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ok = np.all(np.isfinite(p), axis=(1, 2))
    ok[ok] = np.sum(normal[ok] * p[ok].mean(axis=1), axis=1) < 0  # facing the projector
    corners = cand[ok]
    verts, tris = np.unique(corners, return_inverse=True)
    tris = tris.reshape(-1, 3)
    p = points[verts][tris]
    normal = normal[ok] / np.linalg.norm(normal[ok], axis=1, keepdims=True)
    coords = np.zeros((tris.shape[0], 3, 2))
    for k in range(3):  # eq. 2: P1 = P2 + alpha (P3 - P2) + beta R90 (P3 - P2)
        p1, p2, p3 = p[:, k], p[:, (k + 1) % 3], p[:, (k + 2) % 3]
        edge = p3 - p2
        ee = np.sum(edge * edge, axis=1)
        coords[:, k, 0] = np.sum((p1 - p2) * edge, axis=1) / ee
        coords[:, k, 1] = np.sum((p1 - p2) * np.cross(normal, edge), axis=1) / ee
    sides = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    edges, uses = np.unique(sides, axis=0, return_counts=True)
    pts = points[verts]
    lengths = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    return PaperMesh(verts, tris, coords, edges, lengths, edges[uses == 1])


def _conformal(asm: _Assembler, mesh: _Mesh, stride: int, apex_weight: FloatArray) -> None:
    for t, tri in enumerate(mesh.tris):
        for k in range(3):
            i1, i2, i3 = int(tri[k]), int(tri[(k + 1) % 3]), int(tri[(k + 2) % 3])
            a, b = float(mesh.coords[t, k, 0]), float(mesh.coords[t, k, 1])
            x1, x2, x3 = stride * i1, stride * i2, stride * i3
            y1, y2, y3 = x1 + 1, x2 + 1, x3 + 1
            w = float(apex_weight[i1])
            # V1 - V2 - a (V3 - V2) - b R90 (V3 - V2), R90 (x, y) = (y, -x)
            asm.row(w, [(x1, 1.0), (x2, a - 1.0), (x3, -a), (y2, b), (y3, -b)])
            asm.row(w, [(y1, 1.0), (y2, a - 1.0), (y3, -a), (x2, -b), (x3, b)])


def _relative_size(
    asm: _Assembler,
    mesh: _Mesh,
    dirs: FloatArray,
    edge_weight: FloatArray,
    smooth_weight: FloatArray,
) -> None:
    d_edges, d_len = directed(mesh.edges, mesh.lengths)
    for e, (i, j) in enumerate(d_edges):
        i, j = int(i), int(j)
        w = float(edge_weight[e])
        for c in range(2):
            asm.row(w, [(3 * i + c, 1.0), (3 * j + c, -1.0), (3 * i + 2, -d_len[e] * dirs[e, c])])
    for e, (i, j) in enumerate(mesh.edges):
        asm.row(float(smooth_weight[e]), [(3 * int(i) + 2, 1.0), (3 * int(j) + 2, -1.0)])


def solve_conformal_reference(mesh: MeshGeometry) -> FloatArray:
    """E_a only, uniform weights, two vertices pinned (see ``solve_conformal``)."""
    asm = _Assembler()
    _conformal(asm, mesh, 2, np.ones(mesh.n))
    a, b = gauge_vertices(mesh)
    pa, pb = _pin_positions(mesh, a, b)
    fixed = {2 * a: pa[0], 2 * a + 1: pa[1], 2 * b: pb[0], 2 * b + 1: pb[1]}
    return asm.solve(2 * mesh.n, fixed).reshape(-1, 2)


def solve_content_free_reference(
    mesh: MeshGeometry, v_conformal: FloatArray, lam: float
) -> tuple[FloatArray, FloatArray]:
    """E' = E_a + lambda E_r, all weights 1 (see ``solve_content_free``)."""
    asm = _Assembler()
    _conformal(asm, mesh, 3, np.ones(mesh.n))
    d_edges, _ = directed(mesh.edges, mesh.lengths)
    dirs = edge_directions(v_conformal, d_edges)
    l2 = float(np.mean(mesh.lengths**2))
    _relative_size(
        asm, mesh, dirs, np.full(d_edges.shape[0], lam), np.full(mesh.edges.shape[0], lam * 2 * l2)
    )
    a, b = gauge_vertices(mesh)
    fixed = {
        3 * a: v_conformal[a, 0],
        3 * a + 1: v_conformal[a, 1],
        3 * b: v_conformal[b, 0],
        3 * b + 1: v_conformal[b, 1],
    }
    x = asm.solve(3 * mesh.n, fixed).reshape(-1, 3)
    return x[:, :2].copy(), x[:, 2].copy()


@dataclass
class ReferenceContentAwareSolver:
    """Same interface and energy as :class:`~adaproj_edge.warp.solve.ContentAwareSolver`,
    assembled term by term and solved with ``spsolve`` at every step."""

    mesh: MeshGeometry
    weights: ContentAwareWeights = field(default_factory=ContentAwareWeights)

    def step(self, v: FloatArray, w: FloatArray) -> FloatArray:
        """One solve with saliency ``w`` (n,) in {0, 1} from the iterate ``v`` (n, 2)."""
        mesh, cw = self.mesh, self.weights
        n = mesh.n
        asm = _Assembler()
        _conformal(asm, mesh, 2, 1.0 + cw.conformal_salient * w)
        dirs = edge_directions(v, mesh.edges)
        for e, (i, j) in enumerate(mesh.edges):
            i, j = int(i), int(j)
            both = float(w[i] + w[j])
            target = mesh.lengths[e] * dirs[e]
            for c in range(2):
                asm.row(cw.size * both, [(2 * i + c, 1.0), (2 * j + c, -1.0)], float(target[c]))
            old = v[i] - v[j]  # the edge as it is: the floor rows hold it there
            for c in range(2):
                asm.row(
                    cw.size_floor * (2.0 - both),
                    [(2 * i + c, 1.0), (2 * j + c, -1.0)],
                    float(old[c]),
                )
        l2 = float(np.mean(mesh.lengths**2))
        for i in range(n):
            for c in range(2):
                asm.row(l2 * cw.damping, [(2 * i + c, 1.0)], float(v[i, c]))
        a, _ = gauge_vertices(mesh)
        fixed = {2 * a: float(v[a, 0]), 2 * a + 1: float(v[a, 1])}
        return asm.solve(2 * n, fixed).reshape(-1, 2)


def paper_warp(
    surface: Surface,
    content_size: tuple[int, int],
    content_map: ContentMap | None,
    settings: WarpSettings,
) -> tuple[FloatArray, dict[str, Any]]:
    """The paper's method as written, straightforwardly (see the module docstring).

    Returns content pixel coordinates (R*C, 2) of the grid vertices (NaN without
    surface) and ``meta`` (iterations, salient fraction).
    """
    mesh = paper_mesh(surface, settings.grid)
    n = mesh.n
    w, h = content_size
    gamma = h / w
    first, last = 0, n - 1  # V_0 and V_|V|: the first and last vertex of the grid
    # E_a alone (lambda = 0), the two corners pinned: the edge directions of eq. 12
    asm = _Assembler()
    _conformal(asm, mesh, 2, np.ones(n))
    pins2 = {2 * first: 0.0, 2 * first + 1: 0.0, 2 * last: 1.0, 2 * last + 1: gamma}
    v_a = asm.solve(2 * n, pins2).reshape(n, 2)
    d_edges, _ = directed(mesh.edges, mesh.lengths)
    dirs = edge_directions(v_a, d_edges)
    l2 = float(np.mean(mesh.lengths**2))
    # eq. 7: E' (all w_a = 1) with the auxiliary scales
    asm = _Assembler()
    _conformal(asm, mesh, 3, np.ones(n))
    _relative_size(
        asm,
        mesh,
        dirs,
        np.full(d_edges.shape[0], settings.lam),
        np.full(mesh.edges.shape[0], settings.lam * 2 * l2),
    )
    pins3 = {3 * first: 0.0, 3 * first + 1: 0.0, 3 * last: 1.0, 3 * last + 1: gamma}
    x = asm.solve(3 * n, pins3).reshape(n, 3)
    v0 = x[:, :2].copy()
    # §4.1: the content rectangle becomes the maximal inscribed one, same orientation
    rect = inscribed_rectangle(v0, mesh.tris, w / h, boundary=mesh.boundary, near=0.0)
    scale = w / rect.width
    origin = np.array([rect.x0, rect.y0])

    def to_pixels(v: FloatArray) -> FloatArray:
        out: FloatArray = (v - origin) * scale - 0.5
        return out

    boundary = np.unique(mesh.boundary)
    v = v0
    iterations = 0
    fraction = 0.0
    if content_map is not None:
        for _ in range(settings.max_iterations):
            xy = to_pixels(v)
            c = content_map.sample(xy).astype(np.float64)
            wa = (c >= settings.threshold).astype(np.float64)  # eq. 8
            fraction = float(wa.mean())
            if wa.min() == wa.max():
                break
            asm = _Assembler()
            _conformal(asm, mesh, 3, wa + 1e-6)
            _relative_size(
                asm,
                mesh,
                dirs,
                np.full(d_edges.shape[0], settings.lam),
                settings.lam * l2 * (wa[mesh.edges[:, 0]] + wa[mesh.edges[:, 1]]),
            )
            for i in range(n):  # the regulariser of eq. 9 (and a trace: definite)
                reg = max(1.0 - float(c[i]), 0.0) + 1e-6
                asm.row(reg, [(3 * i, 1.0)], float(v[i, 0]))
                asm.row(reg, [(3 * i + 1, 1.0)], float(v[i, 1]))
            fixed = {}
            for i in boundary:  # eq. 9: the boundary stays where the initial solution put it
                fixed[3 * int(i)] = float(v0[i, 0])
                fixed[3 * int(i) + 1] = float(v0[i, 1])
            v_new = asm.solve(3 * n, fixed).reshape(n, 3)[:, :2]
            motion = float(np.mean(np.linalg.norm(to_pixels(v_new) - xy, axis=1)))
            v = v_new
            iterations += 1
            if motion < settings.tolerance:
                break
    image_xy = np.full(((settings.grid.rows + 1) * (settings.grid.cols + 1), 2), np.nan)
    image_xy[mesh.verts] = to_pixels(v)
    meta = {"iterations": iterations, "salient_vertex_fraction": fraction}
    return image_xy, meta


REFERENCE = Backend(
    solve_conformal_reference,
    solve_content_free_reference,
    ReferenceContentAwareSolver,
    paper_warp,
)
