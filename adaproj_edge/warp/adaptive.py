"""Detail finer than the grid: more grid lines where the surface bends faster than the
grid samples it.

Inside a grid cell the display maps each pixel through the plane of its triangle, so
the error grows with the cell's bend ``kappa h`` (normal curvature times the cell's
size on the surface, both along one grid direction): on a corrugated wall whose waves
are two cells long ``kappa h`` is above 1 and the map is 4 % off; at 0.1 it is exact
to 2e-4. A cell that bends one way only (a developable surface) is split down to
:data:`BEND_ONE_WAY`: there this error is all the display has; one that bends both
ways (a dome) to :data:`BEND`, as its own distortion is far larger.

What spoils a triangle is its plane's tilt against the surface's, and that follows how
far the normal turns across it - along its edges, the cell's diagonal among them - not
only how far its rows and columns bend. The two agree where the grid runs along the
surface's directions of curvature; where a cylinder's or a cone's rulings cross the
grid at an angle ``a``, a column bends by ``kappa sin^2 a`` but its normal turns by
``kappa |sin a|``, and along one diagonal the turns along x and along y add up. So on
a developable surface (every cell bending one way only, whichever way its rulings run)
a cell is also split until those two turns together are within
:data:`TURN_ONE_WAY` (a wall meeting a cone rolled 19 deg: the cone's triangles turned
up to 0.12 and showed 7.6e-4 in angle, exact vertices or not). A surface that bends
both ways somewhere is split by its bends alone, as before: its own distortion dwarfs
the chord's. Samples seen more than 66 deg from their normal (:data:`GRAZING_TURN`) do
not count for the turns: their second differences mix in the silhouette, and the lines
they ask for run through the whole frame (a cone wall's, seed 3 case 0: rows split 8x
for the cone's grazing edge, whose chord triangles then pulled the warp's solve 1.5 px
off the exact development, before the sides were measured on the development). Between
60 and 66 deg they do: a picture reaches there where a cone turns away (the wide cone
rolled 80 deg: size std 5.1e-4 without them, 4.7e-4 with; down to 72 deg, 4.5e-4, but
the cone wall's grid 105x50 -> 108x62).

:func:`refine_grid` measures ``kappa h`` along x and along y in every cell of
the base grid, from the surface itself (second differences every :data:`SAMPLE`
pixels, so relief a third of a cell wide is seen), and splits each column and each
row of cells into as many as its worst cell needs (at most :data:`MAX_FACTOR`, and
within a vertex budget). Cells that a curved crease crosses (a curved wall on a floor,
:mod:`adaproj_edge.geometry.creases`) are split :data:`CREASE_FACTOR` times both ways:
the crease's two planes approximate it to second order in the cell's size. A straight
crease needs nothing: its unfolding is exact.

The result is still a regular grid (rows and columns, unevenly spaced), so the warp,
its file and the renderer are unchanged; only the grid's lines are where they are
needed. Along a column or row that needs no more lines nothing is added.

The refined mesh's triangles take their shapes from their sides' lengths on the
surface's development (:data:`ALONG` chords a side,
:func:`~adaproj_edge.geometry.developed.developed_lengths`), not from their corners:
cells a good share of a wave long cut its bends short by where their sides sit on
it, and the chord triangles of a developable wall did not close up (fine corrugations:
angle defects of 0.027 a vertex, 0.001 measured on the development).
"""

from __future__ import annotations

import copy
import hashlib
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.creases import sensed
from adaproj_edge.geometry.planes import plane_equations
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache
from adaproj_edge.warp.warpmap import Grid

SAMPLE = 8  # pixels between the surface samples of the bend measure
BEND = 0.15  # kappa h a cell may have before it is split
# ... where it bends one way only (as a developable surface does: its display is exact
# but for this error, so it is kept smaller); "one way": the other bend is this smaller
BEND_ONE_WAY = 0.08
ONE_WAY = 0.2
# the normal's turn across a developable cell (along x and along y summed) before it is
# split: the display's error grows as the turn squared, more where the surface is seen
# obliquely (the wide cone rolled 70 deg, its rulings near the rows, seen down to 70 deg
# from its normal: mean angle 8.3e-4 at 0.08, 2.8e-4 at 0.05 with the seams' wider blend)
TURN_ONE_WAY = 0.05
MAX_FACTOR = 8  # at most this many columns (rows) out of one
# ... where every cell bends one way only (the display is to be exact): a wavy wall
# whose waves are two cells long needs ~10 (8: mean angle 5.2e-4, 12: 1.5e-4)
MAX_FACTOR_ONE_WAY = 12
CREASE_FACTOR = 4  # cells a curved crease crosses are split this many times both ways
BUDGET = 7000  # vertices at most
MIN_SPACING = 4  # pixels between two lines at least
# the bend both ways (sqrt(|K|) h) below which a cell counts as bending one way only
FLAT = 0.02
GRAZING = 0.5  # the cosine between ray and normal below which a sample is seen grazing
# (0.25: seed 3 case 0's size std 4.5e-4, 0.4: 2.0e-4, 0.5: 1.4e-4; 2.5e-4 before,
# all with chord triangles)
# ... below which a sample's turns do not count (seed 3 case 0, developed sides: 5.0e-5
# at 0.3, 4.8e-5 at 0.5); its bends always count, its bend both ways above GRAZING only
GRAZING_TURN = 0.4
ALONG = 4  # chords a side of the refined mesh is measured in on the development
QUICK = 0.9  # a quick look that sees no bend above this share of the least limit ends it


@dataclass(frozen=True)
class Refinement:
    """The lines of a refined grid.

    Attributes
    ----------
    xs : (C + 1,) column positions (pixels), the base grid's among them.
    ys : (R + 1,) row positions (pixels).
    factor_x : (base columns,) how many columns each base column was split into.
    factor_y : (base rows,)
    """

    xs: FloatArray
    ys: FloatArray
    factor_x: IntArray
    factor_y: IntArray

    @property
    def grid(self) -> Grid:
        """The refined grid's cell counts."""
        return Grid(cols=self.xs.size - 1, rows=self.ys.size - 1)

    @property
    def grid_uv(self) -> FloatArray:
        """Vertex positions (R + 1, C + 1, 2)."""
        gx, gy = np.meshgrid(self.xs, self.ys)
        out: FloatArray = np.stack([gx, gy], axis=-1)
        return out

    @property
    def refined(self) -> bool:
        """Whether any cell was split."""
        return bool(np.any(self.factor_x > 1) or np.any(self.factor_y > 1))

    @property
    def base_cols(self) -> IntArray:
        """Indices into ``xs`` of the base grid's columns."""
        out: IntArray = np.concatenate([[0], np.cumsum(self.factor_x)])
        return out

    @property
    def base_rows(self) -> IntArray:
        """Indices into ``ys`` of the base grid's rows."""
        out: IntArray = np.concatenate([[0], np.cumsum(self.factor_y)])
        return out


def _split(lines: FloatArray, factors: IntArray) -> FloatArray:
    """Grid lines with each interval ``lines[i] .. lines[i + 1]`` split ``factors[i]``
    times (the new lines on whole pixels)."""
    out = [lines[:1]]
    for i, f in enumerate(factors):
        out.append(np.rint(np.linspace(lines[i], lines[i + 1], int(f) + 1)[1:]))
    merged: FloatArray = np.concatenate(out)
    return merged


class Bends(NamedTuple):
    """How the surface bends across each cell (:func:`bends`: (R, C) arrays, the worst
    of the cell's samples, 0 where unknown) or per sample step (:func:`sampled_bends`).

    ``x``, ``y``: ``kappa h`` along x and along y (the normal curvature along the
    direction times the cell's size on the surface: how far its rows and columns bend).
    ``turn_x``, ``turn_y``: the angle the normal turns across the cell along x and
    along y - the same where x and y are the surface's directions of curvature, more
    where they are not: a cylinder's or a cone's rulings at an angle ``a`` to the
    columns bend a column by ``kappa sin^2 a`` per unit length but turn its normal by
    ``kappa |sin a|``. ``two_way``: how far the surface bends both ways, ``|K| -
    ONE_WAY k^2`` (``K`` the Gaussian curvature, ``k`` the greater principal curvature)
    times the cell's area on the surface where positive: 0 where it bends one way only
    (the lesser principal curvature below :data:`ONE_WAY` of the greater), whichever
    way its rulings run in the image.
    """

    x: FloatArray
    y: FloatArray
    turn_x: FloatArray
    turn_y: FloatArray
    two_way: FloatArray


def bends(
    surface: Surface, grid_uv: FloatArray, sample: float = SAMPLE, kinks: bool = False
) -> Bends:
    """The :class:`Bends` of each cell of the grid whose vertices are ``grid_uv``
    (R + 1, C + 1, 2), the worst of its samples'. From the surface's nodes about
    ``sample`` pixels apart; a kink one or two samples wide (a crease) counts only with
    ``kinks``."""
    per_sample, xs, ys, step_x, step_y = sampled_bends(surface, sample, kinks)
    cells = _cells(grid_uv[0, :, 0], grid_uv[:, 0, 1], xs, ys, step_x, step_y)
    n_rows, n_cols = cells.has.shape
    if not per_sample.x.size:
        return Bends(*(np.zeros((n_rows, n_cols)) for _ in Bends._fields))
    sx, sy = cells.size_x[None, :], cells.size_y[:, None]
    scales = (sx, sy, sx, sy, sx * sy)
    out = []
    for per, scale in zip(per_sample, scales, strict=True):
        # samples of a cell are contiguous along both axes: a max per block (rows first,
        # then columns on the transpose: long runs, few calls), 0 where none; a last
        # row and column of zeros end the last blocks (the bends are >= 0)
        padded = np.zeros((per.shape[0] + 1, per.shape[1] + 1))
        padded[:-1, :-1] = np.where(np.isfinite(per), per * scale, 0.0)
        block = np.maximum.reduceat(padded, cells.row_start, axis=0)
        block = np.maximum.reduceat(block.T, cells.col_start, axis=0).T
        out.append(np.where(cells.has, block, 0.0))
    return Bends(*out)


def sampled_bends(
    surface: Surface, sample: float = SAMPLE, kinks: bool = False
) -> tuple[Bends, FloatArray, FloatArray, float, float]:
    """The :class:`Bends` per sample step (before a cell's size in samples scales them:
    ``x``, ``turn_x`` by its width, ``y``, ``turn_y`` by its height, ``two_way`` by
    both) at the surface's inner nodes about ``sample`` pixels apart, the samples'
    pixel columns and rows, and their spacing in pixels."""
    # the surface's own nodes about `sample` pixels apart (no resampling: cheap)
    sx, sy = surface.lattice_scale()
    kx, ky = max(1, round(sample / sx)), max(1, round(sample / sy))
    # component planes (x, y, z), each a contiguous 2D array: fast elementwise sums
    X = np.moveaxis(surface.points[::ky, ::kx], -1, 0).astype(np.float32)
    h, w = surface.shape
    xs = np.arange(0, w, kx, dtype=np.float64) * sx  # the nodes' pixel positions
    ys = np.arange(0, h, ky, dtype=np.float64) * sy
    dx = (X[:, 1:-1, 2:] - X[:, 1:-1, :-2]) / 2  # per sample step
    dy = (X[:, 2:, 1:-1] - X[:, :-2, 1:-1]) / 2
    ddx = X[:, 1:-1, 2:] - 2 * X[:, 1:-1, 1:-1] + X[:, 1:-1, :-2]
    ddy = X[:, 2:, 1:-1] - 2 * X[:, 1:-1, 1:-1] + X[:, :-2, 1:-1]
    dxy = (X[:, 2:, 2:] - X[:, 2:, :-2] - X[:, :-2, 2:] + X[:, :-2, :-2]) / 4
    n = np.stack(
        [
            dx[1] * dy[2] - dx[2] * dy[1],
            dx[2] * dy[0] - dx[0] * dy[2],
            dx[0] * dy[1] - dx[1] * dy[0],
        ]
    )
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        area = np.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)  # |X_x x X_y| = sqrt(E G - F^2)
        # the second fundamental form L, M, N and the first E, F, G, per sample step
        ell = (n[0] * ddx[0] + n[1] * ddx[1] + n[2] * ddx[2]) / area
        m = (n[0] * dxy[0] + n[1] * dxy[1] + n[2] * dxy[2]) / area
        en = (n[0] * ddy[0] + n[1] * ddy[1] + n[2] * ddy[2]) / area
        e = dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2
        f = dx[0] * dy[0] + dx[1] * dy[1] + dx[2] * dy[2]
        g = dy[0] ** 2 + dy[1] ** 2 + dy[2] ** 2
        # kappa h = |n . X_xx| / |X_x|^2 * (|X_x| * cell) = |L| / |X_x| * cell
        bx = np.abs(ell) / np.sqrt(e)
        by = np.abs(en) / np.sqrt(g)
        # the normal's derivative along x is the tangent vector w with w . X_x = -L,
        # w . X_y = -M (Weingarten); along y: -M, -N
        tx = np.sqrt(np.maximum(ell * ell * g - 2 * ell * m * f + m * m * e, 0.0)) / area
        ty = np.sqrt(np.maximum(m * m * g - 2 * m * en * f + en * en * e, 0.0)) / area
        gauss = (ell * en - m * m) / area  # K |X_x x X_y|
        mean = (ell * g - 2 * m * f + en * e) / (2 * area)  # H |X_x x X_y|
        # k^2 |X_x x X_y|, k = |H| + sqrt(H^2 - K)
        most = (np.abs(mean) + np.sqrt(np.maximum(mean * mean - gauss * area, 0.0))) ** 2 / area
        two_way = np.maximum(np.abs(gauss) - ONE_WAY * most, 0.0)
        # seen near grazing, the second differences mix in the silhouette: such a
        # sample cannot tell whether the surface bends both ways, and its turns, huge
        # per pixel, split only as its bends do (columns and rows split for it run
        # through the whole frame); its turns count down to GRAZING_TURN
        c = X[:, 1:-1, 1:-1]
        seen = np.abs(n[0] * c[0] + n[1] * c[1] + n[2] * c[2]) / (
            area * np.sqrt(c[0] ** 2 + c[1] ** 2 + c[2] ** 2)
        )
        grazing = seen < GRAZING
        turns = seen >= GRAZING_TURN
        tx, ty = np.where(turns, tx, 0.0), np.where(turns, ty, 0.0)
        two_way = np.where(grazing, 0.0, two_way)
    if not kinks:  # a crease is one or two samples wide: curvature bends over three
        bx = np.pad(_least3(bx, 1), ((0, 0), (1, 1)))
        by = np.pad(_least3(by, 0), ((1, 1), (0, 0)))
        # the normal and the mixed derivative straddle a crease along the other axis too
        tx, ty, two_way = (np.pad(_least3(_least3(a, 1), 0), 1) for a in (tx, ty, two_way))
    return Bends(bx, by, tx, ty, two_way), xs[1:-1], ys[1:-1], kx * sx, ky * sy


def _least3(a: FloatArray, axis: int) -> FloatArray:
    """The least of three neighbours along ``axis`` (two fewer along it)."""
    if axis == 1:
        out: FloatArray = np.fmin(np.fmin(a[:, :-2], a[:, 1:-1]), a[:, 2:])
    else:
        out = np.fmin(np.fmin(a[:-2], a[1:-1]), a[2:])
    return out


@dataclass(frozen=True)
class _Cells:
    """Which grid cell each sample falls in (:func:`bends`), for a grid's lines and a
    lattice's samples."""

    size_x: FloatArray  # (columns of samples,) the cell's width in samples
    size_y: FloatArray  # (rows of samples,)
    col_start: IntArray  # (grid columns,) each cell's first sample column (or the next's)
    row_start: IntArray  # (grid rows,)
    has: NDArray[np.bool_]  # (grid rows, grid columns) the cell holds a sample


_CELLS: OrderedDict[tuple[bytes | float, ...], _Cells] = OrderedDict()


def _cells(
    cols: FloatArray, rows: FloatArray, xs: FloatArray, ys: FloatArray, step_x: float, step_y: float
) -> _Cells:
    """The :class:`_Cells` of grid lines ``cols``, ``rows`` and samples at ``xs``,
    ``ys`` (pixels), ``step_x``, ``step_y`` pixels apart; the last few kept (a grid and
    a lattice make the same ones on every surface)."""
    key = (cols.tobytes(), rows.tobytes(), xs.tobytes(), ys.tobytes(), step_x, step_y)
    out = _CELLS.get(key)
    if out is not None:
        _CELLS.move_to_end(key)
        return out
    n_cols, n_rows = cols.size - 1, rows.size - 1
    ci = np.clip(np.searchsorted(cols, xs, side="right") - 1, 0, n_cols - 1)
    ri = np.clip(np.searchsorted(rows, ys, side="right") - 1, 0, n_rows - 1)
    has_c, has_r = np.zeros(n_cols, bool), np.zeros(n_rows, bool)
    has_c[ci] = True
    has_r[ri] = True
    out = _Cells(
        np.diff(cols)[ci] / step_x,
        np.diff(rows)[ri] / step_y,
        np.searchsorted(ci, np.arange(n_cols)),
        np.searchsorted(ri, np.arange(n_rows)),
        has_r[:, None] & has_c[None, :],
    )
    _CELLS[key] = out
    while len(_CELLS) > 8:
        _CELLS.popitem(last=False)
    return out


def _limits(bx: FloatArray, by: FloatArray) -> FloatArray:
    """The bend each cell may have: less where it bends one way only (developable)."""
    one_way = np.minimum(bx, by) < ONE_WAY * np.maximum(bx, by)
    out: FloatArray = np.where(one_way, BEND_ONE_WAY, BEND)
    return out


def _developable(b: Bends) -> NDArray[np.bool_]:
    """Cells that bend one way only, wherever their rulings run: at every sample the
    lesser principal curvature below :data:`ONE_WAY` of the greater, or both so small
    over the cell that they do not count (``sqrt(two_way)`` below :data:`FLAT`)."""
    out: NDArray[np.bool_] = b.two_way <= FLAT**2
    return out


def _exact(b: Bends) -> bool:
    """Whether the display is to be exact: the surface bends one way only in every
    cell (developable). Where some cell bends both ways, the warp's own distortion
    there is far above the chord's, and a diagonal's turn adds nothing worth the lines."""
    return bool(np.all(_developable(b)))


def _excess(b: Bends) -> FloatArray:
    """Each cell's bend as a share of its limit (above 1: it is split): ``kappa h``
    along x and along y (:func:`_limits`), and where the surface is developable the
    normal's turns along x and along y summed - along one of the cell's diagonals,
    a triangle's edge, they add up - to :data:`TURN_ONE_WAY`."""
    own: FloatArray = np.maximum(b.x, b.y) / _limits(b.x, b.y)
    if not _exact(b):
        return own
    out: FloatArray = np.maximum(own, (b.turn_x + b.turn_y) / TURN_ONE_WAY)
    return out


def _needs(b: Bends) -> tuple[FloatArray, FloatArray]:
    """How many columns and rows each cell needs for :func:`_excess` to be at most 1.
    Where it is developable, the lesser turn is split to half the limit and the greater
    to what that leaves (the fewest pieces ``fx fy`` with ``tx / fx + ty / fy`` within
    it: ``tx / fx = ty / fy`` where both are split; a cell whose normal turns along x
    only is split along x only, as by its bend)."""
    limit = _limits(b.x, b.y)
    own_x, own_y = np.ceil(b.x / limit), np.ceil(b.y / limit)
    if not _exact(b):
        return own_x, own_y
    small, large = np.minimum(b.turn_x, b.turn_y), np.maximum(b.turn_x, b.turn_y)
    f_small = np.maximum(1.0, np.ceil(2 * small / TURN_ONE_WAY))
    f_large = np.ceil(large / (TURN_ONE_WAY - small / f_small))
    x_small = b.turn_x <= b.turn_y
    need_x = np.maximum(own_x, np.where(x_small, f_small, f_large))
    need_y = np.maximum(own_y, np.where(x_small, f_large, f_small))
    return need_x, need_y


def refine_grid(
    surface: Surface,
    grid: Grid,
    curved: IntArray | None = None,
    budget: int = BUDGET,
    base: FloatArray | None = None,
) -> Refinement:
    """The lines of ``grid``, with columns and rows split where ``surface`` needs it.

    ``curved`` : (rows * cols,) cell indices a curved crease crosses (a mesh of the base
    grid knows them: :attr:`~adaproj_edge.warp.mesh.MeshGeometry.curved_cells`).
    ``base`` : the grid's vertices (:meth:`Grid.vertices`), when the caller has them.
    """
    if base is None:
        base = grid.vertices(surface.projector)
    none = Refinement(
        base[0, :, 0], base[:, 0, 1], np.ones(grid.cols, np.intp), np.ones(grid.rows, np.intp)
    )
    if curved is None or curved.size == 0:
        # a quick look first, twice as sparse and creases included: a surface that is
        # smooth at the grid's scale needs no closer one
        if np.all(_excess(bends(surface, base, 2 * SAMPLE, kinks=True)) < QUICK):
            return none
    b = bends(surface, base)
    need_x, need_y = _needs(b)
    flat = np.zeros(grid.rows * grid.cols)
    if curved is not None and curved.size:
        flat[curved] = 1.0
    creased = flat.reshape(grid.rows, grid.cols)
    need_x = np.maximum(need_x, CREASE_FACTOR * creased)
    need_y = np.maximum(need_y, CREASE_FACTOR * creased)
    # at most MAX_FACTOR (MAX_FACTOR_ONE_WAY where the display is to be exact), and no
    # line closer than MIN_SPACING pixels to the next
    most = MAX_FACTOR_ONE_WAY if _exact(b) else MAX_FACTOR
    most_x = np.minimum(most, np.diff(base[0, :, 0]) // MIN_SPACING)
    most_y = np.minimum(most, np.diff(base[:, 0, 1]) // MIN_SPACING)
    fx = np.clip(need_x.max(axis=0), 1, np.maximum(most_x, 1)).astype(np.intp)
    fy = np.clip(need_y.max(axis=1), 1, np.maximum(most_y, 1)).astype(np.intp)
    # within the budget: scale the extra lines down evenly
    lo, hi = 0.0, 1.0
    if (fx.sum() + 1) * (fy.sum() + 1) > budget:
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            gx = 1 + np.floor((fx - 1) * mid)
            gy = 1 + np.floor((fy - 1) * mid)
            if (gx.sum() + 1) * (gy.sum() + 1) <= budget:
                lo = mid
            else:
                hi = mid
        fx = (1 + np.floor((fx - 1) * lo)).astype(np.intp)
        fy = (1 + np.floor((fy - 1) * lo)).astype(np.intp)
    return Refinement(_split(base[0, :, 0], fx), _split(base[:, 0, 1], fy), fx, fy)


def adaptive_mesh(
    surface: Surface, grid: Grid, cache: WarpCache | None = None, refine: bool = True
) -> tuple[MeshGeometry, dict[str, Any]]:
    """The mesh of ``surface`` on ``grid``, refined by :func:`refine_grid` (``refine``);
    kept in ``cache`` (:meth:`~adaproj_edge.warp.mesh.WarpCache.mesh`) under the
    surface's :func:`mesh_key`, so another warp of the same surface reuses it (with
    its crease unfolding and what is memoised on it).

    Returns
    -------
    The mesh, and meta: ``mesh`` (the refined grid) and ``refined`` (how many columns
    and rows each base column and row became), empty when nothing was refined.
    """
    if cache is None:
        return _adaptive_mesh(surface, grid, None, refine)
    mesh, meta = cache.mesh(
        mesh_key(surface, grid, refine), lambda: _adaptive_mesh(surface, grid, cache, refine)
    )
    return mesh, copy.deepcopy(meta)


def mesh_key(surface: Surface, grid: Grid, refine: bool) -> bytes:
    """What the adaptive mesh of ``surface`` on ``grid`` depends on, as a cache key: the
    surface's points (a digest of their bytes), its lattice's shape, the projector and
    the grid, the planes snapped on it (the mesh's :attr:`~MeshGeometry.planar`) and
    whether it was sensed (:func:`~adaproj_edge.geometry.creases.sensed`: where its
    mesh looks for ruled creases)."""
    proj = surface.projector
    points = np.ascontiguousarray(surface.points)
    digest = hashlib.blake2b(points.tobytes(), digest_size=16)
    digest.update(np.ascontiguousarray(proj.K, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(plane_equations(surface.meta), dtype=np.float64).tobytes())
    head = (
        f"adaptive:{refine}:{sensed(surface)}:{grid.cols}x{grid.rows}:{points.shape}:"
        f"{proj.width}x{proj.height}:"
    )
    return head.encode() + digest.digest()


def _adaptive_mesh(
    surface: Surface, grid: Grid, cache: WarpCache | None, refine: bool
) -> tuple[MeshGeometry, dict[str, Any]]:
    """:func:`adaptive_mesh`, made."""
    mesh = MeshGeometry.build(surface, grid, cache)
    if not refine:
        return mesh, {}
    refinement = refine_grid(surface, grid, mesh.curved_cells, base=mesh.grid_uv)
    if not refinement.refined:
        return mesh, {}
    mesh = MeshGeometry.build(surface, refinement.grid, cache, refinement.grid_uv, along=ALONG)
    return mesh, {
        "mesh": str(refinement.grid),
        "refined": {
            "columns": refinement.factor_x.tolist(),
            "rows": refinement.factor_y.tolist(),
        },
    }
