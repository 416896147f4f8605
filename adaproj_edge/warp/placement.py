"""Placing a solved mesh on the content: upright on the surface, content fully inside.

A solve gives content-space positions up to a similarity. Placement picks it: the
rotation that makes "down" on the surface (:mod:`~adaproj_edge.warp.upright`: gravity
on a wall, toward the device on a floor) point down in the content, then the similarity
that makes the content rectangle the maximal inscribed rectangle of the covered region
(paper §4.1).

Placed again for a new estimate of the same surface, the rectangle is kept where the
last one was (``anchor``: its centre's projector pixel, :attr:`Placement.uv`) while it
is nearly as large as a fresh search's (:func:`~adaproj_edge.geometry.rectangle.
inscribed_rectangle`'s ``keep``): a fresh search on each estimate lands in one local
optimum or another, and on a corner the content jumped along the ridge by tens of
pixels between consecutive depth frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.geometry.rectangle import NEAR, Rect, boundary_loops, inscribed_rectangle
from adaproj_edge.geometry.triangles import carry_through_triangles
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.solve import PLANE_SHAPE
from adaproj_edge.warp.upright import upright

DEFAULT_UP = (0.0, -1.0, 0.0)  # "up" in frame P when the projector is held level


@dataclass(frozen=True)
class Placement:
    """``content = scale * R(angle) @ v + offset``, in content pixels."""

    angle: float
    scale: float
    offset: FloatArray
    centre: FloatArray | None = None  # the rectangle's centre before scaling (warm starts)
    uv: FloatArray | None = None  # the rectangle's centre in projector pixels (anchors)
    kept: bool = False  # placed to keep an anchor: placements from it keep its centre

    def for_scaled(self, k: float) -> Placement:
        """The same placement of positions scaled by ``k`` (``v * k``): the content lands
        where it did, and the rectangle's centre, in the positions' units, scales too."""
        centre = None if self.centre is None else self.centre * k
        return Placement(self.angle, self.scale / k, self.offset, centre, self.uv, self.kept)

    @cached_property
    def _rotation(self) -> FloatArray:
        """R(angle), made once (a warp applies its placement many times)."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.array([[c, -s], [s, c]])

    def apply(self, v: FloatArray) -> FloatArray:
        """Content positions (n, 2) of the solved positions ``v`` (n, 2)."""
        out: FloatArray = self.scale * (v @ self._rotation.T) + self.offset
        return out


def upright_angle(
    mesh: MeshGeometry, v: FloatArray, up: FloatArray, among: NDArray[np.bool_] | None = None
) -> float:
    """Rotation that turns the surface's down direction to +y in content space.

    "Down" is decided by the rule of :func:`~adaproj_edge.warp.upright.upright` from
    gravity's ``up`` (frame P): gravity on a wall, toward the device on a floor (among
    the triangles ``among`` (T,) only, when given). For each triangle that votes, down
    projected on its plane is carried into content space by the triangle's affine map;
    the mean direction (weighted by surface area times how far down lies in the plane,
    times ``1 + PLANE_SHAPE`` on a snapped plane's triangles, as in the solve: the
    warp holds those undistorted and bends the rest) defines the rotation. Returns 0
    when down has no direction on the surface.
    """
    rule = upright(mesh, np.asarray(up, dtype=np.float64), among)
    down = -rule.up
    key = "down " + " ".join(f"{x:.17g}" for x in down)
    a, b, area, weight, ok = mesh.remember(key, lambda: _down_on_surface(mesh, down))
    if rule.votes is not None:
        ok = ok & rule.votes
    corners = _corners(mesh)
    x, y = np.take(v[:, 0], corners), np.take(v[:, 1], corners)  # (3, T)
    dx = a * (x[1] - x[0]) + b * (x[2] - x[0])
    dy = a * (y[1] - y[0]) + b * (y[2] - y[0])
    norm = np.sqrt(dx * dx + dy * dy)
    good = ok & (norm > 0)
    if not np.any(good):
        return 0.0
    w = np.divide(weight, norm, out=np.zeros_like(norm), where=good)  # per unit direction
    # a snapped plane's triangles are held undistorted (their E_a weighs 1 + PLANE_SHAPE):
    # their down is the one a viewer sees; the rest takes the bending the plane refuses,
    # and its votes turn with it, so the held triangles vote at their weight in the solve
    # where down lies in their plane (not a floor's under the wall rule: there gravity
    # has no direction, and a held floor would outvote the wall)
    held = mesh.planar & (weight > HELD_ALONG * area)
    w = w * (1.0 + PLANE_SHAPE * held)
    mean = np.array([dx @ w, dy @ w])
    if np.linalg.norm(mean) < 1e-12 * max(float(np.sum(area)), 1e-300):
        return 0.0
    # rotate mean direction onto +y: angle = atan2(mean) -> pi/2
    return float(np.pi / 2 - np.arctan2(mean[1], mean[0]))


def _corners(mesh: MeshGeometry) -> IntArray:
    """The triangles' vertex indices corner by corner (3, T): gathers with ``np.take``
    and sums over the corners along rows, several times quicker than ``v[mesh.tris]``
    and sums down its short axis."""
    return mesh.topology.remember("corners", lambda: np.ascontiguousarray(mesh.tris.T))


def _down_on_surface(
    mesh: MeshGeometry, down: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """``down`` (3,) projected on each triangle's plane, in the basis of its two edges
    from corner 0: coefficients a, b (T,), the triangles' surface areas, their weights
    (area times the projection's length) and where the basis is sound (T,) - the part
    of :func:`upright_angle` that depends on the mesh alone."""
    corners, points = _corners(mesh), mesh.p
    e1, e2 = [], []
    for k in range(3):  # coordinate by coordinate: (3, T) each
        p = np.take(points[:, k], corners)
        e1.append(p[1] - p[0])
        e2.append(p[2] - p[0])
    ax, ay, az = e1
    bx, by, bz = e2
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx  # e1 x e2
    twice_area = np.sqrt(nx * nx + ny * ny + nz * nz)
    with np.errstate(invalid="ignore", divide="ignore"):  # degenerate: NaN, not ok below
        nx, ny, nz = nx / twice_area, ny / twice_area, nz / twice_area
    across = nx * down[0] + ny * down[1] + nz * down[2]
    gx, gy, gz = down[0] - across * nx, down[1] - across * ny, down[2] - across * nz
    # express g in the (e1, e2) basis: solve [e1 e2] [a b]^T = g (least squares)
    m11 = ax * ax + ay * ay + az * az
    m12 = ax * bx + ay * by + az * bz
    m22 = bx * bx + by * by + bz * bz
    r1 = ax * gx + ay * gy + az * gz
    r2 = bx * gx + by * gy + bz * gz
    det = m11 * m22 - m12 * m12
    ok = det > 1e-18
    a = np.where(ok, (m22 * r1 - m12 * r2) / np.where(ok, det, 1.0), 0.0)
    b = np.where(ok, (m11 * r2 - m12 * r1) / np.where(ok, det, 1.0), 0.0)
    area = 0.5 * twice_area
    strength = np.sqrt(gx * gx + gy * gy + gz * gz)
    return a, b, area, area * strength, ok


HELD_ALONG = math.sin(math.radians(45.0))  # down this much in a held plane: it votes held
MIN_UNDER = 8  # triangles under the content that decide its up (fewer: the whole mesh's)
SAME_ANGLE = math.radians(1.0)  # a rotation this close to the first is kept (no second search)
TURN_KEPT = math.radians(0.1)  # a turn of the mesh under the content this small is not followed


def _rectangle(
    mesh: MeshGeometry,
    v: FloatArray,
    angle: float,
    aspect: float,
    start: FloatArray | None,
    keep: FloatArray | None = None,
) -> Rect:
    """The inscribed rectangle of ``aspect`` of positions ``v`` (n, 2) turned by
    ``angle``, climbing from ``start`` (a centre) when given, kept at ``keep`` (a
    centre) while it stays nearly the largest."""
    vr = Placement(angle, 1.0, np.zeros(2)).apply(v)
    loops = mesh.topology.remember("boundary loops", lambda: boundary_loops(mesh.boundary) or [])
    return inscribed_rectangle(
        vr, mesh.tris, aspect, boundary=mesh.boundary, start=start, near=NEAR, loops=loops,
        keep=keep,
    )  # fmt: skip


def _under(mesh: MeshGeometry, vr: FloatArray, rect: Rect) -> NDArray[np.bool_]:
    """The triangles (T,) whose centroid (of the turned positions ``vr`` (n, 2)) lies in
    ``rect``: those the content is shown on."""
    c = vr[mesh.tris].mean(axis=1)
    x, y = c[:, 0], c[:, 1]
    inside: NDArray[np.bool_] = (
        (x >= rect.x0) & (x <= rect.x0 + rect.width) & (y >= rect.y0) & (y <= rect.y0 + rect.height)
    )
    return inside


def place(
    mesh: MeshGeometry,
    v: FloatArray,
    content_size: tuple[int, int],
    up: FloatArray | tuple[float, float, float] = DEFAULT_UP,
    previous: Placement | None = None,
    anchor: FloatArray | None = None,
) -> Placement:
    """Upright rotation and inscribed-rectangle similarity for positions ``v`` (n, 2).

    With ``previous`` (the placement of a nearby iterate) its rotation is kept and the
    rectangle search starts from its centre: the alternation's cheap placement. The
    content is centred on the covered region when that costs at most ``NEAR`` of its
    size (:mod:`adaproj_edge.geometry.rectangle`): where the largest rectangle can
    slide (content of another aspect than the region, a tilted wall, a region turned in
    a rolled projector's frame) a person expects it in the middle, and consecutive
    frames do not jump between the ends of a ridge. The rectangle is kept where it was
    (``previous``'s centre; else ``anchor`` (2,), the projector pixel where the last
    placement of this surface had its centre) while it stays nearly as large as the
    largest: the placement is continuous in the surface. ``previous``'s centre is kept
    only when it was placed so (``Placement.kept``: an anchored placement and the
    refinement's from it); otherwise, as in a one-shot warp, each placement is centred
    afresh and the alternation's result does not depend on where it started.
    """
    w, h = content_size
    corners = mesh.tris
    up_p = np.asarray(up, dtype=np.float64)

    def anchored(angle: float) -> FloatArray | None:
        """``anchor`` carried into the placement turned by ``angle`` (None: off it)."""
        if anchor is None:
            return None
        vr = Placement(angle, 1.0, np.zeros(2)).apply(v)
        at = np.asarray(anchor, dtype=np.float64).reshape(1, 2)
        found = carry_through_triangles(mesh.uv[corners], vr[corners], at)[0]
        return found if np.all(np.isfinite(found)) else None

    if previous is None:
        angle = upright_angle(mesh, v, up_p)
        keep = anchored(angle)
        rect = _rectangle(mesh, v, angle, w / h, None, keep)
        # the up of the part the content lands on (a piece's flattening turns "down"
        # from place to place; the mean over all of it is not the content's)
        under = _under(mesh, Placement(angle, 1.0, np.zeros(2)).apply(v), rect)
        if under.sum() >= MIN_UNDER:
            again = upright_angle(mesh, v, up_p, under)
            if abs(np.angle(np.exp(1j * (again - angle)))) > SAME_ANGLE:
                angle = again
                keep = anchored(angle)
                rect = _rectangle(mesh, v, angle, w / h, None, keep)
    else:
        angle = previous.angle
        keep = previous.centre if previous.kept else None
        rect = _rectangle(mesh, v, angle, w / h, previous.centre, keep)
    vr = Placement(angle, 1.0, np.zeros(2)).apply(v)
    scale = w / rect.width
    # content pixel centres at integers: the rectangle's corner is pixel (-0.5, -0.5)
    offset = np.array([-0.5 - scale * rect.x0, -0.5 - scale * rect.y0])
    centre = np.array([rect.x0 + rect.width / 2, rect.y0 + rect.height / 2])
    uv = carry_through_triangles(vr[corners], mesh.uv[corners], centre[None, :])[0]
    known = uv if np.all(np.isfinite(uv)) else None
    return Placement(angle, scale, offset, centre, known, keep is not None)


def turned_with_mesh(
    mesh: MeshGeometry,
    origin: FloatArray,
    v: FloatArray,
    placement: Placement,
    content_size: tuple[int, int],
    up: FloatArray | tuple[float, float, float] = DEFAULT_UP,
) -> Placement:
    """The placement to show positions ``v`` (n, 2) with: ``placement`` (whose rotation
    was made upright for the positions ``origin`` (n, 2) and kept since) turned by as
    much as the mesh under the content turned from ``origin`` to ``v``, less
    :data:`TURN_KEPT` (a dead band: the result is continuous in ``v``), and the
    content placed again at that rotation. With fewer than :data:`MIN_UNDER` triangles
    under the content the turn cannot be told, and ``placement`` is kept.

    The content-aware alternation keeps its start's rotation of the content while its
    solves turn the mesh under it (a degree on a rolled device before a turned wall).
    Its own iterates, and a warm start from them, keep that rotation: the turn is only
    shown, so a warm-started sequence settles as it would without it.
    """
    c = placement.apply(v)[mesh.tris].mean(axis=1)  # the triangles the content is on
    w, h = content_size
    on = (c[:, 0] >= -0.5) & (c[:, 0] <= w - 0.5) & (c[:, 1] >= -0.5) & (c[:, 1] <= h - 0.5)
    if int(on.sum()) < MIN_UNDER:
        # too few triangles under the content to tell how it turned: the whole mesh's
        # turn is the turn of what the content is not on (a small picture on a real
        # desk, 3 coarse triangles under it: the rest, a wall, turned it 11.6 deg)
        return placement
    up_p = np.asarray(up, dtype=np.float64)
    turn = upright_angle(mesh, v, up_p, on) - upright_angle(mesh, origin, up_p, on)
    turn = float(np.angle(np.exp(1j * turn)))
    if abs(turn) <= TURN_KEPT:
        return placement
    turned = replace(placement, angle=placement.angle + turn - math.copysign(TURN_KEPT, turn))
    return place(mesh, v, content_size, up_p, turned)
