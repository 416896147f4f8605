"""Placing a solved mesh on the content: upright on the surface, content fully inside.

A solve gives content-space positions up to a similarity. Placement picks it: the
rotation that makes "down" on the surface (gravity, or the projector's y axis) point
down in the content, then the similarity that makes the content rectangle the
maximal inscribed rectangle of the covered region (paper §4.1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.rectangle import NEAR, boundary_loops, inscribed_rectangle
from adaproj_edge.geometry.triangles import cross, triangle_normals
from adaproj_edge.warp.mesh import MeshGeometry

DEFAULT_UP = (0.0, -1.0, 0.0)  # "up" in frame P when the projector is held level


@dataclass(frozen=True)
class Placement:
    """``content = scale * R(angle) @ v + offset``, in content pixels."""

    angle: float
    scale: float
    offset: FloatArray
    centre: FloatArray | None = None  # the rectangle's centre before scaling (warm starts)

    def apply(self, v: FloatArray) -> FloatArray:
        """Content positions (n, 2) of the solved positions ``v`` (n, 2)."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        r = np.array([[c, -s], [s, c]])
        out: FloatArray = self.scale * (v @ r.T) + self.offset
        return out


def upright_angle(mesh: MeshGeometry, v: FloatArray, up: FloatArray) -> float:
    """Rotation that turns the surface's down direction to +y in content space.

    For each triangle, ``-up`` projected on its plane is carried into content space by
    the triangle's affine map; the mean direction (weighted by surface area times how
    far down lies in the plane) defines the rotation. Returns 0 when the surface is
    level (down has no direction on it).
    """
    down = -np.asarray(up, dtype=np.float64)
    down = down / np.linalg.norm(down)
    key = "down " + " ".join(f"{x:.17g}" for x in down)
    a, b, area, weight, ok = mesh.remember(key, lambda: _down_on_surface(mesh, down))
    q = v[mesh.tris]  # (T, 3, 2)
    d = a[:, None] * (q[:, 1] - q[:, 0]) + b[:, None] * (q[:, 2] - q[:, 0])
    norm = np.linalg.norm(d, axis=1)
    good = ok & (norm > 0)
    if not np.any(good):
        return 0.0
    unit = d[good] / norm[good, None]
    mean = np.sum(unit * weight[good, None], axis=0)
    if np.linalg.norm(mean) < 1e-12 * max(float(np.sum(area)), 1e-300):
        return 0.0
    # rotate mean direction onto +y: angle = atan2(mean) -> pi/2
    return float(np.pi / 2 - np.arctan2(mean[1], mean[0]))


def _down_on_surface(
    mesh: MeshGeometry, down: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """``down`` (3,) projected on each triangle's plane, in the basis of its two edges
    from corner 0: coefficients a, b (T,), the triangles' surface areas, their weights
    (area times the projection's length) and where the basis is sound (T,) - the part
    of :func:`upright_angle` that depends on the mesh alone."""
    p = mesh.p[mesh.tris]  # (T, 3, 3)
    n = triangle_normals(p)
    g = down[None, :] - np.sum(n * down, axis=1, keepdims=True) * n
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    # express g in the (e1, e2) basis: solve [e1 e2] [a b]^T = g (least squares)
    m11 = np.sum(e1 * e1, axis=1)
    m12 = np.sum(e1 * e2, axis=1)
    m22 = np.sum(e2 * e2, axis=1)
    r1 = np.sum(e1 * g, axis=1)
    r2 = np.sum(e2 * g, axis=1)
    det = m11 * m22 - m12 * m12
    ok = det > 1e-18
    a = np.where(ok, (m22 * r1 - m12 * r2) / np.where(ok, det, 1.0), 0.0)
    b = np.where(ok, (m11 * r2 - m12 * r1) / np.where(ok, det, 1.0), 0.0)
    area = 0.5 * np.linalg.norm(cross(e1, e2), axis=1)
    strength = np.linalg.norm(g, axis=1)
    return a, b, area, area * strength, ok


def place(
    mesh: MeshGeometry,
    v: FloatArray,
    content_size: tuple[int, int],
    up: FloatArray | tuple[float, float, float] = DEFAULT_UP,
    previous: Placement | None = None,
) -> Placement:
    """Upright rotation and inscribed-rectangle similarity for positions ``v`` (n, 2).

    With ``previous`` (the placement of a nearby iterate) its rotation is kept and the
    rectangle search starts from its centre: the alternation's cheap placement. The
    content is centred on the covered region when that costs at most ``NEAR`` of its
    size (:mod:`adaproj_edge.geometry.rectangle`): where the largest rectangle can
    slide (content of another aspect than the region, a tilted wall, a region turned in
    a rolled projector's frame) a person expects it in the middle, and consecutive
    frames do not jump between the ends of a ridge.
    """
    if previous is None:
        angle = upright_angle(mesh, v, np.asarray(up, dtype=np.float64))
        start = None
    else:
        angle, start = previous.angle, previous.centre
    rot = Placement(angle, 1.0, np.zeros(2))
    vr = rot.apply(v)
    w, h = content_size
    loops = mesh.topology.remember("boundary loops", lambda: boundary_loops(mesh.boundary) or [])
    rect = inscribed_rectangle(
        vr, mesh.tris, w / h, boundary=mesh.boundary, start=start, near=NEAR, loops=loops
    )
    scale = w / rect.width
    # content pixel centres at integers: the rectangle's corner is pixel (-0.5, -0.5)
    offset = np.array([-0.5 - scale * rect.x0, -0.5 - scale * rect.y0])
    centre = np.array([rect.x0 + rect.width / 2, rect.y0 + rect.height / 2])
    return Placement(angle, scale, offset, centre)
