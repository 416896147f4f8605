"""Surface and Warp files: round trips and the errors bad files give."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import InputError, SurfaceError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.maps import map_from_warp
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid, Warp


def test_surface_round_trip_keeps_points_and_lattice(tmp_path: Path) -> None:
    s = simulate_surface("sphere-convex", step=8)
    s.save(tmp_path / "s.npz")
    t = Surface.load(tmp_path / "s.npz")
    np.testing.assert_array_equal(t.points, s.points)
    np.testing.assert_array_equal(t.projector.K, s.projector.K)
    assert (t.projector.width, t.projector.height) == (1280, 800)
    assert t.meta["name"] == "sphere-convex"


def test_lattice_surface_samples_like_the_dense_one() -> None:
    dense = simulate_surface("cylinder-concave")
    coarse = simulate_surface("cylinder-concave", step=8)
    uv = np.array([[100.0, 50.0], [640.0, 400.0], [1279.0, 799.0], [3.3, 777.7]])
    np.testing.assert_allclose(coarse.points_at(uv), dense.points_at(uv), atol=2e-4)


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"K": np.eye(3)}, "no 'points'"),
        ({"points": np.zeros((4, 4)), "K": np.eye(3)}, "(H, W, 3)"),
        ({"points": np.zeros((4, 4, 3)), "K": np.zeros((2, 2))}, "3x3"),
    ],
)
def test_bad_surface_files_are_named_errors(
    tmp_path: Path, arrays: dict[str, np.ndarray], message: str
) -> None:
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Surface.load(path)


def test_missing_and_garbage_surface_files(tmp_path: Path) -> None:
    with pytest.raises(SurfaceError, match="not found"):
        Surface.load(tmp_path / "nope.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip file")
    with pytest.raises(SurfaceError, match="cannot read"):
        Surface.load(tmp_path / "junk.npz")


def test_a_surface_that_misses_the_frame_is_refused() -> None:
    p = Projector.default(64, 40)
    pts = np.full((40, 64, 3), np.nan, np.float32)
    pts[:2, :2] = [0.0, 0.0, 1.0]
    with pytest.raises(SurfaceError, match="meets the surface"):
        compute_warp(Surface(pts, p), (32, 20), settings=WarpSettings(mode="conformal"))


def test_points_behind_the_projector_are_no_surface() -> None:
    pts = np.ones((4, 4, 3), np.float32)
    pts[0, 0, 2] = -1.0
    s = Surface(pts, Projector.default(4, 4))
    assert not s.valid[0, 0] and s.valid.sum() == 15


def test_warp_round_trip_and_map_contract(tmp_path: Path) -> None:
    s = simulate_surface("sphere-convex", step=4)
    settings = WarpSettings(mode="conformal", grid=Grid(16, 10), adaptive=False)
    warp = compute_warp(s, (320, 200), settings=settings)
    warp.map_xy = map_from_warp(warp, s)
    warp.save(tmp_path / "w.npz")
    back = Warp.load(tmp_path / "w.npz")
    assert back.grid_uv.shape == (11, 17, 2) and back.image_xy.shape == (11, 17, 2)
    assert back.map_xy is not None and back.map_xy.shape == (800, 1280, 2)
    assert back.map_xy.dtype == np.float32
    np.testing.assert_allclose(back.image_xy, warp.image_xy, rtol=1e-6, equal_nan=True)
    # the sphere does not cover the frame: its corners show black
    assert np.isnan(back.map_xy[0, 0]).all() and np.isnan(back.image_xy[0, 0]).all()
    assert back.meta["mode"] == "conformal" and back.content_size == (320, 200)


def test_grid_parsing() -> None:
    assert Grid.parse("40x30") == Grid(40, 30)
    for bad in ("20", "x", "0x5", "20x20x2", "1000x1000"):
        with pytest.raises(InputError):
            Grid.parse(bad)


def test_content_is_upright_for_the_given_gravity() -> None:
    """With "up" rolled by 20 degrees in frame P, content "down" follows it on the wall."""
    s = simulate_surface("plane", step=8)
    a = np.deg2rad(20.0)
    up = (float(np.sin(a)), -float(np.cos(a)), 0.0)
    warp = compute_warp(s, (320, 200), settings=WarpSettings(mode="conformal", up=up))
    xy = warp.image_xy
    # true down points 20 degrees to the projector's left; walking straight down the
    # projector's columns therefore drifts 20 degrees to the right of content "down"
    step = xy[-1, 10] - xy[0, 10]
    assert np.degrees(np.arctan2(step[0], step[1])) == pytest.approx(20.0, abs=0.5)
    level = compute_warp(s, (320, 200), settings=WarpSettings(mode="conformal"))
    step0 = level.image_xy[-1, 10] - level.image_xy[0, 10]
    assert abs(np.degrees(np.arctan2(step0[0], step0[1]))) < 0.5
