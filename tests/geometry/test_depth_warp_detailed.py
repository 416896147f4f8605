"""The done-when of ``test_depth_warp.py`` on the surfaces with detail at the grid's
scale (bumps, waves): the warp computed from the estimated surface is within 2x of the
distortion of the warp computed from the true surface. A file of its own so that these
slowest cases run beside the others, not after them."""

from __future__ import annotations

import pytest

from tests.geometry.test_depth_warp import DETAILED, NONE, distortions


@pytest.mark.slow
@pytest.mark.parametrize("name", DETAILED)
def test_warp_from_the_estimate_is_within_twice_the_true_distortion(name: str) -> None:
    est, true = distortions(name)
    assert est.folds == 0
    assert est.angle_mean <= 2 * true.angle_mean + NONE, (est.angle_mean, true.angle_mean)
    assert est.size_std <= 2 * true.size_std + NONE, (est.size_std, true.size_std)
