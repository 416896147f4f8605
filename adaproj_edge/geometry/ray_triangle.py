"""Ray-triangle intersection in float64 numpy (Möller-Trumbore).

Two uses: :func:`intersect_brute_force` tests every ray against every triangle (the
reference the BVH caster is tested against, and the fallback without it), and
:func:`ray_triangle` gives the exact float64 hit of rays on known triangles (the BVH
caster finds the triangle in float32 and takes the distance from here, so both
casters give the same numbers).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, FloatArray

MIN_DET = 1e-12
"""Rays closer to parallel to a triangle than this (|det|) do not hit it."""
MIN_T = 1e-9
"""Hits at ray parameters up to this are behind the origin (or at it): not hits."""
_PAIRS_PER_CHUNK = 500_000


def ray_triangle(
    origins: FloatArray, dirs: FloatArray, v0: FloatArray, e1: FloatArray, e2: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Möller-Trumbore for rays against triangles, broadcast over leading axes.

    Parameters
    ----------
    origins, dirs : (..., 3) float64
        Ray origins and directions (any length; t is in multiples of it).
    v0, e1, e2 : (..., 3) float64
        Each triangle's first vertex and its two edges from it (``v1 - v0``, ``v2 - v0``).

    Returns
    -------
    t, u, v, det : (...,) float64
        Ray parameter of the hit on the triangle's plane, barycentric coordinates of
        the hit (inside the triangle: ``u >= 0``, ``v >= 0``, ``u + v <= 1``) and the
        determinant (about 0: the ray is parallel to the plane; then t, u, v are
        inf or NaN).
    """
    with np.errstate(all="ignore"):  # parallel, degenerate or non-finite rays: no hit
        p = np.cross(dirs, e2)
        det = np.sum(e1 * p, axis=-1)
        inv = 1.0 / det
        tv = origins - v0
        u = np.sum(tv * p, axis=-1) * inv
        q = np.cross(tv, e1)
        v = np.sum(dirs * q, axis=-1) * inv
        t = np.sum(e2 * q, axis=-1) * inv
    return t, u, v, det


def triangle_edges(
    vertices: FloatArray, faces: NDArray[np.int64]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Each triangle's first vertex and its two edges from it, as :func:`ray_triangle` takes.

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices.
    faces : (M, 3) int64
        Vertex indices of each triangle.

    Returns
    -------
    v0, e1, e2 : (M, 3) float64
        ``v[f0]``, ``v[f1] - v[f0]``, ``v[f2] - v[f0]``.
    """
    tri = vertices[faces]
    v0 = tri[:, 0]
    return v0, tri[:, 1] - v0, tri[:, 2] - v0


def _is_hit(t: FloatArray, u: FloatArray, v: FloatArray, det: FloatArray) -> BoolArray:
    """Which results of :func:`ray_triangle` are hits (inside, not parallel, t > 0)."""
    with np.errstate(invalid="ignore"):
        ok: BoolArray = (np.abs(det) > MIN_DET) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > MIN_T)
    return ok


def intersect_brute_force(
    vertices: FloatArray, faces: NDArray[np.int64], origins: FloatArray, dirs: FloatArray
) -> FloatArray:
    """Ray parameter t (N,) of the nearest hit with t > 0 of each ray, NaN where none.

    Every ray is tested against every triangle, a few rays at a time: exact and
    simple, but its time grows with rays x triangles (fine for a warp grid on a
    few thousand triangles, not for images of large meshes).

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices.
    faces : (M, 3) int64
        Vertex indices of each triangle.
    origins, dirs : (N, 3) float64
        Ray origins and directions.

    Returns
    -------
    (N,) float64
        t of the nearest hit (the hit point is ``origin + t * dir``), NaN for none.
    """
    v0, e1, e2 = triangle_edges(vertices, faces)
    out = np.full(len(dirs), np.nan)
    chunk = max(1, _PAIRS_PER_CHUNK // len(faces))
    for s in range(0, len(dirs), chunk):
        t, u, v, det = ray_triangle(
            origins[s : s + chunk, None, :], dirs[s : s + chunk, None, :], v0, e1, e2
        )
        best = np.where(_is_hit(t, u, v, det), t, np.inf).min(axis=1)
        out[s : s + chunk] = np.where(np.isfinite(best), best, np.nan)
    return out
