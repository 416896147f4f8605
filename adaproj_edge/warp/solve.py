"""The warp solves: conformal (E_a), content-free (E_a + lambda E_r, paper §4.1) and
the content-aware refinement (our reformulation of paper §4.2).

Everything here works in "surface units": content-space coordinates whose scale is
about one unit per metre of surface. :mod:`adaproj_edge.warp.placement` later turns
them into content pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import WarpError
from adaproj_edge.warp import terms
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.system import BandedLeastSquares, ComplexLeastSquares, Rows

# A large plane the surface was snapped to (a wall, a floor) is what a viewer looks at;
# the chair leg in front of it is not. Its triangles (``MeshGeometry.planar``) weigh this
# much more in E_a in every solve, and in the content-free and content-aware solves their
# edges' length rows weigh this much more too, so the distortion the rest of the
# footprint forces goes onto the rest (the paper's idea, with the plane as a subject).
PLANE_SHAPE = 100.0
PLANE_SIZE = 30.0


def plane_roles(mesh: MeshGeometry, per_role: int) -> FloatArray:
    """(T * 3 * per_role,) 1.0 on the E_a rows of the planar triangles (rows ordered
    triangle, role, then ``per_role`` components), else 0."""
    return np.repeat(mesh.planar.astype(np.float64), 3 * per_role)


@dataclass(frozen=True)
class ContentAwareWeights:
    """Weights of the content-aware energy (see :class:`ContentAwareSolver`).

    conformal_salient : extra E_a weight on triangle roles whose apex is salient; the
        E_a weight is ``1 + conformal_salient * w``.
    size : weight of the salient edges' length-and-direction rows (E_r with one common
        scale); the rows are lengths, like the E_a rows, so the two compare directly.
    size_floor : weight of the non-salient edges' rows toward their previous vectors
        (they only steady the iteration: they vanish at its fixed point).
    damping : weight of ``|V_i - V_i^(n)|^2`` on every vertex, per unit edge length^2.
    plane : extra E_a weight on the triangles on a snapped plane (``mesh.planar``), as
        in the conformal and content-free solves (:data:`PLANE_SHAPE`).
    plane_size : weight of those triangles' edges' length rows (toward their length on
        the surface at the salient region's scale; :data:`PLANE_SIZE`).

    Defaults: the salient region is made a few hundred times stiffer than the rest, in
    shape (``conformal_salient``) and in size (``size``); shape weighs more than size,
    so the subject stays conformal and only its scale is evened out. Measured on the
    analytic spheres and bowl with off-centre subjects (``tools/measure_warp.py``,
    asserted in ``tests/warp/test_quality.py``), the subject's size inconsistency
    falls to 0.13-0.42x that of the conformal warp and its angle error to 0.42-0.77x.
    With ``size`` equal to ``conformal_salient`` the angle error rose above the conformal
    warp's (up to 1.4x); ten times weaker weights keep more of the size drift (0.6x).
    """

    conformal_salient: float = 300.0
    size: float = 100.0
    size_floor: float = 0.02
    damping: float = 1e-4
    plane: float = PLANE_SHAPE
    plane_size: float = PLANE_SIZE


def gauge_vertices(mesh: MeshGeometry) -> tuple[int, int]:
    """Two compact vertices to pin: the one nearest the grid centre and the farthest one
    from it among its row and column neighbours' extremes (once per mesh)."""
    return mesh.remember("gauge vertices", lambda: _gauge_vertices(mesh))


def _gauge_vertices(mesh: MeshGeometry) -> tuple[int, int]:
    """:func:`gauge_vertices`, worked out."""
    uv = mesh.uv
    centre = mesh.grid_uv.reshape(-1, 2).mean(axis=0)
    a = int(np.argmin(np.sum((uv - centre) ** 2, axis=1)))
    b = int(np.argmax(np.sum((uv - uv[a]) ** 2, axis=1)))
    return a, b


def _pin_positions(mesh: MeshGeometry, a: int, b: int) -> tuple[FloatArray, FloatArray]:
    """Positions for the two pinned vertices: a at the origin, b at the surface distance
    from a, in the projector's image direction from a to b."""
    p = mesh.p
    d = mesh.uv[b] - mesh.uv[a]
    d = d / np.linalg.norm(d)
    return np.zeros(2), d * float(np.linalg.norm(p[b] - p[a]))


def solve_conformal(mesh: MeshGeometry, plane: float = PLANE_SHAPE) -> FloatArray:
    """E_a only, two vertices pinned: the iLamps-style conformal warp; uniform weights
    but on the triangles of a snapped plane (``mesh.planar``), ``1 + plane``.

    Solved over complex unknowns with the content-aware step's system
    (:func:`complex_system`: vertex a pinned; one set-up serves both): E_a at weight 1,
    the edge and position rows at weight 0 but b's, which pulls b toward its pin. E_a is
    a quadratic form that vanishes on translations, so that minimiser is the two-pin
    solution scaled about a (by a real factor just below 1); scaling it back to b's pin
    gives that solution exactly. Returns (n, 2) positions in surface units.
    """
    n = mesh.n
    rows = complex_system(mesh)
    a, b = gauge_vertices(mesh)
    pa, pb = _pin_positions(mesh, a, b)
    za, zb = complex(pa[0], pa[1]), complex(pb[0], pb[1])
    n_conf, n_edge, _ = rows.sizes
    at_b = n_conf + n_edge + b  # b's position row
    weights = np.zeros(sum(rows.sizes))
    weights[:n_conf] = 1.0 + plane * plane_roles(mesh, 1)
    weights[at_b] = 1.0
    const = np.zeros(sum(rows.sizes), dtype=np.complex128)
    const[at_b] = zb
    z_fixed = np.zeros(n, dtype=np.complex128)
    z_fixed[a] = za
    rows.system.factor(rows.vals, weights)
    z = rows.system.solve(const, z_fixed, zero_rows=at_b)
    if not abs(z[b] - za) > 0:
        raise WarpError("the conformal solve collapsed (the mesh is degenerate?)")
    z = za + (z - za) * ((zb - za) / (z[b] - za))
    z[a], z[b] = za, zb
    return _as_xy(z)


@dataclass(frozen=True)
class ComplexRows:
    """The E_a, edge and position rows over complex unknowns (one per vertex) and their
    least-squares system with vertex a (:func:`gauge_vertices`) pinned.

    sizes : rows of each block (E_a: (triangle, role); edges; vertices)
    vals : (m, 3) their coefficients (shared: read, never write)
    system : the system (made once per topology; it keeps its last factorisation)
    """

    sizes: tuple[int, int, int]
    vals: NDArray[np.complex128]
    system: ComplexLeastSquares


def complex_system(mesh: MeshGeometry) -> ComplexRows:
    """:class:`ComplexRows` of ``mesh``, made once per mesh: the conformal solve and the
    content-aware step share them (and the system's set-up)."""

    def make() -> ComplexRows:
        n = mesh.n
        blocks = [
            terms.complex_conformal_rows(mesh.tris, mesh.coords),
            terms.complex_edge_rows(mesh.edges),
            terms.complex_position_rows(n),
        ]
        sizes = (blocks[0][0].shape[0], blocks[1][0].shape[0], blocks[2][0].shape[0])
        vals = np.zeros((sum(sizes), 3), dtype=np.complex128)
        start = 0
        for _, v in blocks:
            vals[start : start + v.shape[0], : v.shape[1]] = v
            start += v.shape[0]
        a, _ = gauge_vertices(mesh)

        def system() -> ComplexLeastSquares:
            cols = np.full((sum(sizes), 3), -1, dtype=np.intp)
            start = 0
            for c, _ in blocks:
                cols[start : start + c.shape[0], : c.shape[1]] = c
                start += c.shape[0]
            fixed = np.zeros(n, dtype=bool)
            fixed[a] = True
            return ComplexLeastSquares(cols, n, fixed)

        vals.flags.writeable = False
        return ComplexRows(sizes, vals, mesh.topology.remember("content-aware", system))

    return mesh.remember("complex rows", make)


def _as_xy(z: NDArray[np.complex128]) -> FloatArray:
    """Complex positions (n,) as (n, 2) x, y (a view of a fresh array)."""
    out: FloatArray = np.ascontiguousarray(z).view(np.float64).reshape(-1, 2)
    return out


def edge_directions(v: FloatArray, edges: IntArray) -> FloatArray:
    """Unit content-space directions (E, 2) of ``edges`` (E, 2) in positions ``v``."""
    d = v[edges[:, 0]] - v[edges[:, 1]]
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    if np.any(norm <= 0):
        raise WarpError("a mesh edge collapsed to a point")
    out: FloatArray = d / norm
    return out


def directed(edges: IntArray, lengths: FloatArray) -> tuple[IntArray, FloatArray]:
    """Both directions of each undirected edge."""
    return np.concatenate([edges, edges[:, ::-1]]), np.concatenate([lengths, lengths])


def solve_content_free(
    mesh: MeshGeometry,
    v_conformal: FloatArray,
    lam: float,
    plane: float = PLANE_SHAPE,
    plane_size: float = PLANE_SIZE,
) -> tuple[FloatArray, FloatArray]:
    """E' = E_a + lambda E_r with all weights 1 (paper eq. 7, the initial solution), but
    on a snapped plane's triangles (``mesh.planar``): E_a ``1 + plane``, their edges'
    E_r rows ``1 + plane_size`` (one scale over the plane).

    Edge directions v_ij come from the conformal solution (the two-step linearisation
    of §4.2); the same two vertices as in the conformal solve stay pinned.

    Returns positions (n, 2) and auxiliary scales (n,).
    """
    n = mesh.n
    d_edges, d_len = directed(mesh.edges, mesh.lengths)
    dirs = edge_directions(v_conformal, d_edges)
    blocks = [
        terms.conformal_rows(mesh.tris, mesh.coords, stride=3),
        terms.scale_edge_rows(d_edges, d_len, dirs),
        terms.scale_smooth_rows(mesh.edges),
    ]
    rows = Rows.concat(blocks)
    l2 = float(np.mean(mesh.lengths**2))
    on_plane = mesh.planar_edges.astype(np.float64)
    weights = np.concatenate(
        [
            1.0 + plane * plane_roles(mesh, 2),
            lam * (1.0 + plane_size * np.repeat(np.tile(on_plane, 2), 2)),
            lam * 2.0 * l2 * (1.0 + plane_size * on_plane),  # (w_i + w_j) = 2
        ]
    )
    a, b = gauge_vertices(mesh)
    fixed = np.zeros(3 * n, dtype=bool)
    fixed[[3 * a, 3 * a + 1, 3 * b, 3 * b + 1]] = True
    x_fixed = np.zeros(3 * n)
    x_fixed[3 * a : 3 * a + 2] = v_conformal[a]
    x_fixed[3 * b : 3 * b + 2] = v_conformal[b]
    system = mesh.topology.remember(
        "content-free", lambda: BandedLeastSquares(rows.cols, 3 * n, fixed)
    )
    x = system.solve(rows.vals, rows.rhs, weights, x_fixed).reshape(n, 3)
    return x[:, :2].copy(), x[:, 2].copy()


@dataclass
class ContentAwareSolver:
    """One content-aware alternation step at a time (our reformulation of §4.2).

    Energy, for binary saliency w (paper eq. 5/8) at the current iterate V^(n):

    ``sum_roles (1 + c w_apex + plane p_t) |E_a residual|^2``
    ``+ sum_edges (size (w_i + w_j) + 2 plane_size p_ij) |V_i - V_j - l_ij v_ij|^2``
    ``+ floor sum_edges (2 - w_i - w_j) |V_i - V_j - (V_i^(n) - V_j^(n))|^2``
    ``+ L^2 damping sum_i |V_i - V_i^(n)|^2``

    with ``v_ij`` the edge's unit direction in V^(n) (re-linearised every step, as in
    as-rigid-as-possible deformation), L the mean edge length, and ``p`` 1 on the
    triangles (edges) of a snapped plane (``mesh.planar``): a wall is held like a
    subject. The last two terms
    vanish at a fixed point (they only steady the iteration), so the alternation
    converges to a stationary point of
    ``sum (1 + c w) |E_a|^2 + size sum (w_i + w_j) (|V_i - V_j| - l_ij)^2``.

    This is the paper's E_r with its auxiliary scales tied to one common value on the
    salient region: ``s_i = 1`` there (every salient object gets the same scale, so
    separate objects keep their relative sizes) and free elsewhere. Unlike the paper,
    the boundary is free (no content is lost: the placement re-inscribes the content
    rectangle) and non-salient vertices are not pinned to the previous iterate: they
    follow the conformal term, so they absorb the size change the salient region
    refuses. The scales eliminated, the unknowns are one complex number per vertex;
    every term's coefficients depend on the saliency alone, so the system is factored
    once per salient set and each further step is one back-substitution.
    """

    mesh: MeshGeometry
    weights: ContentAwareWeights = field(default_factory=ContentAwareWeights)

    def __post_init__(self) -> None:
        mesh = self.mesh
        rows = complex_system(mesh)
        self.sizes = list(rows.sizes)
        self.vals = rows.vals
        self.system = rows.system
        self.pinned, _ = gauge_vertices(mesh)
        self.l2 = float(np.mean(mesh.lengths**2))
        self.apex = mesh.tris.reshape(-1)  # rows are (triangle, role): role k's apex is k
        self._const = np.zeros(sum(self.sizes), dtype=np.complex128)
        self._plane_roles = plane_roles(mesh, 1)
        self._plane_edges = mesh.planar_edges.astype(np.float64)
        self._w: FloatArray | None = None
        self._length_share = self._keep_share = self._row_weights = np.zeros(0)

    def row_weights(self, w: FloatArray) -> FloatArray:
        """The weight (m,) of every row for saliency ``w`` (n,)."""
        cw = self.weights
        ei, ej = self.mesh.edges[:, 0], self.mesh.edges[:, 1]
        both = w[ei] + w[ej]
        return np.concatenate(
            [
                1.0 + cw.conformal_salient * w[self.apex] + cw.plane * self._plane_roles,
                self._size_weight(both) + cw.size_floor * (2.0 - both),
                np.full(self.mesh.n, self.l2 * cw.damping),
            ]
        )

    def _size_weight(self, both: FloatArray) -> FloatArray:
        """The edges' length rows' weight for ``both`` (E,) = w_i + w_j."""
        cw = self.weights
        out: FloatArray = cw.size * both + 2.0 * cw.plane_size * self._plane_edges
        return out

    def _use(self, w: FloatArray) -> None:
        """Make the system's factorisation the one for saliency ``w`` (the system is
        shared by the solvers of a topology: it keeps only its last factorisation)."""
        if self._w is None or not np.array_equal(self._w, w):
            cw, edges = self.weights, self.mesh.edges
            both = w[edges[:, 0]] + w[edges[:, 1]]
            w_size = self._size_weight(both)
            w_floor = cw.size_floor * (2.0 - both)
            # the edge rows' target mixes the length target and the edge as it is
            self._length_share = w_size * self.mesh.lengths / (w_size + w_floor)
            self._keep_share = w_floor / (w_size + w_floor)
            self._w = np.array(w, copy=True)
            self._row_weights = self.row_weights(w)
        self.system.factor(self.vals, self._row_weights)  # a no-op when it is current

    def step(self, v: FloatArray, w: FloatArray) -> FloatArray:
        """One solve with saliency ``w`` (n,) in {0, 1} from the iterate ``v`` (n, 2)."""
        mesh = self.mesh
        self._use(w)
        z = v[:, 0] + 1j * v[:, 1]
        e = z[mesh.edges[:, 0]] - z[mesh.edges[:, 1]]
        length = np.abs(e)
        if not length.min() > 0:  # (NaN: not > 0)
            raise WarpError("a mesh edge collapsed to a point")
        t0, t1 = self.sizes[0], self.sizes[0] + self.sizes[1]
        const = self._const
        const[t0:t1] = self._length_share * (e / length) + self._keep_share * e
        const[t1:] = z
        z_fixed = np.zeros(mesh.n, dtype=np.complex128)
        z_fixed[self.pinned] = z[self.pinned]
        # the E_a rows aim at zero
        return _as_xy(self.system.solve(const, z_fixed, zero_rows=t0))


@dataclass
class PaperAlternation:
    """The paper's alternation step as written (§4.2, eq. 8–9, Algorithm 1).

    ``E_a`` weighted by the binary saliency of each role's apex, ``lambda E_r`` with the
    auxiliary scales (smoothness weighted ``w_i + w_j``) and edge directions from the
    E_a-only solution, the regulariser ``(1 - C(V_i)) |V_i - V_i^(n)|^2``, and the
    boundary vertices fixed to the initial solution. Kept for comparison
    (``WarpSettings(alternation="paper")``): it barely moves the salient region, which
    is why :class:`ContentAwareSolver` is the default.
    """

    mesh: MeshGeometry
    v_conformal: FloatArray
    v_initial: FloatArray
    lam: float = 1.0

    def __post_init__(self) -> None:
        mesh = self.mesh
        n = mesh.n
        self.d_edges, self.d_len = directed(mesh.edges, mesh.lengths)
        dirs = edge_directions(self.v_conformal, self.d_edges)
        self.blocks = [
            terms.conformal_rows(mesh.tris, mesh.coords, stride=3),
            terms.scale_edge_rows(self.d_edges, self.d_len, dirs),
            terms.scale_smooth_rows(mesh.edges),
            terms.position_rows(n, stride=3),
        ]
        self.rows = Rows.concat(self.blocks)
        self.offsets = np.concatenate([[0], np.cumsum([b.rhs.size for b in self.blocks])])
        boundary = np.unique(mesh.boundary)
        fixed = np.zeros(3 * n, dtype=bool)
        fixed[3 * boundary] = True
        fixed[3 * boundary + 1] = True
        self.fixed = fixed
        cols = self.rows.cols
        self.system = mesh.topology.remember(
            "paper", lambda: BandedLeastSquares(cols, 3 * n, fixed)
        )
        self.apex = np.repeat(mesh.tris, 2, axis=1).reshape(-1)
        self.l2 = float(np.mean(mesh.lengths**2))
        self.s = np.ones(n)

    def step(self, v: FloatArray, w: FloatArray, c: FloatArray) -> FloatArray:
        """One solve of eq. 9 from ``v`` (n, 2) with saliency ``w`` and content map ``c``."""
        n = self.mesh.n
        rows = self.rows
        tail = slice(int(self.offsets[3]), int(self.offsets[4]))
        rows.rhs[tail] = v.ravel()
        ei, ej = self.mesh.edges[:, 0], self.mesh.edges[:, 1]
        reg = np.clip(1.0 - c, 0.0, 1.0) + 1e-6  # eq. 9, and a trace to keep it definite
        weights = np.concatenate(
            [
                w[self.apex] + 1e-6,
                np.full(self.blocks[1].rhs.size, self.lam),
                self.lam * self.l2 * (w[ei] + w[ej]),
                np.repeat(reg, 2),
            ]
        )
        x_fixed = np.column_stack([self.v_initial, self.s]).ravel()  # only boundary x, y count
        x = self.system.solve(rows.vals, rows.rhs, weights, x_fixed).reshape(n, 3)
        self.s = x[:, 2].copy()
        return x[:, :2].copy()
