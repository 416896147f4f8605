"""Gyro integration and prediction on synthetic rates with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from adaproj_edge.geometry.rotations import rotation_matrix, rotation_vector
from adaproj_edge.motion import prediction
from adaproj_edge.motion.prediction import GyroTrack, PredictionSettings, small_rotation

RATE_HZ = 416.0


def _feed(track: GyroTrack, t: np.ndarray, w: np.ndarray) -> None:
    for ti, wi in zip(t, w, strict=True):
        track.add(round(ti * 1e9), wi)


def test_a_constant_rate_integrates_and_predicts_exactly() -> None:
    w = np.array([0.1, -0.2, 0.05])
    t = np.arange(0, 0.5, 1 / RATE_HZ)
    for method in ("ar", "constant"):
        track = GyroTrack(PredictionSettings(method=method))  # type: ignore[arg-type]
        _feed(track, t, np.tile(w, (len(t), 1)))
        assert np.allclose(track.orientation, rotation_matrix(w * t[-1]), atol=1e-9)
        ahead = t[-1] + 0.02
        got = track.predict(round(ahead * 1e9))
        assert np.allclose(got, rotation_matrix(w * ahead), atol=1e-6)
    none = GyroTrack(PredictionSettings(method="none"))
    _feed(none, t, np.tile(w, (len(t), 1)))
    assert np.allclose(none.predict(int(1e9)), none.orientation)


def _tremor_error(method: str, refit_s: float = 0.05) -> float:
    """RMS angle error (rad) predicting 14 ms ahead on a narrow-band 'tremor'."""
    rng = np.random.default_rng(0)
    f = rng.normal(10.0, 1.0, 30)
    ph = rng.uniform(0, 2 * np.pi, 30)
    amp = 0.003 / np.sqrt(np.sum(np.ones(30)) / 2)

    def angle(t: np.ndarray) -> np.ndarray:
        return np.sum(amp * np.sin(2 * np.pi * f * t[:, None] + ph), axis=1)

    def rate(t: np.ndarray) -> np.ndarray:
        return np.sum(amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t[:, None] + ph), axis=1)

    t = np.arange(0, 3.0, 1 / RATE_HZ)
    w = np.zeros((len(t), 3))
    w[:, 1] = rate(t) + rng.normal(scale=0.001, size=len(t))
    track = GyroTrack(PredictionSettings(method=method, ar_refit_s=refit_s))  # type: ignore[arg-type]
    errs = []
    for k in range(len(t)):
        track.add(round(t[k] * 1e9), w[k])
        if k > 400 and k % 5 == 0:
            ahead = t[k] + 0.014
            R = track.predict(round(ahead * 1e9))
            moved = rotation_vector(track.orientation.T @ R)[1]
            truth = float(angle(np.array([ahead]))[0] - angle(t[k : k + 1])[0])
            errs.append(moved - truth)
    return float(np.sqrt(np.mean(np.square(errs))))


def test_the_autoregressive_prediction_follows_tremor_far_better_than_a_constant_rate() -> None:
    ar, const, none = (_tremor_error(m) for m in ("ar", "constant", "none"))
    assert ar < 0.25 * const < 0.25 * none
    assert ar < 0.1 * 0.003  # a tenth of the tremor (3 mrad RMS)


def test_old_samples_are_refused_and_a_gap_starts_afresh() -> None:
    track = GyroTrack()
    assert track.add(1_000_000, np.zeros(3))
    assert not track.add(1_000_000, np.ones(3))
    assert not track.add(500_000, np.ones(3))
    assert track.add(200_000_000, np.ones(3))  # 0.2 s later: a gap
    t, w = track.rates()
    assert len(t) == 1 and np.allclose(w, 1.0)
    assert np.allclose(track.orientation, np.eye(3))  # nothing integrated over the gap


def test_the_bias_is_removed_from_integration_and_prediction() -> None:
    track = GyroTrack()
    bias = np.array([0.01, -0.02, 0.005])
    track.bias = bias.copy()
    t = np.arange(0, 1.0, 1 / RATE_HZ)
    _feed(track, t, np.tile(bias, (len(t), 1)))
    assert np.allclose(track.orientation, np.eye(3), atol=1e-12)
    assert np.allclose(track.predict(int(2e9)), np.eye(3), atol=1e-9)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_prediction_from_noise_stays_bounded(seed: int) -> None:
    rng = np.random.default_rng(seed)
    track = GyroTrack()
    t = np.arange(0, 1.0, 1 / RATE_HZ)
    _feed(track, t, rng.normal(scale=0.05, size=(len(t), 3)))
    R = track.predict(round((t[-1] + 0.02) * 1e9))
    assert np.linalg.norm(rotation_vector(track.orientation.T @ R)) < 0.02 * 0.2


@given(
    st.lists(st.floats(-4.0, 4.0, allow_nan=False), min_size=3, max_size=3),
    st.sampled_from([1.0, 1e-4, 1e-9, 0.0]),
)
def test_small_rotation_is_rodrigues(r: list[float], scale: float) -> None:
    v = np.array(r) * scale
    # scalar libm against numpy's vectorised sin and cos (an ulp apart, by CPU), in sums
    # of a few products of terms up to ~2: a few 1e-15; any wrong term is off by far more
    assert np.allclose(small_rotation(v), rotation_matrix(v), rtol=0, atol=1e-13)


def _reference_ar(w: np.ndarray, p: int, dt: float, h: float) -> np.ndarray:
    """The AR prediction written out plainly, axis by axis (``np.linalg.lstsq`` for the
    trend and the coefficients, a sample-by-sample run and trapezoids): what
    :mod:`adaproj_edge.motion.prediction` computes at once for the three axes."""
    n = len(w)
    x = (np.arange(n) - (n - 1)) * dt
    A = np.stack([np.ones(n), x], axis=1)
    trend = np.linalg.lstsq(A, w, rcond=None)[0]
    y = w - A @ trend
    out = np.zeros(3)
    steps = int(np.ceil(h / dt - 1e-9))
    for a in range(3):
        X = np.stack([y[p - 1 - i : n - 1 - i, a] for i in range(p)], axis=1)
        coef = np.linalg.lstsq(X, y[p:, a], rcond=None)[0]
        r = [y[-1, a]]
        hist = list(y[-p:, a][::-1])
        for _ in range(steps):
            r.append(float(np.dot(coef, hist)))
            hist = [r[-1], *hist[:-1]]
        for j in range(steps):
            width = min(dt, h - j * dt)
            end = r[j] + (r[j + 1] - r[j]) * width / dt
            out[a] += 0.5 * (r[j] + end) * width
        out[a] += trend[0, a] * h + 0.5 * trend[1, a] * h * h
    return out


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_the_batched_ar_fit_is_the_plain_least_squares_one(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dt = 1 / RATE_HZ
    t = np.arange(208) * dt
    f = rng.normal(10.0, 1.0, (12, 3))
    ph = rng.uniform(0, 2 * np.pi, (12, 3))
    w = np.sum(0.05 * np.cos(2 * np.pi * f * t[:, None, None] + ph), axis=1)
    w += rng.normal(scale=0.002, size=w.shape) + 0.03 * t[:, None] - 0.01
    h = 0.016
    y, c0, slope = prediction._detrend(w, dt)
    coef = prediction._ar_fit(y, 4)
    assert coef is not None
    got = prediction._ar_run(y, coef, dt, h)
    assert got is not None
    got = got + c0 * h + 0.5 * slope * h * h
    assert np.allclose(got, _reference_ar(w, 4, dt, h), rtol=1e-7, atol=1e-12)


def test_an_axis_without_oscillation_is_carried_by_its_trend_alone() -> None:
    dt = 1 / RATE_HZ
    t = np.arange(208) * dt
    w = np.zeros((len(t), 3))
    w[:, 0] = 0.05 * np.sin(2 * np.pi * 9.5 * t) + 0.001 * np.cos(2 * np.pi * 31 * t)
    w[:, 2] = 0.2 + 0.1 * t  # a turn speeding up, no tremor
    y, _, _ = prediction._detrend(w, dt)
    coef = prediction._ar_fit(y, 4)
    assert coef is not None
    assert np.all(coef[1:] == 0.0) and np.any(coef[0] != 0.0)


def test_coefficients_fitted_less_often_predict_about_as_well() -> None:
    every, sometimes = (_tremor_error("ar", refit) for refit in (0.0, 0.05))
    assert sometimes < 1.1 * every
