"""Distances on a surface's development, from its point map.

A grid triangle's shape taken from its three corners (its chords) cuts every bend of
the surface between them short. Where the grid's cells are a good share of a bend
(corrugations a few cells long, cut by the grid at an angle), a chord is shortened by
how the edge happens to sit on the wave, so neighbouring triangles disagree: the chord
triangles of a developable wall then carry angle defects (0.027 rad a vertex on a
corrugated wall whose 54 px waves run at 29 deg to a 12.8 px grid) and a conformal
solve answers them with a scale field that a development does not have.

:func:`developed_lengths` measures an edge as a development has it instead: the curve
under the edge's pixel segment, sampled in a few chords, is laid flat - each chord
turned from the last by the curve's turn in the surface's tangent plane (its geodesic
curvature, which a development keeps), a bend across the surface unrolled - and the
distance between its ends taken. On a developable surface that is the ends' distance
in the development, to second order in the chords' length (the same corrugated wall:
0.001 rad a vertex); on a plane it is the chord.
"""

from __future__ import annotations

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.triangles import cross_first, dot_first


def developed_lengths(
    surface: Surface, start: FloatArray, end: FloatArray, steps: int
) -> FloatArray:
    """Distances (E,) on the development of ``surface`` between projector pixels
    ``start`` (E, 2) and ``end`` (E, 2) (see the module's description), the curve
    between them sampled in ``steps`` >= 2 chords; NaN where a sample has no surface.

    Examples
    --------
    >>> from adaproj_edge.geometry.analytic import simulate_surface
    >>> s = simulate_surface("plane")
    >>> a, b = np.array([[100.0, 100.0]]), np.array([[140.0, 130.0]])
    >>> chord = np.linalg.norm(s.points_at(b) - s.points_at(a))
    >>> bool(abs(developed_lengths(s, a, b, 4)[0] - chord) < 1e-7 * chord)
    True
    """
    e = start.shape[0]
    t = np.arange(steps + 1, dtype=np.float64) / steps
    along = end - start
    uv = start[:, None] + t[None, :, None] * along[:, None]  # (E, steps + 1, 2)
    # a pixel to either side of the inner samples, across the segment: the tangent plane
    with np.errstate(invalid="ignore", divide="ignore"):
        side = np.stack([-along[:, 1], along[:, 0]], axis=1)
        side /= np.sqrt(np.sum(along * along, axis=1))[:, None]
    inner = uv[:, 1:-1]
    across = np.concatenate([inner + side[:, None], inner - side[:, None]], axis=1)
    every = np.concatenate([uv, across], axis=1)  # (E, 3 steps - 1, 2)
    pts = _points(surface, every[..., 0], every[..., 1])  # (3, E, 3 steps - 1)
    p, plus, minus = (
        pts[:, :, : steps + 1],
        pts[:, :, steps + 1 : 2 * steps],
        pts[:, :, 2 * steps :],
    )
    d = p[:, :, 1:] - p[:, :, :-1]  # (3, E, steps) the chords
    lengths = np.sqrt(dot_first(d, d))
    n = cross_first(p[:, :, 2:] - p[:, :, :-2], plus - minus)  # (3, E, steps - 1) normals
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.sqrt(dot_first(n, n))
    a, b = d[:, :, :-1], d[:, :, 1:]  # the chords meeting at each inner sample, laid flat
    a = a - dot_first(a, n) * n
    b = b - dot_first(b, n) * n
    turn = np.arctan2(dot_first(n, cross_first(a, b)), dot_first(a, b))
    heading = np.concatenate([np.zeros((e, 1)), np.cumsum(turn, axis=1)], axis=1)
    flat_x = np.sum(lengths * np.cos(heading), axis=1)
    flat_y = np.sum(lengths * np.sin(heading), axis=1)
    out: FloatArray = np.sqrt(flat_x * flat_x + flat_y * flat_y)
    return out


def _points(surface: Surface, u: FloatArray, v: FloatArray) -> FloatArray:
    """``surface.points_at`` pixels (``u``, ``v``) (...), component-first (3, ...)."""
    depth = surface.depth_at(np.stack([u, v], axis=-1))
    k = np.linalg.inv(surface.projector.K)
    rays = [k[i, 0] * u + k[i, 1] * v + k[i, 2] for i in range(3)]
    out: FloatArray = np.stack([rays[0] / rays[2] * depth, rays[1] / rays[2] * depth, depth])
    return out
