"""Content points followed into the projector frame (the glide's and the handheld
scoring's mesh inversion), against maps whose inverse is known in closed form."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.render.content_points import content_points, frame_pixels
from adaproj_edge.warp.warpmap import Grid, Warp

PROJECTOR = simulate_surface("plane", step=8).projector


def affine_warp(A: np.ndarray, b: np.ndarray, grid: Grid) -> Warp:
    """A warp whose every triangle maps projector pixel u to content A u + b."""
    uv = grid.vertices(PROJECTOR)
    return Warp(uv, uv @ A.T + b, (640, 400), PROJECTOR)


@settings(max_examples=40, deadline=None)
@given(
    scale=st.floats(0.2, 2.0),
    angle=st.floats(-0.6, 0.6),
    shear=st.floats(-0.3, 0.3),
    shift=st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    cells=st.integers(2, 24),
)
def test_an_affine_warp_is_inverted_exactly(
    scale: float, angle: float, shear: float, shift: tuple[float, float], cells: int
) -> None:
    c, s = np.cos(angle), np.sin(angle)
    A = scale * np.array([[c, -s], [s, c]]) @ np.array([[1.0, shear], [0.0, 1.0]])
    b = np.array(shift)
    warp = affine_warp(A, b, Grid(cells, cells))
    xy = np.vstack([content_points((640, 400)), warp.image_xy[1:-1, 1:-1].reshape(-1, 2)])
    got = frame_pixels(warp, xy)
    truth = (xy - b) @ np.linalg.inv(A).T
    w, h = PROJECTOR.width - 1, PROJECTOR.height - 1
    covered = np.all((truth >= -1e-6) & (truth <= np.array([w, h]) + 1e-6), axis=1)
    assert np.all(np.isnan(got[~covered]))
    np.testing.assert_allclose(got[covered], truth[covered], atol=1e-6)


def test_points_over_a_hole_or_outside_have_no_pixel() -> None:
    warp = affine_warp(np.eye(2) * 0.5, np.zeros(2), Grid(8, 8))
    warp.image_xy[3:6, 3:6] = np.nan  # the cells around these vertices have no surface
    hole = warp.image_xy.copy()
    centre = 0.5 * np.array(warp.grid_uv[4, 4])  # inside the hole
    xy = np.array([centre, [-5.0, -5.0], [1e4, 10.0], 0.5 * np.array(warp.grid_uv[1, 1])])
    got = frame_pixels(warp, xy)
    assert np.isnan(got[:3]).all()
    np.testing.assert_allclose(got[3], warp.grid_uv[1, 1], atol=1e-9)
    np.testing.assert_array_equal(np.isnan(hole), np.isnan(warp.image_xy))  # not written
