"""The content's up over a small sweep of hands, its worst seed against the simulator's
ground truth (the hand's gravity on a wall facing the device and on one turned 35
degrees), with the accelerometer offset the simulated calibration measured.

Each case runs the runtime's IMU chain on ten simulated hands
(:func:`~adaproj_edge.app.upright_score.trace_upright`: no depth, no warps; about a
third of a second each) and scores the largest angle while the hand holds still. The
target is a degree on walls (``tools/bench_handheld.py --only sweep`` runs the whole
sweep); met at every tremor up to 0.5 degrees on these 4-s hands. At 0.5 degrees the
gyro's offset is not learnt within 4 s and carries the estimate off while the
accelerometer waits out a move: with a further 0.3-s hold after each turn and 0.5 s
taken back before it, 1.24 / 1.31 / 1.35 degrees at rolls 0 / 12 / 30 (seeds 2, 9,
5), now within 0.84 (``docs/handheld.md``). Asserted at roll 30, the worst of the
three then.
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
    [(0.05, 0.0, SECONDS), (0.15, 30.0, SECONDS), (0.3, 12.0, SECONDS), (0.5, 30.0, SECONDS)],
)
def test_the_worst_seed_keeps_walls_upright(tremor: float, roll: float, seconds: float) -> None:
    err, seed = _worst(tremor, roll, seconds)
    assert np.isfinite(err) and err <= 1.0, f"{err:.2f} deg at seed {seed}"
