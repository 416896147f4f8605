"""Distances on a surface's development (adaproj_edge/geometry/developed.py), against
the analytic development of a corrugated wall."""

from __future__ import annotations

import numpy as np

from adaproj_edge.geometry.analytic import get_surface, simulate_surface
from adaproj_edge.geometry.developed import developed_lengths
from adaproj_edge.geometry.relief import Waves


def _developed(waves: Waves, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The exact distance (N,) between points ``p``, ``q`` (N, 3) on ``waves``' development:
    along the waves, the arc length of the profile ``a sin(k s)`` (a fine trapezoid
    rule); across them, straight."""
    c, s = np.cos(waves.direction), np.sin(waves.direction)
    (u0, v0), (u1, v1) = waves.to_wall(p)[:, :2].T, waves.to_wall(q)[:, :2].T
    s0, s1 = u0 * c + v0 * s, u1 * c + v1 * s
    k = 2 * np.pi / waves.wavelength
    x = np.linspace(0.0, 1.0, 4001)[None]
    slope = waves.amplitude * k * np.cos(k * (s0[:, None] + (s1 - s0)[:, None] * x))
    along = (s1 - s0) * np.trapezoid(np.sqrt(1 + slope * slope), x, axis=1)
    out: np.ndarray = np.hypot(along, (-u1 * s + v1 * c) - (-u0 * s + v0 * c))
    return out


def test_a_corrugated_walls_sides_are_measured_as_its_development_has_them() -> None:
    """Sides of the adaptive grid's size (12.8 px) in every direction across the fine
    corrugations (54 px waves): a chord cuts a wave's bend short by up to 1.4 %, and by
    how much depends on where the side sits on the wave; measured in 4 chords laid flat
    the error is that of a chord a quarter of the side long, ``(a k^2 h / 4)^2 / 24``
    ~ 1e-3 (``h`` the side on the surface): 0.0011 at most here."""
    waves = get_surface("waves-fine")
    assert isinstance(waves, Waves)
    s = simulate_surface(waves, step=2)
    rng = np.random.default_rng(0)
    a = rng.uniform([200.0, 150.0], [1080.0, 650.0], size=(400, 2))
    turn = rng.uniform(0.0, np.pi, 400)
    b = a + 12.8 * np.stack([np.cos(turn), np.sin(turn)], axis=1)
    pa, pb = s.points_at(a), s.points_at(b)
    exact = _developed(waves, pa, pb)
    chord = np.linalg.norm(pb - pa, axis=1)
    assert np.abs(chord / exact - 1).max() > 0.01  # what the chords were
    assert np.abs(developed_lengths(s, a, b, 4) / exact - 1).max() < 0.002


def test_on_a_plane_the_developed_length_is_the_chord() -> None:
    s = simulate_surface("tilted", step=4)
    a = np.array([[100.0, 100.0], [600.0, 400.0], [900.0, 700.0]])
    b = a + np.array([[40.0, 30.0], [-25.0, 60.0], [13.0, -7.0]])
    chord = np.linalg.norm(s.points_at(b) - s.points_at(a), axis=1)
    # the chords of one straight line, laid flat unturned: the lattice's points are
    # float32, so its samples stray off the line by their rounding (6e-8 of a depth)
    np.testing.assert_allclose(developed_lengths(s, a, b, 4), chord, rtol=1e-7)
