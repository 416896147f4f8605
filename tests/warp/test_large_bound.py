"""Large subjects on doubly curved surfaces (issue 13, docs/engine.md "Large subjects"):
no warp the engine's grid can show evens out the subject's size to 0.6x the conformal
warp's without more angle error than the conformal warp's (sphere-concave, quarter and
half subject; bowl, half).

Computed independently of the engine's solves (``tests/warp/bound.py``): the grid
vertices of the conformal warp are optimised through the per-pixel display's weights
for ``sum_subject angle + mu (log size - m)^2``, scored by the quality tests' scorer
(every 8th pixel). At the ``mu`` below the optimum's angle error on the subject already
exceeds the conformal warp's, and its size spread is still above 0.6x: for a global
optimum of that energy, any warp with no more angle error has no less size spread.
Table: ``.venv/bin/python tools/measure_large_bound.py``.
"""

from __future__ import annotations

import pytest

from tests.warp.bound import optimise, problem, score

pytestmark = pytest.mark.slow

# per case, a weight (size against angle, each relative to the conformal warp's) at
# which the optimum spends more than the conformal warp's angle error. Not here: bowl
# with the quarter subject, where the grid's best reaches 0.57x at 1.01x the angle
# error (0.62x at 0.95x), and sphere-convex with the half subject, where the
# optimisation folds the map (docs/engine.md, "Large subjects")
CROSSING = {
    ("sphere-concave", "quarter"): 1.0,
    ("sphere-concave", "half"): 1.5,
    ("bowl", "half"): 1.5,
}


@pytest.mark.parametrize(("name", "mask"), sorted(CROSSING))
def test_no_warp_of_the_grid_reaches_0_6x_within_the_conformal_angle_error(
    name: str, mask: str
) -> None:
    pb = problem(name, mask, step=8, on_grid=True)
    conf = score(pb, pb.v0, None)
    mu = CROSSING[(name, mask)]
    best = score(pb, optimise(pb, mu), mu)
    assert best.folds == 0
    assert best.angle > conf.angle, (best.angle, conf.angle)  # past the budget
    assert best.size > 0.6 * conf.size, (best.size / conf.size, best.angle / conf.angle)
