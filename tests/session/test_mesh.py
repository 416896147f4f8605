"""Triangle-mesh surfaces: file readers, and the simulator's depth on meshes."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import Plane, Sphere
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.geometry.mesh_surface import MeshSurface, load_mesh, ply_bytes, uv_sphere
from adaproj_edge.geometry.rotations import rotation_of
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate, true_surface

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


def sagitta(mesh: MeshSurface, centre: FloatArray, r: float) -> float:
    """Largest gap between a sphere and the mesh inscribed in it (its chord error):
    each triangle's plane cuts the sphere in a circle through its three corners, and
    the sphere rises above that plane by at most r - sqrt(r^2 - rc^2), rc the
    triangle's circumradius."""
    tri = mesh.vertices[mesh.faces] - centre
    a = np.linalg.norm(tri[:, 1] - tri[:, 2], axis=1)
    b = np.linalg.norm(tri[:, 2] - tri[:, 0], axis=1)
    c = np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1)
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ok = area2 > 1e-12  # the poles' degenerate triangles cover nothing
    rc = a[ok] * b[ok] * c[ok] / (2 * area2[ok])
    return float(np.max(r - np.sqrt(np.maximum(r**2 - rc**2, 0.0))))


def test_simulated_depth_of_a_fine_mesh_is_the_analytic_one_within_its_chord_error() -> None:
    centre, r = np.array([0.05, 0.0, 2.2]), 0.62
    mesh = uv_sphere((0.05, 0.0, 2.2), r, 96, 192)  # 36,864 triangles
    sphere = Sphere("s", (0.05, 0.0, 2.2), r, False)
    d = DepthCameraModel.oak_d(320, 200)
    q = np.array([0.05, -0.08, 0.02, 0.99])  # (x, y, z, w): a few degrees off axis
    R = rotation_of(tuple(q / np.linalg.norm(q)))
    t = np.array([0.03, -0.02, 0.1])
    got = Scene(mesh, {}).points_seen(d.K, d.width, d.height, R, t)[..., 2]
    exact = Scene(sphere, {}).points_seen(d.K, d.width, d.height, R, t)
    # incidence on the true sphere: the depth error along a ray is the gap / cos
    hit_w = exact @ R.T + t
    normal = (hit_w - centre) / r
    ray_w = hit_w - t
    cos = np.abs(np.sum(normal * ray_w, axis=-1)) / np.linalg.norm(ray_w, axis=-1)
    front = np.isfinite(exact[..., 2]) & (cos > 0.3)
    assert front.mean() > 0.2
    assert np.isfinite(got[front]).all()
    err = got[front] - exact[front][:, 2]  # the facets lie inside the sphere: farther
    tol = sagitta(mesh, centre, r) / cos[front]
    assert np.all(err >= -1e-9) and np.all(err <= tol + 1e-9)
    assert err.max() > 0.2 * tol.min()  # the bound is not vacuous
    # and the silhouettes agree up to the chord error (a pixel or two at the rim)
    edge = np.isfinite(got) != np.isfinite(exact[..., 2])
    assert edge.sum() < 0.01 * np.isfinite(exact[..., 2]).sum()


def test_the_scorers_truth_on_a_mesh_is_the_analytic_one_within_its_chord_error() -> None:
    """``true_surface`` (what the replay scores against) casts the mesh the same way."""
    centre, r = np.array([0.05, 0.0, 2.2]), 0.62
    mesh = uv_sphere((0.05, 0.0, 2.2), r, 96, 192)
    pose = TruthPose(0, (0.02, -0.03, 0.05), (0.03, -0.02, 0.01, 0.9993))
    proj = Calibration.default().projector
    got = true_surface(Scene(mesh, {}), pose, proj, (41, 61)).points[..., 2]
    exact = true_surface(Scene(Sphere("s", (0.05, 0.0, 2.2), r, False), {}), pose, proj, (41, 61))
    pts = exact.points.astype(np.float64)
    z = pts[..., 2]
    ray_w = pts @ rotation_of(pose.quaternion).T  # projector -> world, from its centre
    normal = (ray_w + np.asarray(pose.position) - centre) / r
    cos = np.abs(np.sum(normal * ray_w, axis=-1)) / np.linalg.norm(ray_w, axis=-1)
    front = np.isfinite(z) & (cos > 0.3)
    assert front.mean() > 0.2 and np.isfinite(got[front]).all()
    # float32 points: 1e-6; the facets are farther by up to the chord error / cos
    tol = sagitta(mesh, centre, r) / cos[front] + 1e-6
    assert np.all(np.abs(got[front] - z[front]) <= tol)


def test_a_mesh_reaching_behind_the_camera_is_seen() -> None:
    """A floor under the device extends behind it (a room scan): its front part shows."""
    v = np.array([[-5, 0.4, -5], [5, 0.4, -5], [5, 0.4, 5], [-5, 0.4, 5]], float)
    floor = MeshSurface("floor", v, np.array([[0, 1, 2], [0, 2, 3]]))
    plane = Plane("floor", (0.0, -1.0, 0.0), -0.4)
    d = DepthCameraModel.oak_d(64, 40)
    R, t = np.eye(3), np.zeros(3)
    got = Scene(floor, {}).points_seen(d.K, d.width, d.height, R, t)
    exact = Scene(plane, {}).points_seen(d.K, d.width, d.height, R, t)
    inside = np.isfinite(exact[..., 2]) & (exact[..., 2] < 5)
    assert 0.3 < inside.mean() < 0.6  # the lower half of the picture
    assert np.allclose(got[inside], exact[inside], rtol=1e-12, atol=1e-12)


FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "sessions"


def test_simulating_the_mesh_fixture_again_gives_its_depth_frames_exactly() -> None:
    """The caster gives the committed session's hits: same frames, bit for bit.

    Settings as tools/make_fixtures.py made ``mesh-sphere.mcap`` (3 s, 5 fps, seed 14,
    the default hand and the default depth noise: the OAK-D's).
    """
    settings = SimulationSettings(seconds=3.0, depth_fps=5.0, seed=14)
    recs = simulate(Scene.load(str(FIXTURES / "mesh-sphere.ply")), Calibration.default(), settings)
    new = [r.depth_mm for r in recs if isinstance(r, DepthFrame)]
    old = [f.depth_mm for f in read_session(FIXTURES / "mesh-sphere.mcap").depth]
    assert len(new) == len(old) == 15
    for a, b in zip(new, old, strict=True):
        assert np.array_equal(a, b)


def test_mesh_validation() -> None:
    with pytest.raises(InputError):
        MeshSurface("x", np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(InputError):
        MeshSurface("x", np.zeros((3, 2)), np.array([[0, 1, 2]]))
