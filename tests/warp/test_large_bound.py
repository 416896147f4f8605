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

from functools import cache

import numpy as np
import pytest

from tests.warp.bound import Problem, _residuals, optimise, problem, score

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


@cache
def grid_problem(name: str, mask: str) -> Problem:
    return problem(name, mask, step=8, on_grid=True)


@pytest.mark.parametrize(("name", "mask"), sorted(CROSSING))
def test_no_warp_of_the_grid_reaches_0_6x_within_the_conformal_angle_error(
    name: str, mask: str
) -> None:
    pb = grid_problem(name, mask)
    conf = score(pb, pb.v0, None)
    mu = CROSSING[(name, mask)]
    best = score(pb, optimise(pb, mu), mu)
    assert best.folds == 0
    assert best.angle > conf.angle, (best.angle, conf.angle)  # past the budget
    assert best.size > 0.6 * conf.size, (best.size / conf.size, best.angle / conf.angle)


def test_the_optimiser_s_derivatives_are_the_energy_s() -> None:
    """The optimisation's Jacobian is written out (finite differences cost ~20x more);
    a wrong one would stop it short of the optimum, and a worse optimum passes the test
    above more easily. So: along random directions, the Jacobian's derivative agrees
    with central differences of the residuals."""
    pb = grid_problem("sphere-concave", "quarter")
    subj = np.flatnonzero(pb.subject)
    sub = Problem(**{**pb.__dict__, "tris": pb.tris[subj], "frames": pb.frames[subj]})
    free = np.ones(pb.basis.shape[1], dtype=bool)
    free[:2] = False
    b_free, fixed = pb.basis[:, free], pb.basis[:, ~free] @ pb.v0[~free]
    rng = np.random.default_rng(13)
    # away from the conformal warp (whose angle errors sit at the smoothing's kink)
    x = np.concatenate([pb.v0[free].ravel() + rng.normal(0, 0.3, 2 * free.sum()), [-6.0]])
    jac = _residuals(sub, b_free, fixed, 1.7, x, jacobian=True)[1]
    assert jac is not None
    for _ in range(3):
        v = rng.normal(size=x.size)
        # h in content px: the residuals vary on the scale of a sample triangle (8 px),
        # so truncation (~h^2) and rounding (~eps / h) stay below 1e-5 of the derivative
        h = 1e-5
        plus = _residuals(sub, b_free, fixed, 1.7, x + h * v)[0]
        minus = _residuals(sub, b_free, fixed, 1.7, x - h * v)[0]
        exact = jac @ v
        assert np.linalg.norm((plus - minus) / (2 * h) - exact) <= 1e-5 * np.linalg.norm(exact)
