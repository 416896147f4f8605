"""The brightness gain as the device makes it: flat mid-grey on a wall corner and a
concave dome looks even to a viewer 0.8 m to the side, with the gain made from the
surface the device estimates (simulated OAK-D depth frames, the runtime's surface
source: estimate, average, walls snapped; its warp source: the pose's warp and gain)
and judged by the oracle's own ray cast of the true analytic surface
(``tests/render/photometry_oracle.py``), not by the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.surfaces import SurfaceSource
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.app.warps import WarpSource
from adaproj_edge.geometry.analytic import get_surface
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.render.frame import render_frame
from adaproj_edge.render.photometry import PhotometrySettings, apply_gain
from adaproj_edge.render.viewer import DEFAULT_VIEWER, viewer_for
from adaproj_edge.session.simulator import Scene
from adaproj_edge.session.stereo import default_noise, stereo_depth
from adaproj_edge.warp.engine import WarpSettings
from tests.render.photometry_oracle import CITED_GRADIENT, GREY, seen_brightness

CAL = Calibration.default()
SIZE = (800, 600)
FRAMES = 3
"""Depth frames averaged (the runtime's first capture)."""


@pytest.mark.parametrize("name", ["corner", "sphere-concave"])
def test_the_device_evens_out_grey_on_the_surface_it_estimates(name: str) -> None:
    """The Done-when figures through the device's own path at 1280x800 with the gain
    at its 1/4 scale: max/min <= 1.10 over the picture, the mean >= 0.7x the
    uncompensated, the brightness changing by less than the cited threshold per
    degree, and never less even than uncompensated. The corner's crease is known
    to the surface only as two snapped planes on a lattice of 8x5 frame pixels, the
    dome only at the warp grid's 21x21 nodes, each a few millimetres off (the light
    taken from the normals of the lattice's cells gave the corner 1.30 and the dome 1.053
    where it was 1.034 uncompensated)."""
    scene = Scene.load(name)
    d, T = CAL.depth, CAL.T_P_D
    pts = scene.points_seen(d.K, d.width, d.height, T[:3, :3], T[:3, 3])
    rng = np.random.default_rng(0)
    settings = AppSettings(photometry=PhotometrySettings(scale=AppSettings().map_scale))
    telemetry = Telemetry(100)
    surfaces = SurfaceSource(CAL, settings, telemetry.times)
    for k in range(FRAMES):
        depth = stereo_depth(pts, d, default_noise(), rng, pts @ T[:3, :3].T + T[:3, 3])
        est = surfaces.filter.update(surfaces.estimate(DepthFrame(k, k, k, depth)), k > 0)
    surface = surfaces.prepared(est)
    warps = WarpSource(CAL.projector, settings, telemetry)
    entry, _ = warps.pose(surface, FRAMES, 0, np.zeros(3), SIZE, WarpSettings(mode="content"))
    gain = warps.gain(entry, surface)
    assert gain is not None
    plain = render_frame(
        np.full((SIZE[1], SIZE[0], 3), GREY, np.uint8), warps.content_free_maps(entry)
    )
    analytic = get_surface(name)
    viewer = viewer_for(surface, DEFAULT_VIEWER)
    before = seen_brightness(analytic, CAL.projector, plain, viewer)
    after = seen_brightness(analytic, CAL.projector, apply_gain(plain, gain), viewer)
    assert after.ratio() <= 1.10
    assert after.mean() >= 0.7 * before.mean()
    assert after.gradient_per_deg() <= CITED_GRADIENT
    assert after.ratio() <= before.ratio() + 1e-9
    if name == "corner":  # far from even before: the figure is the gain's doing
        assert before.ratio() > 1.8 and before.gradient_per_deg() > 0.05
