"""The light at every projector pixel of an estimated surface: exact on its snapped
planes up to the crease's own pixel, on either side of a fold seen from inside or
outside; smooth between the nodes of a coarse lattice."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.irradiance import relative_irradiance
from adaproj_edge.geometry.planes import snap_planes
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.surface_irradiance import irradiance_at
from tests.render.photometry_oracle import creased

SMALL = Projector.default(640, 400)
GRID = (21, 21)


@pytest.mark.parametrize(("angle", "slope"), [(30.0, 0.6), (-50.0, -0.4)])
def test_the_light_on_snapped_planes_is_exact_to_the_crease(angle: float, slope: float) -> None:
    """A wall folded along a slanted crease, towards the projector (seen from inside a
    corner) and away from it (outside one), sampled at the warp grid's 21x21 lattice
    and snapped onto its planes (at 8x that lattice): the light at every frame pixel
    more than one pixel from the crease is the analytic one (the oracle's own normals)
    to 1e-3 in log: the snapping fits a plane to the nodes within 4.5 mm of it, a few
    of them beside the crease on the other wall, which tilts it by ~1e-4 (its fitted
    RMS is 0.3-0.5 mm); the wrong wall's light would be 10 % off and more, and the
    snapped lattice's own nodes beside the crease are on the wrong wall for up to 8
    pixels. The normals of the snapped lattice's cells, interpolated, miss it by far
    more beside the crease."""
    dense, exact, dist = creased(SMALL, angle, slope)
    coarse = Surface(dense.points_at(lattice_uv(SMALL, GRID)).astype(np.float32), SMALL)
    snapped, planes = snap_planes(coarse)
    assert len(planes) == 2
    uv = SMALL.pixel_grid()
    got = irradiance_at(snapped, uv)
    judged = np.abs(dist) > 1.0
    err = np.abs(np.log(got.light / exact))[judged]
    assert np.all(np.isfinite(err)) and float(err.max()) < 1e-3
    cells = relative_irradiance(snapped.points_at(uv), SMALL, uv)
    assert float(np.nanmax(np.abs(np.log(cells / exact))[judged])) > 0.05


def test_a_coarse_lattice_gives_smooth_light_between_its_nodes() -> None:
    """A concave dome at the warp grid's lattice, each node's depth 3 mm off (the
    device's estimate after a few frames): its light at the gain's 1/4 frame is within
    2.5 % of the true light (over 5 draws of the noise: 1.4-1.8 %; the nodes' normals
    tilt by ~0.04 rad, blurred over two degrees they average out), where the normals of
    the lattice's cells are off by 6-9 %; and it bends smoothly (its largest second
    difference of log light along a row under 0.005, the gain's crease threshold: under
    7e-4 here), where the cells' facets bend it by 0.04 and more at their edges. The
    dome's rim (grazing light, 8 reduced pixels) is left out."""
    truth = simulate_surface("sphere-concave", SMALL)
    pts = truth.points_at(lattice_uv(SMALL, GRID)).astype(np.float64)
    z = pts[..., 2]
    noisy_z = z + np.random.default_rng(1).normal(0.0, 0.003, z.shape)
    noisy = Surface((pts * (noisy_z / z)[..., None]).astype(np.float32), SMALL)
    v, u = np.mgrid[0:100, 0:160].astype(np.float64)
    uv = np.stack([(u + 0.5) * 4 - 0.5, (v + 0.5) * 4 - 0.5], axis=-1)
    exact = relative_irradiance(truth.points_at(uv), SMALL, uv)
    got = irradiance_at(noisy, uv)
    cells = relative_irradiance(noisy.points_at(uv), SMALL, uv)
    assert got.smoothed
    inner = (slice(8, -8), slice(8, -8))

    def off(light: np.ndarray) -> float:
        return float(np.nanmax(np.abs(np.log(light / exact))[inner]))

    def bend(light: np.ndarray) -> float:
        return float(np.nanmax(np.abs(np.diff(np.log(light), 2, axis=1))[:, 7:-7][inner[0]]))

    assert off(got.light) < 0.025 and off(cells) > 2 * off(got.light)
    assert bend(got.light) < 0.005 < bend(cells)
