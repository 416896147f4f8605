"""Mesh ray casting through the BVH (geometry/mesh_bvh.py) against the brute force
(geometry/ray_triangle.py) and an oracle computed here, triangle by triangle.

The BVH finds the nearest triangle in float32 and the distance is taken in float64,
so where a ray meets a triangle well inside it the two casters agree to float64
rounding. Rays that pass within float32 reach of a triangle's edge (grazing), or
meet two triangles at the same distance, may pick either: the oracle accepts
exactly those.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry import mesh_bvh
from adaproj_edge.geometry.mesh_surface import MeshSurface, load_mesh, ply_bytes, uv_sphere
from adaproj_edge.geometry.ray_triangle import intersect_brute_force

TILT = np.array([0.0, 0.0, 1e-3])  # keeps drawn vectors off zero
EDGE_TOL = 1e-5  # barycentric: what float32 coordinates of metre-sized scenes can resolve
TIE_TOL = 1e-5  # ray parameter (dirs about unit length): hits this close are a tie


def oracle_ok(
    mesh: MeshSurface, origins: FloatArray, dirs: FloatArray, t: FloatArray
) -> NDArray[np.bool_]:
    """Assert each ``t`` is a right answer: the nearest hit, up to grazes and ties.

    Every ray is intersected with every triangle here, with a 3x3 solve of
    o + t d = v0 + u e1 + v e2 (not the code under test). Returns which rays are
    clear cases (no graze or tie decides them): there ``t`` is the only answer.
    """
    tri = mesh.vertices[mesh.faces]
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    clear = np.zeros(len(dirs), bool)
    for i, (o, d, got) in enumerate(zip(origins, dirs, t, strict=True)):
        a = np.stack([np.broadcast_to(-d, e1.shape), e1, e2], axis=-1)  # (M, 3, 3)
        det = np.linalg.det(a)
        usable = np.abs(det) > 1e-12  # as the casters: closer to parallel is no hit
        sol = np.full((len(tri), 3), np.nan)
        sol[usable] = np.linalg.solve(a[usable], (o - v0)[usable][..., None])[..., 0]
        tt, u, v = sol.T
        margin = np.minimum(np.minimum(u, v), 1 - u - v)
        with np.errstate(invalid="ignore"):
            near = usable & (tt > 1e-9) & (margin >= -EDGE_TOL)  # hit, or grazed
            # certainly hit: well inside, not so close to parallel that t is ill-posed,
            # and not within float32 reach of the origin
            robust = near & (margin >= EDGE_TOL) & (np.abs(det) > 1e-6) & (tt > TIE_TOL)
        first = tt[robust].min() if robust.any() else np.inf
        if np.isnan(got):
            assert not robust.any(), f"missed a clear hit at t={first}"
        else:
            # float64 rounding of o - v0 (coordinates of a few units), over |det|
            tol = np.where(np.abs(det) > 1e-6, 1e-12 * (1 + np.abs(tt)) / np.abs(det), 1e-3)
            assert np.any(near & (np.abs(tt - got) <= tol)), "t of no triangle"
            assert got <= first + TIE_TOL, "a nearer clear hit exists"
        clear[i] = np.count_nonzero(near & (tt <= first + TIE_TOL)) == np.count_nonzero(
            robust & (tt <= first)
        )
    return clear


# ---------------------------------------------------------------- random triangle soups
@st.composite
def soups(draw: st.DrawFn) -> MeshSurface:
    """Well-shaped triangles (angles >= 20 deg) at random places, sizes and tilts."""
    n = draw(st.integers(1, 25))
    coord = st.floats(-2.0, 2.0, allow_nan=False)
    tris = []
    for _ in range(n):
        c = np.array([draw(coord) for _ in range(3)])
        normal = np.array([draw(coord) for _ in range(3)]) + TILT
        normal /= np.linalg.norm(normal)
        a = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(normal, a)
        r = draw(st.floats(0.1, 1.0))
        th0 = draw(st.floats(0.0, 2 * np.pi))
        th = [th0 + k * 2 * np.pi / 3 + draw(st.floats(-0.35, 0.35)) for k in range(3)]
        tris.append([c + r * (np.cos(x) * a + np.sin(x) * b) for x in th])
    v = np.asarray(tris).reshape(-1, 3)
    return MeshSurface("soup", v, np.arange(len(v)).reshape(-1, 3))


@st.composite
def rays_at(draw: st.DrawFn, mesh: MeshSurface) -> tuple[FloatArray, FloatArray]:
    """Rays of four kinds: anywhere, through a vertex, through an edge, and away."""
    v = mesh.vertices
    centre = v.mean(axis=0)
    radius = float(np.linalg.norm(v - centre, axis=1).max())
    unit = st.floats(-1.0, 1.0)
    origins, dirs = [], []
    for _ in range(draw(st.integers(1, 12))):
        o = np.array([draw(st.floats(-4.0, 4.0)) for _ in range(3)])
        kind = draw(st.sampled_from(["any", "vertex", "edge", "away"]))
        if kind == "any":
            d = np.array([draw(unit) for _ in range(3)])
        elif kind == "vertex":
            d = v[draw(st.integers(0, len(v) - 1))] - o
        elif kind == "edge":
            f = mesh.faces[draw(st.integers(0, len(mesh.faces) - 1))]
            k = draw(st.integers(0, 2))
            s = draw(st.sampled_from([0.5, 0.25, 1 / 3, 0.9]))
            d = (1 - s) * v[f[k]] + s * v[f[(k + 1) % 3]] - o
        else:  # from outside the bounding sphere, moving away from it: cannot hit
            o = centre + (o + TILT) / np.linalg.norm(o + TILT) * (radius + 0.5)
            d = o - centre + np.array([draw(unit) for _ in range(3)]) * 0.1
        n = np.linalg.norm(d)
        if n < 1e-3:
            continue
        origins.append(o)
        dirs.append(d / n * draw(st.floats(0.5, 2.0)))
    if not origins:
        origins, dirs = [centre + np.array([0.0, 0.0, radius + 1.0])], [np.array([0.0, 0.0, -1.0])]
    return np.asarray(origins), np.asarray(dirs)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_bvh_agrees_with_brute_force_on_triangle_soups(data: st.DataObject) -> None:
    mesh = data.draw(soups())
    o, d = data.draw(rays_at(mesh))
    got = mesh.intersect(o, d)
    ref = intersect_brute_force(mesh.vertices, mesh.faces, o, d)
    clear = oracle_ok(mesh, o, d, ref)  # the oracle accepts the reference ...
    oracle_ok(mesh, o, d, got)  # ... and the BVH
    # and where no graze or tie decides, they give the same numbers
    same = np.isclose(got, ref, rtol=1e-12, atol=0.0, equal_nan=True)
    assert same[clear].all()


def test_bvh_is_what_meshes_cast_with() -> None:
    """With the sim extra installed (the dev install), no silent fall back to brute force."""
    m = uv_sphere((0.0, 0.0, 2.0), 0.5, 6, 12)
    assert isinstance(m._cast.__self__, mesh_bvh.MeshBvh)  # type: ignore[attr-defined]


def test_rays_through_vertices_and_edges_of_a_closed_mesh_hit_them() -> None:
    """No ray slips between the triangles of a closed mesh (watertight), in float64 t."""
    m = uv_sphere((0.05, -0.02, 2.0), 0.5, 12, 24)
    o = np.array([0.02, 0.01, 0.0])
    edges = m.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    targets = np.concatenate([m.vertices, m.vertices[edges].mean(axis=1)])
    centre = np.array([0.05, -0.02, 2.0])
    facing = np.einsum("ij,j->i", targets - centre, o - centre)
    targets = targets[facing > 0.3 * 0.5 * np.linalg.norm(o - centre)]  # on the near side
    assert len(targets) > 200
    t = m.intersect(o, targets - o)
    assert np.abs(t - 1.0).max() < 1e-9, targets[
        ~(np.abs(t - 1.0) < 1e-9)
    ]  # each ray's first hit is the point it aims at


def test_misses_degenerate_rays_and_origins_on_the_surface() -> None:
    # two parallel unit squares, at z = 1 and z = 2
    v = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    v = np.concatenate([v, v + np.array([0, 0, 1])])
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    m = MeshSurface("two squares", v, f)
    o = np.array(
        [[0.3, 0.4, 0.0], [0.3, 0.4, 0.0], [np.nan, 0, 0], [0.3, 0.4, 1.0], [0.3, 0.4, 1.0]]
    )
    d = np.array([[0, 0, 0], [0, 0, np.inf], [0, 0, 1], [0, 0, 1], [0, 0, -1]], float)
    t = m.intersect(o, d)
    assert np.isnan(t[:3]).all()  # zero, infinite and NaN rays
    assert t[3] == pytest.approx(1.0)  # from on the first square: the second one, t > 0
    assert np.isnan(t[4])  # from on the first square, away from both
    ref = intersect_brute_force(v, f, o, d)
    assert np.array_equal(np.isnan(t), np.isnan(ref)) and t[3] == pytest.approx(ref[3])


def test_origins_broadcast_and_shapes_are_kept() -> None:
    m = uv_sphere((0.0, 0.0, 2.0), 0.5, 8, 16)
    dirs = np.zeros((4, 5, 3))
    dirs[..., 2] = 1.0
    dirs[..., 0] = np.linspace(-0.2, 0.2, 5)
    t = m.intersect(np.zeros(3), dirs)
    assert t.shape == (4, 5) and np.isfinite(t).all()
    assert m.intersect(np.zeros(3), np.zeros((0, 3))).shape == (0,)


# ---------------------------------------------------------------- meshes from files
def camera_rays(width: int, height: int, f: float) -> FloatArray:
    v, u = np.mgrid[0:height, 0:width].astype(float)
    return np.stack([(u - width / 2) / f, (v - height / 2) / f, np.ones_like(u)], axis=-1)


def write_obj(path: Path, v: FloatArray, faces: NDArray[np.int64]) -> None:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("fmt", ["ply", "obj"])
def test_loaded_meshes_cast_like_brute_force(tmp_path: Path, fmt: str) -> None:
    # a sphere in front of a bumpy wall, as one mesh
    s = uv_sphere((0.1, 0.05, 1.6), 0.35, 14, 28)
    g = np.linspace(-1.5, 1.5, 15)
    x, y = np.meshgrid(g, g)
    wall = np.stack([x, y, 2.4 + 0.05 * np.sin(3 * x) * np.cos(2 * y)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(14), np.arange(14), indexing="ij")
    a = (i * 15 + j).ravel()
    quads = np.concatenate([np.stack([a, a + 15, a + 1], 1), np.stack([a + 1, a + 15, a + 16], 1)])
    v = np.concatenate([s.vertices, wall])
    f = np.concatenate([s.faces, quads + len(s.vertices)])
    path = tmp_path / f"scene.{fmt}"
    if fmt == "ply":
        path.write_bytes(ply_bytes(MeshSurface("scene", v, f)))
    else:
        write_obj(path, v, f)
    m = load_mesh(path)
    dirs = camera_rays(48, 30, 30.0).reshape(-1, 3)
    o = np.broadcast_to([0.01, -0.02, 0.0], dirs.shape)
    got = m.intersect(o, dirs)
    ref = intersect_brute_force(m.vertices, m.faces, np.ascontiguousarray(o), dirs)
    assert 0.1 < np.isnan(got).mean() < 0.7  # the wall ends inside the view
    same = (np.isnan(got) & np.isnan(ref)) | (np.abs(got - ref) <= 1e-12 * np.abs(ref))
    assert same.mean() > 0.99
    bad = ~same
    oracle_ok(m, o[bad], dirs[bad], got[bad])


# ---------------------------------------------------------------- set-up and fall back
def test_the_bvh_is_built_once_per_mesh(monkeypatch: pytest.MonkeyPatch) -> None:
    built = []
    original = mesh_bvh.MeshBvh.__init__

    def counting(self: mesh_bvh.MeshBvh, *args: NDArray[np.generic]) -> None:
        built.append(1)
        original(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(mesh_bvh.MeshBvh, "__init__", counting)
    m = uv_sphere((0.0, 0.0, 2.0), 0.5, 8, 16)
    dirs = camera_rays(8, 5, 10.0)
    first = m.intersect(np.zeros(3), dirs)
    second = m.intersect(np.zeros(3), dirs)
    assert len(built) == 1 and np.array_equal(first, second, equal_nan=True)


def test_without_warp_meshes_are_cast_by_brute_force_with_a_warning(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setitem(sys.modules, "adaproj_edge.geometry.mesh_bvh", None)  # not installed
    m = uv_sphere((0.0, 0.0, 2.0), 0.5, 8, 16)
    dirs = camera_rays(16, 10, 12.0)
    with caplog.at_level(logging.WARNING):
        got = m.intersect(np.zeros(3), dirs)
    assert "pip install 'adaproj-edge[sim]'" in caplog.text and "uv-sphere" in caplog.text
    ref = intersect_brute_force(m.vertices, m.faces, np.zeros((160, 3)), dirs.reshape(-1, 3))
    assert np.array_equal(got.ravel(), ref, equal_nan=True)
