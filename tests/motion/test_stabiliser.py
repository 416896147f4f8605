"""The stabiliser on synthetic motion: tremor cancelled, deliberate turns followed, the
margin never exceeded, the gyro bias learnt."""

from __future__ import annotations

import numpy as np
import pytest

from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.rotations import rotation_matrix, rotation_vector
from adaproj_edge.motion.stabiliser import Stabiliser, StabiliserSettings
from adaproj_edge.session.hand import HandMotion

PROJ = Projector.default()
SIZE = (PROJ.width, PROJ.height)
RATE_HZ = 416.0
REFRESH_S = 1 / 60


def _run(
    rate: np.ndarray, t: np.ndarray, settings: StabiliserSettings | None = None
) -> tuple[np.ndarray, list[np.ndarray], list[float]]:
    """Feed rates (N, 3) at times t (N,); step at every refresh, lit 10 ms after the
    newest sample. Returns refresh times, the device's true orientation times the
    correction's inverse (where the stabilised picture points) and margin use."""
    st = Stabiliser(PROJ.K, SIZE, settings)
    R = np.eye(3)
    pointing, usage, times = [], [], []
    next_refresh = 0.05
    for k in range(len(t)):
        if k:
            R = R @ rotation_matrix(0.5 * (rate[k - 1] + rate[k]) * (t[k] - t[k - 1]))
        st.add_gyro(round(t[k] * 1e9), rate[k])
        if t[k] >= next_refresh:
            c = st.step(round(t[k] * 1e9))
            pointing.append(R @ c.C.T)
            usage.append(c.usage)
            times.append(t[k])
            next_refresh += REFRESH_S
    return np.array(times), pointing, usage


def _angles(pointing: list[np.ndarray]) -> np.ndarray:
    return np.array([rotation_vector(P) for P in pointing])


def _tremor(t: np.ndarray, rms: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = rng.normal(10.0, 1.0, (20, 3))
    ph = rng.uniform(0, 2 * np.pi, (20, 3))
    a = rms / np.sqrt(20 / 2)
    return np.sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t[:, None, None] + ph), axis=1)


@pytest.mark.parametrize(
    ("rms", "seed", "share"),
    [(0.003, 0, 0.1), (0.0087, 2, 0.25)],
)
def test_tremor_is_cancelled_on_a_still_hand(rms: float, seed: int, share: float) -> None:
    """0.17 degrees RMS: a tenth or less is left. 0.5 degrees RMS uses over half the
    margin, and the pull back towards the device lets some through: a quarter or less
    (the pull once aimed at the device's own orientation, tremor and all: 0.29 of it
    on this seed, 0.22-0.29 on seeds 1-3; now towards its low-passed orientation:
    0.24, 0.15-0.24)."""
    t = np.arange(0, 6.0, 1 / RATE_HZ)
    rate = _tremor(t, rms, seed)
    times, on, _ = _run(rate, t)
    _, off, _ = _run(rate, t, StabiliserSettings(margin=0.0))
    late = times > 2.0
    motion_on = np.linalg.norm(np.diff(_angles(on)[late], axis=0), axis=1)
    motion_off = np.linalg.norm(np.diff(_angles(off)[late], axis=0), axis=1)
    # frame-to-frame motion of where the picture points, against the device's own
    assert np.sqrt(np.mean(motion_on**2)) < share * np.sqrt(np.mean(motion_off**2))


def test_without_a_margin_nothing_is_corrected() -> None:
    st = Stabiliser(PROJ.K, SIZE, StabiliserSettings(margin=0.0))
    for k in range(100):
        st.add_gyro(k * 2_400_000, np.array([0.0, 0.3, 0.0]))
    c = st.step(300_000_000)
    assert np.array_equal(c.C, np.eye(3)) and c.usage == 0.0
    assert not StabiliserSettings(margin=0.0).enabled


def test_a_deliberate_turn_is_followed_and_the_margin_is_never_exceeded() -> None:
    t = np.arange(0, 6.0, 1 / RATE_HZ)
    rate = _tremor(t, 0.002)
    turning = (t > 1.0) & (t < 2.0)
    rate[turning, 1] += 0.3  # 17 degrees in a second, far past the margin
    times, pointing, usage = _run(rate, t)
    assert max(usage) <= 1.0 + 1e-6
    yaw = _angles(pointing)[:, 1]
    # the picture followed the turn: it points most of the way round at the end
    assert yaw[-1] > 0.3 * 0.95
    # and, once the hand holds still again, it settles within a few tenths of the margin
    assert np.mean(np.array(usage)[times > 4.5]) < 0.3


def test_the_gyro_bias_is_learnt_while_still_and_does_not_turn_the_picture() -> None:
    t = np.arange(0, 20.0, 1 / RATE_HZ)
    bias = np.array([0.006, -0.01, 0.003])
    rate = _tremor(t, 0.002) + bias
    st = Stabiliser(PROJ.K, SIZE)
    for k in range(len(t)):
        st.add_gyro(round(t[k] * 1e9), rate[k])
    assert np.allclose(st.bias, bias, atol=0.0015)


def test_reset_starts_without_a_correction() -> None:
    st = Stabiliser(PROJ.K, SIZE)
    for k in range(200):
        st.add_gyro(k * 2_400_000, np.array([0.0, 0.05 * np.sin(k / 5), 0.0]))
    st.step(480_000_000)
    st.reset()
    assert st.step(500_000_000).usage == 0.0
    st.add_gyro(600_000_000, np.zeros(3))
    first = st.step(610_000_000)
    assert np.array_equal(first.C, np.eye(3))


def test_a_follower_started_mid_tremor_points_at_the_hand_s_mean_not_its_first_sample() -> None:
    # the hand trembles about a fixed aim (the orientation at t = 0): wherever the tremor
    # is when the first refresh comes, the stabilised picture settles on that aim
    # within its first second instead of keeping the first refresh's deflection (which
    # then decays with tau_still: a drift of the picture over the first seconds)
    t = np.arange(0, 2.0, 1 / RATE_HZ)
    worst = 0.0
    for seed in range(4):
        rate = _tremor(t, 0.004, seed)
        times, pointing, _ = _run(rate, t)
        # the aim: the orientation's mean over the session (the tremor is zero-mean)
        angles = _angles(pointing)
        R = np.eye(3)
        truth = [np.zeros(3)]
        for k in range(1, len(t)):
            R = R @ rotation_matrix(0.5 * (rate[k - 1] + rate[k]) * (t[k] - t[k - 1]))
            truth.append(rotation_vector(R))
        aim = np.mean(truth, axis=0)
        held = (times > 0.5) & (times < 1.5)
        worst = max(worst, float(np.linalg.norm(angles[held].mean(axis=0) - aim)))
    # (a follower that starts on its first sample keeps about the tremor's RMS here)
    assert worst < 0.3 * 0.004


def test_two_steps_at_one_time_right_after_the_start_are_a_still_correction() -> None:
    # a refresh repeated at the same time (dt 0) just after the follower started
    st = Stabiliser(PROJ.K, SIZE)
    st.add_gyro(0, np.zeros(3))
    st.step(10_000_000)
    st.add_gyro(2_400_000, np.array([0.01, 0.0, 0.0]))
    a = st.step(10_000_000)
    b = st.step(10_000_000)
    assert np.all(np.isfinite(a.C)) and np.allclose(a.C, b.C)


def _narrow_tremor(t: np.ndarray, rms: float, f0: float, seed: int) -> np.ndarray:
    """Rates (N, 3) of a tremor of ``rms`` rad RMS about each axis: Gaussian noise in a
    band around ``f0`` Hz (1 Hz wide), Rayleigh amplitudes, as the simulated hand's."""
    rng = np.random.default_rng(seed)
    f = np.clip(rng.normal(f0, 1.0, (48, 3)), 1.0, None)
    ph = rng.uniform(0, 2 * np.pi, (48, 3))
    a = rng.rayleigh(1.0, (48, 3))
    a *= rms / np.sqrt(np.sum(a**2, axis=0) / 2)
    return np.sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t[:, None, None] + ph), axis=1)


def _turning(rate: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``turning`` and the deliberate rate of the moment after every sample from 0.5 s
    on (before, the low-pass, started at rest on a tremor of ~1 rad/s, is settling)."""
    st = Stabiliser(PROJ.K, SIZE)
    turning, rates = [], []
    for k in range(len(t)):
        st.add_gyro(round(t[k] * 1e9), rate[k])
        turning.append(st.turning)
        rates.append(st.deliberate_rate)
    late = t >= 0.5
    return np.array(turning)[late], np.array(rates)[late]


@pytest.mark.parametrize("f0", [4.0, 6.0, 9.5, 12.0])
def test_a_strong_tremor_is_not_a_turn_and_a_turn_through_it_is(f0: float) -> None:
    """0.5 degrees RMS of tremor in a band around 4-12 Hz, the hand otherwise held
    still (the truth: no turn): ``turning`` never says so (its window's mean stays
    under 0.036 rad/s, the worst at 4 Hz; 0.011-0.019 at 6-12 Hz), though the deliberate rate of
    the moment goes over ``moving_rate`` (the display loop once showed a re-placement at
    once on it: a 188 mm jump at a corner). A turn of 20 degrees a second about another
    axis, with the same tremor on top, is ``turning`` within 0.2 s of its start and for
    as long as it lasts."""
    t = np.arange(0, 4.0, 1 / RATE_HZ)
    tremor = _narrow_tremor(t, np.deg2rad(0.5), f0, seed=int(f0))
    moving_rate = StabiliserSettings().moving_rate
    turning, rates = _turning(tremor, t)
    assert not turning.any()
    assert rates.max() > moving_rate  # what the rate of the moment alone would say
    turn = tremor.copy()
    on = t >= 2.0
    turn[on] += np.array([0.3, 0.0, 0.2]) * np.deg2rad(20.0) / np.hypot(0.3, 0.2)
    turning, _ = _turning(turn, t)
    late = t[t >= 0.5]
    assert not turning[late < 2.0].any()
    assert turning[late >= 2.2].all()


def test_the_simulated_hand_s_strong_tremor_is_not_a_turn() -> None:
    """The session simulator's hand held still for 12 s at 0.5 degrees RMS (a narrow
    band drawn at 8.5-11 Hz, the sway on top; its true rates in frame P, no gyro
    offset): never ``turning``, and the offset learnt stays near the true zero (learnt
    from the raw rate, the tremor left it 0.049 rad/s off on this seed, a steady turn of
    that rate in the deliberate rate's mean: ``turning`` at 0.048 rad/s)."""
    seconds = 12.0
    t = np.arange(0, seconds, 1 / RATE_HZ)
    _, rate = HandMotion(seconds, seed=1, tremor_deg=0.5, hold_after=0).imu_truth(t)
    st = Stabiliser(PROJ.K, SIZE)
    turning, rates, worst_bias = [], [], 0.0
    for k in range(len(t)):
        st.add_gyro(round(t[k] * 1e9), rate[k])
        turning.append(st.turning)
        rates.append(st.deliberate_rate)
        worst_bias = max(worst_bias, float(np.linalg.norm(st.bias)))
    late = t >= 0.5
    assert not np.array(turning)[late].any()
    assert max(rates) > StabiliserSettings().moving_rate
    # the true rate's mean over the session is under 0.001 rad/s; the learnt offset's
    # error goes into the turning rate whole: a fifth of moving_rate at most
    assert worst_bias < 0.2 * StabiliserSettings().moving_rate


def test_a_turn_ends_when_the_hand_stops_not_a_window_later() -> None:
    """A turn of 20 degrees a second for 1 s under a light tremor (0.05 degrees RMS):
    ``turning`` ends with the low-passed rate of the moment, within 0.32 s of the stop
    (the two low-passes' step response falls from 0.35 to under 0.04 rad/s in 3.6 time
    constants of 0.08 s: 0.29 s); the window's mean alone would end it after another
    0.1 s (0.44 s), a frame published then taken for one following a turn (shown at
    once: at a corner after each move, jitter ratio 0.127 -> 0.183)."""
    t = np.arange(0, 3.6, 1 / RATE_HZ)
    rate = _narrow_tremor(t, np.deg2rad(0.05), 9.5, seed=1)
    on = (t >= 2.0) & (t < 3.0)
    rate[on, 1] += np.deg2rad(20.0)
    st = Stabiliser(PROJ.K, SIZE)
    turning, mean_says = [], []
    for k in range(len(t)):
        st.add_gyro(round(t[k] * 1e9), rate[k])
        turning.append(st.turning)
        mean_says.append(st.turning_rate >= st.settings.moving_rate)
    after = t - 3.0
    assert np.array(turning)[(after > 0.0) & (after < 0.25)].all()
    assert not np.array(turning)[after >= 0.32].any()
    assert np.array(mean_says)[(after >= 0.32) & (after < 0.4)].all()
