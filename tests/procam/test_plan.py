"""What the plan asks for after each pose."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from adaproj_edge.procam.plan import PlanSettings, PoseSummary, assess, coverage

SIZE = (1280, 800)
WALLS = np.array([[0.7, 0.0, -0.7], [-0.7, 0.0, -0.7]])


def pose(depth: float, turn_deg: tuple[float, float, float] = (0, 0, 0), full: bool = True,
         planes: np.ndarray = WALLS) -> PoseSummary:  # fmt: skip
    rng = np.random.default_rng(int(depth * 100))
    hi = np.array(SIZE) * (1.0 if full else 0.4)
    uv = rng.uniform([0, 0], hi, size=(2000, 2))
    pts = np.c_[rng.normal(size=(2000, 2)) * 0.3, np.full(2000, depth)]
    turn = Rotation.from_euler("xyz", turn_deg, degrees=True).as_rotvec()
    return PoseSummary(uv, pts, planes, turn)


def test_coverage_counts_pairs_per_region() -> None:
    s = PlanSettings(cells=(4, 2))
    uv = np.array([[10.0, 10.0], [1279.0, 799.0], [700.0, 100.0], [700.0, 100.0]])
    cov = coverage(uv, SIZE, s)
    assert cov.shape == (2, 4) and cov[0, 0] == 1 and cov[1, 3] == 1 and cov[0, 2] == 2


def test_a_good_set_of_poses_is_done() -> None:
    poses = [pose(1.6), pose(1.1, (3, -14, 0)), pose(2.0, (-10, 9, 2)), pose(1.4, (12, 5, 1))]
    plan = assess(poses, SIZE)
    assert plan.done and plan.poses_needed == 0 and "enough poses" in plan.status
    assert plan.planes == 2 and plan.coverage == 1.0


def test_each_missing_need_is_asked_for() -> None:
    first = assess([pose(1.6)], SIZE)
    assert not first.done and first.poses_needed == 3
    same = assess([pose(1.6), pose(1.62, (0, -15, 0))], SIZE)
    assert "closer" in same.advice or "farther" in same.advice
    assert "tilt the device up or down" in same.advice  # only turned left/right so far
    corner_of_frame = assess([pose(1.6, full=False), pose(1.1, (0, -15, 0), full=False)], SIZE)
    where = corner_of_frame.advice.split("projection's")[1].split("parts")[0]
    assert "bottom" in where and "right" in where and "top" not in where
    assert corner_of_frame.coverage < 0.6
    flat = assess([pose(1.6, planes=WALLS[:1]), pose(1.1, (5, -15, 0), planes=WALLS[:1])], SIZE)
    assert "wall corner" in flat.advice and not flat.done
