"""The mesh's fast paths give exactly what the straightforward computations give.

The mesh build samples the surface with one gather (:meth:`Surface.depth_at`), works
on component-first planes (:func:`~adaproj_edge.geometry.triangles.shapes_first`) and
numbers a grid triangle's sides instead of sorting them (``Topology.from_triangles``
with ``grid_cols``), and keeps the base grid's sampling (rays, bilinear stencil) for
every surface of the same lattice. Each is checked here, on random surfaces, against a plain
implementation of its definition written out below (the formulas the fast paths
replaced): integers and decisions (which triangles, which nodes are unknown) must be the
same, the values equal up to rounding (they are computed in another order, and numpy's
SIMD loops round a last bit differently by CPU), with a tolerance from each formula's
condition (:func:`rounded_alike`). A cache hit is compared with a fresh computation bit
for bit: that is the same code on the same inputs.
"""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.creases import crease_probes, unfold_creases
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import (
    conformal_coords,
    grid_triangles,
    triangle_normals,
    triangle_shapes,
    unique_edges,
)
from adaproj_edge.warp.adaptive import bends, sampled_bends
from adaproj_edge.warp.mesh import MeshGeometry, Topology, planar_shapes
from adaproj_edge.warp.sampling import SAMPLINGS, probe_index, probes
from adaproj_edge.warp.warpmap import Grid


def plain_depth_at(surface: Surface, uv: np.ndarray) -> np.ndarray:
    """Bilinear over the valid neighbours, neighbour by neighbour; NaN outside the frame
    or where the nearest node is invalid."""
    sx, sy = surface.lattice_scale()
    h, w = surface.shape
    gx, gy = uv[..., 0] / sx, uv[..., 1] / sy
    inside = (gx >= -0.5) & (gx <= w - 0.5) & (gy >= -0.5) & (gy <= h - 0.5)
    gx, gy = np.clip(gx, 0.0, w - 1.0), np.clip(gy, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(gx).astype(np.intp), w - 2)
    y0 = np.minimum(np.floor(gy).astype(np.intp), h - 2)
    fx, fy = gx - x0, gy - y0
    z = surface.points[..., 2].astype(np.float64)
    num, den = np.zeros(gx.shape), np.zeros(gx.shape)
    for dy, dx, wgt in (
        (0, 0, (1 - fx) * (1 - fy)),
        (0, 1, fx * (1 - fy)),
        (1, 0, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        zz = z[y0 + dy, x0 + dx]
        ok = np.isfinite(zz) & (wgt > 1e-9)
        num += np.where(ok, zz * wgt, 0.0)
        den += np.where(ok, wgt, 0.0)
    nearest = z[np.rint(gy).astype(np.intp), np.rint(gx).astype(np.intp)]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[~inside | ~np.isfinite(nearest) | (den <= 0)] = np.nan
    return out


def plain_shapes(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Conformal coordinates role by role, side lengths, planar frames of (T, 3, 3)."""
    n = triangle_normals(p)
    coords = np.empty((*p.shape[:2], 2))
    for k in range(3):
        p1, p2, p3 = p[:, k], p[:, (k + 1) % 3], p[:, (k + 2) % 3]
        e, d = p3 - p2, p1 - p2
        ee = np.sum(e * e, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            coords[:, k, 0] = np.sum(d * e, axis=1) / ee
            coords[:, k, 1] = np.sum(d * np.cross(n, e), axis=1) / ee
    sides = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    l1 = np.linalg.norm(e1, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        x2 = np.sum(e1 * e2, axis=1) / l1
    planar = np.zeros((p.shape[0], 3, 2))
    planar[:, 1, 0], planar[:, 2, 0] = l1, x2
    planar[:, 2, 1] = np.sqrt(np.maximum(np.sum(e2 * e2, axis=1) - x2 * x2, 0.0))
    return coords, sides, planar


def random_surface(seed: int, h: int, w: int, holes: float) -> Surface:
    """A bumpy surface facing the projector on an (h, w) lattice, ``holes`` of it unseen."""
    rng = np.random.default_rng(seed)
    projector = Projector.default()
    xs = np.linspace(0, projector.width - 1, w)
    ys = np.linspace(0, projector.height - 1, h)
    rays = projector.rays(np.stack(np.meshgrid(xs, ys), axis=-1))
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    a, b = rng.uniform(-3, 3, 2)
    depth = 1.5 + 0.1 * np.sin(a * 7 * xx + b * 5 * yy) + 0.01 * rng.standard_normal((h, w))
    points = (rays * depth[..., None]).astype(np.float32)
    points[rng.random((h, w)) < holes] = np.nan
    return Surface(points, projector)


same = np.testing.assert_array_equal
EPS = float(np.finfo(np.float64).eps)
ULPS = 64  # a few roundings per operation, a handful of operations per value


def rounded_alike(got: np.ndarray, want: np.ndarray, scale: np.ndarray | float) -> None:
    """``got`` equals ``want`` up to :data:`ULPS` roundings of size ``scale`` (broadcast
    against them: the magnitude of the terms times the formula's condition), with NaN and
    infinities in the same places. Any wrong term is off by far more."""
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    fin = np.isfinite(want)
    np.testing.assert_array_equal(got[~fin], want[~fin])  # infinities of the same sign
    tol = np.broadcast_to(ULPS * EPS * np.asarray(scale, dtype=np.float64), want.shape)
    np.testing.assert_array_less(np.abs(got - want)[fin], tol[fin] + np.finfo(float).tiny)


def shape_conditions(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle of ``p`` (T, 3, 3): the scale of its coordinates' rounding (the longest
    side over the shortest, times the condition L^2 / 2A, which grows as it flattens) and
    of its lengths' (the longest side times that condition); inf where degenerate."""
    sides = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
    longest, shortest = sides.max(axis=1), sides.min(axis=1)
    area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cond = np.where(area2 > 0, longest**2 / area2, np.inf)
        return np.nan_to_num(cond * longest / shortest, nan=np.inf), np.nan_to_num(
            cond * longest, nan=np.inf
        )


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    h=st.integers(2, 40),
    w=st.integers(2, 40),
    holes=st.sampled_from([0.0, 0.05, 0.3, 0.9]),
)
def test_depth_at_is_the_plain_bilinear(seed: int, h: int, w: int, holes: float) -> None:
    surface = random_surface(seed, h, w, holes)
    rng = np.random.default_rng(seed + 1)
    p = surface.projector
    uv = rng.uniform(-2, [p.width + 1, p.height + 1], (500, 2))
    uv[:100] = np.rint(uv[:100])  # on pixel centres, some on the lattice's nodes
    sx, sy = surface.lattice_scale()
    uv[100:150] = rng.integers(0, [w, h], (50, 2)) * [sx, sy]  # exactly on nodes
    uv[150:200, 0] = (rng.integers(0, w - 1, 50) + 0.5) * sx  # halfway: rounding ties
    # positive weights of positive depths: a few roundings relative to the depth
    want = plain_depth_at(surface, uv)
    rounded_alike(surface.depth_at(uv), want, np.abs(want))
    flat = want.reshape(10, 50)
    rounded_alike(surface.depth_at(uv.reshape(10, 50, 2)), flat, np.abs(flat))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), t=st.integers(1, 60), degenerate=st.booleans())
def test_triangle_shapes_are_the_plain_formulas(seed: int, t: int, degenerate: bool) -> None:
    rng = np.random.default_rng(seed)
    p = rng.standard_normal((t, 3, 3)) * rng.uniform(1e-3, 1e3)
    if degenerate:  # repeated corners, collinear ones, missing ones
        p[0, 1] = p[0, 0]
        p[-1, 2] = 0.5 * (p[-1, 0] + p[-1, 1])
        p[t // 2, rng.integers(0, 3)] = np.nan
    coords, sides, planar = triangle_shapes(p)
    want = plain_shapes(p)
    of_coords, of_lengths = shape_conditions(p)
    rounded_alike(coords, want[0], of_coords[:, None, None])
    rounded_alike(sides, want[1], want[1])  # norms: relative
    rounded_alike(planar, want[2], of_lengths[:, None, None])
    rounded_alike(conformal_coords(p), want[0], of_coords[:, None, None])
    rounded_alike(planar_shapes(p), want[2], of_lengths[:, None, None])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    rows=st.integers(1, 12),
    cols=st.integers(1, 12),
    share=st.sampled_from([0.1, 0.5, 0.9, 1.0]),
)
def test_grid_sides_are_the_sorted_unique_edges(
    seed: int, rows: int, cols: int, share: float
) -> None:
    rng = np.random.default_rng(seed)
    all_tris = grid_triangles(rows, cols)
    kept = np.flatnonzero(rng.random(all_tris.shape[0]) < share)
    if kept.size == 0:
        kept = np.array([rng.integers(0, all_tris.shape[0])])
    n = (rows + 1) * (cols + 1)
    fast = Topology.from_triangles(all_tris[kept], kept, n, grid_cols=cols)
    plain = Topology.from_triangles(all_tris[kept], kept, n)
    for name in ("verts", "tris", "edges", "inverse", "boundary"):
        a, b = getattr(fast, name), getattr(plain, name)
        assert a.dtype == b.dtype, name
        same(a, b)
    # and against the definition
    e = np.concatenate([plain.tris[:, [0, 1]], plain.tris[:, [1, 2]], plain.tris[:, [2, 0]]])
    edges, inverse, _ = unique_edges(e, plain.verts.size)
    same(fast.edges, edges)
    same(fast.inverse, inverse)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    rows=st.integers(2, 14),
    cols=st.integers(2, 14),
    holes=st.sampled_from([0.0, 0.02, 0.2]),
)
def test_mesh_build_is_the_plain_geometry(seed: int, rows: int, cols: int, holes: float) -> None:
    surface = random_surface(seed, 48, 64, holes)
    grid = Grid(cols, rows)
    try:
        mesh = MeshGeometry.build(surface, grid)
    except WarpError:  # too little of the grid meets the surface: nothing to compare
        assume(False)
        return
    uv = mesh.grid_uv.reshape(-1, 2)
    all_tris = grid_triangles(rows, cols)
    # the vertices are the surface at the grid's pixels
    want_pts = surface.projector.rays(uv) * plain_depth_at(surface, uv)[:, None]
    rounded_alike(mesh.points, want_pts, np.abs(want_pts).max(axis=1, keepdims=True))
    # kept: every corner seen, facing the projector, not degenerate (then its largest piece)
    tri = want_pts[all_tris]
    n = triangle_normals(tri)
    with np.errstate(invalid="ignore"):
        facing = np.all(np.isfinite(n), axis=1) & (np.sum(n * tri.mean(axis=1), axis=1) < 0)
    assert set(mesh.topology.rows.tolist()) <= set(np.flatnonzero(facing).tolist())
    # the shapes are those of the (unfolded) triangles
    cand = mesh.topology.cand
    unfolded = unfold_creases(surface, uv[cand], cand, mesh.points).points
    coords, sides, planar = plain_shapes(unfolded)
    of_coords, of_lengths = shape_conditions(unfolded)
    rounded_alike(mesh.coords, coords, of_coords[:, None, None])
    rounded_alike(mesh.shapes, planar, of_lengths[:, None, None])
    sums = np.zeros(mesh.edges.shape[0])
    np.add.at(sums, mesh.topology.inverse, sides.T.ravel())
    counts = np.bincount(mesh.topology.inverse, minlength=mesh.edges.shape[0])
    rounded_alike(mesh.lengths, sums / counts, sums / counts)  # norms, averaged: relative


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), rows=st.integers(1, 15), cols=st.integers(1, 15))
def test_shared_probes_are_each_triangles_crease_probes(seed: int, rows: int, cols: int) -> None:
    rng = np.random.default_rng(seed)
    xs = np.cumsum(rng.uniform(0.5, 40, cols + 1))
    ys = np.cumsum(rng.uniform(0.5, 40, rows + 1))
    grid_uv = np.stack(np.meshgrid(xs, ys), axis=-1)
    grid_uv += rng.uniform(-0.3, 0.3, grid_uv.shape)  # not even a tensor grid
    uv = grid_uv.reshape(-1, 2)
    want = crease_probes(uv[grid_triangles(rows, cols)])  # (T, 4, 2)
    got = probes(grid_uv)[probe_index(rows, cols)]  # (4, T, 2)
    rounded_alike(got.transpose(1, 0, 2), want, np.abs(uv).max())  # points between corners


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31), h=st.integers(2, 30), w=st.integers(2, 30), holes=st.floats(0, 1)
)
def test_valid_fraction_is_the_mean(seed: int, h: int, w: int, holes: float) -> None:
    surface = random_surface(seed, h, w, holes)
    assert surface.valid_fraction == float(np.mean(surface.valid))
    assert type(surface.valid_fraction) is float


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), h=st.integers(2, 12), w=st.integers(2, 12))
def test_valid_fraction_counts_what_a_ray_meets(seed: int, h: int, w: int) -> None:
    """Counted once when the surface is made: a node with any coordinate not finite, or
    behind the projector, does not count (ground truth counted here, node by node)."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(-1, 2, (h, w, 3)).astype(np.float32)  # z <= 0 behind: some
    bad = rng.random((h, w, 3)) < 0.1
    points[bad] = rng.choice([np.nan, np.inf, -np.inf], size=int(bad.sum()))
    meets = sum(
        all(np.isfinite(points[i, j])) and points[i, j, 2] > 0 for i in range(h) for j in range(w)
    )
    surface = Surface(points, Projector.default())
    assert surface.valid_fraction == meets / (h * w)
    assert int(np.count_nonzero(surface.valid)) == meets


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), holes=st.sampled_from([0.0, 0.1]))
def test_a_kept_sampling_serves_every_surface_of_the_lattice(seed: int, holes: float) -> None:
    """The base grid's sampling (rays, stencil) is made once per grid, projector and
    lattice shape: a mesh of another surface on it is the mesh made from scratch."""
    first, second = random_surface(seed, 40, 60, holes), random_surface(seed + 1, 40, 60, holes)
    uv = np.random.default_rng(seed).uniform(0, 1000, (300, 2))
    same(first.stencil(uv).depth(second.points), second.depth_at(uv))  # what depth_at runs
    grid = Grid(12, 9)
    MeshGeometry.build(first, grid)  # keeps the sampling
    kept = MeshGeometry.build(second, grid)
    SAMPLINGS.clear()
    fresh = MeshGeometry.build(second, grid)
    for name in ("grid_uv", "points", "coords", "lengths", "shapes", "tris", "edges"):
        same(getattr(kept, name), getattr(fresh, name))


def plain_bends(
    surface: Surface, grid_uv: np.ndarray, sample: float, kinks: bool
) -> list[np.ndarray]:
    """The per-sample bends (:func:`sampled_bends`), the worst in each cell, cell by
    cell."""
    per_sample, xs, ys, step_x, step_y = sampled_bends(surface, sample, kinks)
    cols, rows = grid_uv[0, :, 0], grid_uv[:, 0, 1]
    ci = np.clip(np.searchsorted(cols, xs, side="right") - 1, 0, cols.size - 2)
    ri = np.clip(np.searchsorted(rows, ys, side="right") - 1, 0, rows.size - 2)
    wide = (np.diff(cols)[ci] / step_x)[None, :]
    tall = (np.diff(rows)[ri] / step_y)[:, None]
    scales = (wide, tall, wide, tall, wide * tall)  # x, y, turn_x, turn_y, two_way
    out = []
    for per, scale in zip(per_sample, scales, strict=True):
        per = per * scale
        per = np.where(np.isfinite(per), per, 0.0)
        worst = np.zeros((rows.size - 1, cols.size - 1))
        for r in range(rows.size - 1):
            for c in range(cols.size - 1):
                block = per[np.ix_(ri == r, ci == c)]
                if block.size:
                    worst[r, c] = block.max()
        out.append(worst)
    return out


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    rows=st.integers(1, 12),
    cols=st.integers(1, 12),
    sample=st.sampled_from([8.0, 16.0, 40.0]),
    kinks=st.booleans(),
)
def test_bends_are_the_plain_worst_per_cell(
    seed: int, rows: int, cols: int, sample: float, kinks: bool
) -> None:
    surface = random_surface(seed, 80, 120, 0.02)
    p = surface.projector
    rng = np.random.default_rng(seed)
    xs = np.unique(np.rint(rng.uniform(0, p.width - 1, cols + 1)))
    ys = np.unique(np.rint(rng.uniform(0, p.height - 1, rows + 1)))
    assume(xs.size > 1 and ys.size > 1)
    grid_uv = np.stack(np.meshgrid(xs, ys), axis=-1)
    got = bends(surface, grid_uv, sample, kinks)
    again = bends(surface, grid_uv, sample, kinks)  # the cells kept from the first call
    want = plain_bends(surface, grid_uv, sample, kinks)
    assert len(got) == len(want) == 5
    for a, b, c in zip(got, again, want, strict=True):
        rounded_alike(a, c, np.abs(c))  # the largest of products: relative
        same(b, a)  # the same code, served from what it kept
