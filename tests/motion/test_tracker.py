"""The stillness test of the motion tracker."""

from __future__ import annotations

import numpy as np

from adaproj_edge.hal.lsm6dsox import STANDARD_GRAVITY
from adaproj_edge.motion.tracker import is_still


def test_is_still() -> None:
    rng = np.random.default_rng(2)
    g = rng.normal(scale=0.001, size=(40, 3))
    a = np.array([0.0, -STANDARD_GRAVITY, 0.0]) + rng.normal(scale=0.01, size=(40, 3))
    assert is_still(g, a)
    assert not is_still(g + np.array([0.2, 0.0, 0.0]), a)
    assert not is_still(g, a + rng.normal(scale=1.0, size=a.shape))
    assert not is_still(g[:1], a[:1])
