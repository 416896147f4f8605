"""The brightness gain as the device makes it: flat mid-grey on a wall corner and a
concave dome looks even to a viewer 0.8 m to the side, with the gain made from the
surface the device estimates (simulated OAK-D depth frames, the runtime's surface
source: estimate, average, walls snapped; its warp source: the pose's warp and gain)
and judged by the oracle's own ray cast of the true analytic surface
(``tests/render/photometry_oracle.py``), not by the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.analytic import Corner, get_surface
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.planes import plane_equations
from adaproj_edge.geometry.surface import Surface
from tests.render.photometry_oracle import CITED_GRADIENT, device_grey_case


def crease_errors_m(surface: Surface, corner: Corner) -> np.ndarray:
    """How far (m) the crease of ``surface``'s two snapped planes (its meta's
    equations) lies from ``corner``'s true, vertical crease at the top, the middle and
    the bottom row of the projector's frame (the horizontal distance between the two
    lines at those heights)."""
    eq = plane_equations(surface.meta)
    assert len(eq) == 2, "the corner is snapped as its two walls"
    p = surface.projector
    ys = (np.array([0.0, p.height / 2, p.height - 1.0]) - p.K[1, 2]) / p.K[1, 1] * corner.z0
    a = eq[:, [0, 2]]  # the planes at height y: n_x x + n_z z = d - n_y y
    xz = np.array([np.linalg.solve(a, eq[:, 3] - eq[:, 1] * y) for y in ys])
    return np.asarray(np.hypot(xz[:, 0] - corner.x0, xz[:, 1] - corner.z0))


@pytest.mark.parametrize(
    ("name", "frames", "seed"),
    [("corner", 3, 0), ("corner", 12, 1), ("corner", 12, 7), ("sphere-concave", 3, 0)],
)
def test_the_device_evens_out_grey_on_the_surface_it_estimates(
    name: str, frames: int, seed: int
) -> None:
    """The Done-when figures through the device's own path at 1280x800 with the gain
    at its 1/4 scale: max/min <= 1.10 over the picture, the mean >= 0.7x the
    uncompensated, the brightness changing by less than the cited threshold per
    degree, and never less even than uncompensated. The corner's crease is known
    to the surface only as two snapped planes on a lattice of 8x5 frame pixels, the
    dome only at the warp grid's 21x21 nodes, each a few millimetres off (the light
    taken from the normals of the lattice's cells gave the corner 1.30 and the dome 1.053
    where it was 1.034 uncompensated). This draw of the depth noise puts the snapped
    crease 0.4 pixels from the true one; draws that put it 1-1.7 pixels off give the
    corner 1.10-1.19 at the first capture, from a line of the wrong wall's gain between
    the two creases (docs/photometry.md, Limits); seed 1 is such a draw (1.19 from 3
    frames), and the gain the runtime remakes from the surface averaged over 12 frames
    meets the line on it too; seed 7 is the draw on which the planes fitted to the newest
    frame's raw depth put the crease 2-4 mm off and the corner read 1.14.

    The corner's snapped crease itself is checked against the true one at 12 frames
    (3 frames leave it 1-3 mm off, planes fitted to nodes or raw depth alike): within an
    eighth of the sensor's depth step there (1.5 mm at 1.8 m, a projector pixel and a
    half). Each wall's plane is fitted to hundreds of raw points over 12 frames, so
    their random error is a fraction of a millimetre; the steps stay (the same in every
    frame), and a plane across the ~25 steps a 45-degree wall spans is off by about
    step / sqrt(12) / sqrt(25) = step / 17, the crease by sqrt(2) of that: step / 12;
    an eighth leaves half as much again for the rest. Planes fitted to the newest frame
    alone, with the pixels whose depth mixes both walls (within the matcher's footprint
    of the crease), put it up to 2.7 mm (seed 1) and 3.7 mm (seed 7) off."""
    case = device_grey_case(name, frames=frames, seed=seed)
    if name == "corner" and frames >= 12:
        corner = get_surface(name)
        assert isinstance(corner, Corner) and case.surface is not None
        sensor = SensorModel.of(Calibration.default().depth)
        bound = float(sensor.step_m(corner.z0)) / 8.0
        assert np.all(crease_errors_m(case.surface, corner) <= bound)
    before, after = case.before, case.after
    assert after.ratio() <= 1.10
    assert after.mean() >= 0.7 * before.mean()
    assert after.gradient_per_deg() <= CITED_GRADIENT
    assert after.ratio() <= before.ratio() + 1e-9
    if name == "corner":  # far from even before: the figure is the gain's doing
        # (twice the cited line or more: the uncompensated picture's steepest change
        # depends on where the estimated crease puts the picture; seed 7 read 0.047
        # once the averaged raw depth was smoothed again, 0.05 and over before)
        assert before.ratio() > 1.8 and before.gradient_per_deg() > 2 * CITED_GRADIENT
