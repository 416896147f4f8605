"""The content's up: tremor never tilts it, a deliberate roll turns it within a second;
the worst seed of a few settings against the simulator's true gravity (IMU streams
as the session simulator makes them, offsets and noise included, no warps)."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.app.upright_score import trace_upright, wall_normal
from adaproj_edge.motion.upright import Upright
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.simulator import ImuNoise

CALIBRATED = ImuNoise(accel_bias_sigma=0.02)  # a unit whose zero-g offset was calibrated
SEEDS = range(10)


def _worst(tremor: float, roll: float, yaw: float, from_s: float) -> tuple[float, int]:
    worst = (0.0, -1)
    for seed in SEEDS:
        hand = HandMotion(4.0, seed=seed, tremor_deg=tremor, roll_deg=roll)
        trace = trace_upright(hand, seed, CALIBRATED, from_s=from_s)
        err = float(trace.error_deg(wall_normal(yaw))[trace.still].max())
        worst = max(worst, (err, seed))
    return worst


@pytest.mark.parametrize(
    ("tremor", "roll", "yaw"),
    [
        (0.15, 12.0, 0.0),
        (0.3, 0.0, 35.0),
        (0.5, 20.0, 0.0),
    ],
)
def test_held_still_the_content_stays_within_a_degree_of_upright_on_walls(
    tremor: float, roll: float, yaw: float
) -> None:
    # from the second still phase: in the first second the estimate rests on a quarter
    # of a second of samples (within 1.5 degrees, asserted below)
    err, seed = _worst(tremor, roll, yaw, from_s=1.8)
    assert err <= 1.0, f"seed {seed}: {err:.2f} deg"
    err, seed = _worst(tremor, roll, yaw, from_s=0.9)
    assert err <= 1.5, f"seed {seed}: {err:.2f} deg"


@pytest.mark.parametrize("tremor", [0.3, 0.5])
def test_a_deliberate_20_degree_roll_is_followed_within_a_second(tremor: float) -> None:
    hand = HandMotion(
        5.0, seed=7, tremor_deg=tremor, move_rad=0.0, move_m=0.0,
        roll_move_deg=20.0, roll_move_at_s=2.5, roll_move_s=0.4,
    )  # fmt: skip
    trace = trace_upright(hand, 7, CALIBRATED, every=1, from_s=2.0)
    err = trace.error_deg(wall_normal(0.0))
    assert err[trace.t < 2.5].max() <= 1.0
    assert err[(trace.t > 2.7) & (trace.t < 3.0)].max() > 2.0  # it did turn
    assert err[trace.t >= 3.5].max() <= 1.0  # followed within 1 s of the roll's start


def test_tremor_inside_the_dead_band_never_moves_the_up() -> None:
    up = Upright()
    rng = np.random.default_rng(0)
    g = np.array([0.0, -9.80665, 0.0])
    shown = []
    for k in range(2000):
        t = k * 2_403_846
        roll = np.radians(0.2) * np.sin(2 * np.pi * 10 * k / 416)  # tremor's roll
        a = np.array([np.sin(roll) * -g[1], g[1] * np.cos(roll), 0.0]) * -1
        up.update(t, -a + rng.normal(scale=0.05, size=3), np.zeros(3))
        if up.up is not None:
            shown.append(up.up)
    assert len(shown) > 1000
    assert np.ptp(np.array(shown[10:]), axis=0).max() < 1e-9
