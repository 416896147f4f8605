"""Triangle-mesh surfaces: file readers, ray casting, rasterising."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import Sphere, ray_cast
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.geometry.mesh_surface import (
    MeshSurface,
    load_mesh,
    ply_bytes,
    rasterize_depth,
    uv_sphere,
)

QUAD_OBJ = """# a 2 m square at z = 1.5, as a quad and with texture/normal indices
v -1 -1 1.5
v 1 -1 1.5
v 1 1 1.5
v -1 1 1.5
vt 0 0
f 1/1/1 2/1/1 3/1/1 4/1/1
"""


def test_obj_quad_is_fan_triangulated(tmp_path: Path) -> None:
    (tmp_path / "q.obj").write_text(QUAD_OBJ)
    m = load_mesh(tmp_path / "q.obj")
    assert m.faces.shape == (2, 3)
    t = m.intersect(np.zeros(3), np.array([[0.1, 0.2, 1.0], [2.0, 0.0, 1.0]]))
    assert t[0] == pytest.approx(1.5) and np.isnan(t[1])


def test_ply_binary_and_ascii(tmp_path: Path) -> None:
    m = uv_sphere((0.0, 0.0, 2.0), 0.5, 8, 16)
    (tmp_path / "s.ply").write_bytes(ply_bytes(m))
    b = load_mesh(tmp_path / "s.ply")
    assert np.allclose(b.vertices, m.vertices, atol=1e-6) and np.array_equal(b.faces, m.faces)
    lines = ["ply", "format ascii 1.0", "element vertex 3", "property float x",
             "property float y", "property float z", "property uchar red",
             "element face 1", "property list uchar int vertex_indices", "end_header",
             "0 0 1 255", "1 0 1 255", "0 1 1 255", "3 0 1 2"]  # fmt: skip
    (tmp_path / "t.ply").write_text("\n".join(lines) + "\n")
    t = load_mesh(tmp_path / "t.ply")
    assert t.faces.tolist() == [[0, 1, 2]] and t.vertices[1].tolist() == [1, 0, 1]


SHORT_PLY = (
    b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n"
    b"property float x\nproperty float y\nproperty float z\nend_header\n"
    + struct.pack("<3f", 0, 0, 1)
)


@pytest.mark.parametrize(
    ("name", "data"),
    [
        ("bad.ply", b"ply\nformat binary_big_endian 1.0\nend_header\n"),
        ("bad2.ply", b"not a ply"),
        ("short.ply", SHORT_PLY),
        ("bad.obj", b"v 0 0 1\nv 1 0 1\nf 1 2 7\n"),
        ("empty.obj", b"# nothing\n"),
        ("m.stl", b"solid"),
    ],
)  # fmt: skip
def test_malformed_meshes(tmp_path: Path, name: str, data: bytes) -> None:
    (tmp_path / name).write_bytes(data)
    with pytest.raises(InputError):
        load_mesh(tmp_path / name)


def test_missing_mesh(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        load_mesh(tmp_path / "none.obj")


def test_rasterized_depth_matches_ray_casting() -> None:
    d = DepthCameraModel.oak_d(80, 50)
    m = uv_sphere((0.05, 0.0, 2.2), 0.62, 16, 32)
    R = np.eye(3)
    t = np.array([0.01, -0.02, 0.0])
    z = rasterize_depth(m, d.K, d.width, d.height, R, t)
    v, u = np.mgrid[0 : d.height, 0 : d.width].astype(float)
    rays = np.stack([(u - d.K[0, 2]) / d.K[0, 0], (v - d.K[1, 2]) / d.K[1, 1], np.ones_like(u)], -1)
    tm = m.intersect(t, rays)
    both = np.isfinite(z) & np.isfinite(tm)
    assert both.mean() > 0.2
    assert np.abs(z[both] - tm[both]).max() < 1e-6
    exact = ray_cast(Sphere("s", (0.05, 0.0, 2.2), 0.62, False), t, rays)[..., 2]
    assert np.nanmedian(np.abs(z - exact)) < 0.01  # facets vs the true sphere


def test_mesh_validation() -> None:
    with pytest.raises(InputError):
        MeshSurface("x", np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(InputError):
        MeshSurface("x", np.zeros((3, 2)), np.array([[0, 1, 2]]))
