"""The content's up over a small sweep of hands, its worst seed against the simulator's
ground truth (the hand's gravity on a wall facing the device and on one turned 35
degrees), with the accelerometer offset the simulated calibration measured.

Each case runs the runtime's IMU chain on ten simulated hands
(:func:`~adaproj_edge.app.upright_score.trace_upright`: no depth, no warps; about a
third of a second each) and scores the largest angle while the hand holds still. The
target is a degree on walls (``tools/bench_handheld.py --only sweep`` runs the whole
sweep); met up to 0.3 degrees of tremor on these 4-s hands, with the gravity estimate
fitting the drift of the gyro's offset itself (``docs/handheld.md``). At 0.5 degrees
the 4-s hands leave too little still time to fit the offset's drift on every seed
(over a degree on some, not asserted); the 6-s hands of the bench are asserted at
roll 30, where the seeds' median is highest at that tremor.
"""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.app.upright_score import trace_upright, wall_normal
from adaproj_edge.session.hand import HandMotion

SEEDS = range(10)
SECONDS = 4.0
YAWS = (0.0, 35.0)


def _worst(tremor: float, roll: float, seconds: float) -> tuple[float, int]:
    worst = (0.0, -1)
    for seed in SEEDS:
        hand = HandMotion(seconds, seed=seed, tremor_deg=tremor, roll_deg=roll)
        trace = trace_upright(hand, seed)
        for yaw in YAWS:
            err = float(trace.error_deg(wall_normal(yaw))[trace.still].max())
            worst = max(worst, (err, seed))
    return worst


@pytest.mark.parametrize(
    ("tremor", "roll", "seconds"),
    [(0.05, 0.0, SECONDS), (0.15, 30.0, SECONDS), (0.3, 12.0, SECONDS), (0.5, 30.0, 6.0)],
)
def test_the_worst_seed_keeps_walls_upright(tremor: float, roll: float, seconds: float) -> None:
    err, seed = _worst(tremor, roll, seconds)
    assert np.isfinite(err) and err <= 1.0, f"{err:.2f} deg at seed {seed}"
