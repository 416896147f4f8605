"""A wall with something in front of it: the warp keeps the wall undistorted and puts the
distortion on the thing in front (the planes a surface was snapped to, listed in its
meta, weigh more in every solve)."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.planes import PLANES_KEY
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp

P = Projector.default()
SHAPE = (41, 41)
HEIGHT = 0.4  # how far the dome stands proud of the wall (m)
NORMAL = np.array([0.5, 0.0, -1.0]) / np.hypot(0.5, 1.0)  # a wall turned 27 deg
OFFSET = -2.0 / np.hypot(0.5, 1.0)  # 2 m ahead on the axis


def wall_depth(rays: FloatArray) -> FloatArray:
    """Depth of the wall along ``rays`` (..., 3; z = 1)."""
    out: FloatArray = OFFSET / (rays @ NORMAL)
    return out


def wall_with_a_bump() -> tuple[Surface, FloatArray]:
    """The wall with a smooth dome 40 cm proud on the right third of the frame (the
    chair in front of the wall), as a lattice; and the wall's share of every lattice
    node (1: on the wall)."""
    uv = lattice_uv(P, SHAPE)
    rays = P.rays(uv)
    z = wall_depth(rays)
    # a dome of radius 0.25 of the frame's width about (0.8 W, 0.5 H): cos^2 profile
    r = np.hypot(uv[..., 0] - 0.8 * P.width, uv[..., 1] - 0.5 * P.height) / (0.25 * P.width)
    bump = np.where(r < 1.0, HEIGHT * np.cos(0.5 * np.pi * np.minimum(r, 1.0)) ** 2, 0.0)
    points = rays * (z - bump)[..., None]
    return Surface(points.astype(np.float32), P), (bump == 0.0).astype(np.float64)


def wall_distortion(
    surface: Surface, mode: str, on_wall_lattice: FloatArray
) -> tuple[float, float]:
    """(mean angle distortion, size inconsistency) of the warp of ``surface`` over its
    grid triangles that lie on the wall, measured on the wall itself: each vertex's
    point is where its projector ray meets the analytic wall (not the warp's mesh)."""
    warp = compute_warp(surface, (800, 600), None, WarpSettings(mode=mode))  # type: ignore[arg-type]
    uv = warp.grid_uv.reshape(-1, 2)
    X = P.rays(uv) * wall_depth(P.rays(uv))[:, None]
    xy = warp.image_xy.reshape(-1, 2)
    # a vertex is on the wall when the bump is nowhere near it (every lattice node within
    # a lattice cell of it on the wall)
    rows, cols = SHAPE
    gi = np.clip(np.rint(uv[:, 1] / (P.height - 1) * (rows - 1)).astype(int), 1, rows - 2)
    gj = np.clip(np.rint(uv[:, 0] / (P.width - 1) * (cols - 1)).astype(int), 1, cols - 2)
    near = [on_wall_lattice[gi + di, gj + dj] for di in (-1, 0, 1) for dj in (-1, 0, 1)]
    flat = np.min(near, axis=0) > 0
    r, c = warp.grid_uv.shape[:2]
    ii, jj = np.meshgrid(np.arange(r - 1), np.arange(c - 1), indexing="ij")
    a, b, d = ii * c + jj, ii * c + jj + 1, (ii + 1) * c + jj + 1
    e = (ii + 1) * c + jj
    tris = np.concatenate(
        [np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, e], -1).reshape(-1, 3)]
    )
    tris = tris[flat[tris].all(axis=1) & np.isfinite(xy[tris]).all(axis=(1, 2))]
    dc = np.stack([xy[tris[:, 1]] - xy[tris[:, 0]], xy[tris[:, 2]] - xy[tris[:, 0]]], axis=2)
    dX = np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]], axis=2)
    J = dX @ np.linalg.inv(dc)
    sv = np.linalg.svd(J, compute_uv=False)
    assert len(J) > 200  # most of the frame is wall
    return float(np.mean(sv[:, 0] / sv[:, 1] - 1.0)), float(
        np.std(0.5 * np.log(sv[:, 0] * sv[:, 1]))
    )


@pytest.mark.parametrize("mode", ["conformal", "content"])
def test_a_snapped_wall_stays_undistorted_beside_a_bump(mode: str) -> None:
    """The conformal warp and the content-free warp E' (no content map): with the wall
    listed as a snapped plane its angle and size distortion fall to a small fraction of
    what the uniform weights spread onto it from the dome (0.023 and 0.24 today).
    Tolerances: the wall's own figure, were the dome absent, is float32 rounding (~1e-6);
    the weights (1 + 100 on the wall's triangles) leave the wall about a part in 100 of
    the energy's residual, so 0.1x of the uniform warp's figure; and the absolute lines
    of the issue (0.02), a quarter of it for the angle."""
    surface, on_wall = wall_with_a_bump()
    before = wall_distortion(surface, mode, on_wall)
    snapped = Surface(surface.points, P, {PLANES_KEY: [[*NORMAL, OFFSET]]})
    after = wall_distortion(snapped, mode, on_wall)
    assert before[0] > 0.01 and before[1] > 0.01  # the dome does distort the wall
    assert after[0] < 0.1 * before[0] and after[0] < 0.005, (before, after)
    assert after[1] < 0.1 * before[1] and after[1] < 0.02, (before, after)


@pytest.mark.parametrize("up", [(0.4, -1.0, 0.0), (-0.5, -1.0, 0.2)])
def test_a_snapped_wall_stays_upright_beside_a_bump(up: tuple[float, float, float]) -> None:
    """A rolled, pitched device (gravity's up ``up`` in frame P): the content's vertical on
    the snapped wall is gravity's there. The plane-held warp bends the dome more, and its
    triangles' votes for "down" turn with it (1.6-2.9 deg on the wall when every
    triangle voted alike); the wall's triangles vote at their weight in the solve.
    Measured independently of the warp's mesh: an affine fit of the analytic wall's points
    (rays of the grid's vertices met with the wall) against their content positions over
    the frame's left half (all wall: the dome covers x > 0.55 W), its -y against gravity
    projected on the wall. Tolerance 0.5 deg: the wall keeps about a part in 100 of the
    residual (0.1 deg here), well under the issue's 2 deg line and the 1.6 deg before."""
    surface, _ = wall_with_a_bump()
    snapped = Surface(surface.points, P, {PLANES_KEY: [[*NORMAL, OFFSET]]})
    warp = compute_warp(snapped, (800, 600), None, WarpSettings(mode="content", up=up))
    uv = warp.grid_uv.reshape(-1, 2)
    X = P.rays(uv) * wall_depth(P.rays(uv))[:, None]
    xy = warp.image_xy.reshape(-1, 2)
    left = np.isfinite(xy).all(axis=1) & (uv[:, 0] < 0.5 * P.width)
    coef = np.linalg.lstsq(np.c_[xy[left], np.ones(left.sum())], X[left], rcond=None)[0]
    g = np.asarray(up) / np.linalg.norm(up)
    ref, shown = g - (g @ NORMAL) * NORMAL, -coef[1] + (coef[1] @ NORMAL) * NORMAL
    cos = float(ref @ shown / (np.linalg.norm(ref) * np.linalg.norm(shown)))
    assert np.degrees(np.arccos(min(1.0, cos))) < 0.5
