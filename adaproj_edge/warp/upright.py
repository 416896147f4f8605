"""Which way is up on a surface: one rule, decided once per mesh and gravity.

- **A wall** (the surface under the content's centre more than 45 deg from level):
  gravity. The content's vertical follows "up" on every triangle (the weighted mean of
  :func:`~adaproj_edge.warp.placement.upright_angle`).
- **A floor or a table** (its normal within 45 deg of gravity): away from the device,
  along its forward direction (the projector's optical axis, +z of frame P) projected
  onto the surface; only the level triangles vote (gravity has no direction on a level
  surface, and a wall beside it would pull its own way). Looking straight down, where
  forward has no direction on the floor either, the device's top (-y of frame P) takes
  over, smoothly: a device pitched down from level and on past the vertical keeps
  the same "away".
- **Across a wall and a floor**: the rule of the part the content's centre lies on.

The placement (:func:`~adaproj_edge.warp.placement.place`) decides the rule again
among the triangles its rectangle lands on, and turns the content by their votes
alone: the flattening of a messy piece (real depth: objects, curtains, a wall and
the floor) turns "down" from place to place, and the mean over the whole piece is
not the up where the content is.

Never upside down: on a wall up is gravity's; on a floor it points away from the device.
The content's centre is taken where it is in the projector's frame: the centre of the
lit region (the mesh's pixel-area centroid), where the placement centres it
(:mod:`~adaproj_edge.geometry.rectangle`) and where the device is aimed. It depends on
the mesh alone, so two warps of one surface (content-aware and conformal, say) are
upright the same way; a floor seen grazing, whose flattened area dwarfs the rest,
does not take over a picture aimed at a wall.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.warp.mesh import MeshGeometry

LEVEL_COS = float(np.cos(np.deg2rad(45.0)))  # a normal this close to gravity is level
CENTRE_SHARE = 0.1  # the triangles nearest the content's centre, by area, that decide
FORWARD = np.array([0.0, 0.0, 1.0])  # the device's forward in frame P
TOP = np.array([0.0, -1.0, 0.0])  # the device's top in frame P
FORWARD_MIN = 0.1  # below this length of forward on the floor (84 deg down), the top joins in

Rule = Literal["wall", "floor"]


@dataclass(frozen=True)
class Upright:
    """The rule chosen for a mesh, and what it asks of the placement.

    Attributes
    ----------
    rule : "wall" or "floor"
    up : (3,) float array
        Unit "up" in frame P the triangles' votes follow (gravity on a wall, the away
        direction on a floor).
    votes : (T,) bool array or None
        The triangles that vote (None: all).
    """

    rule: Rule
    up: FloatArray
    votes: NDArray[np.bool_] | None


def upright(
    mesh: MeshGeometry, gravity_up: FloatArray, among: NDArray[np.bool_] | None = None
) -> Upright:
    """The up rule for ``mesh`` and gravity's "up" ``gravity_up`` (3,) in frame P: made
    once per gravity and kept with the mesh, so every placement of the mesh
    (content-free, conformal, guarded, refined) is upright the same way.

    With ``among`` (T,) the rule is decided by, and its votes restricted to, those
    triangles (the ones the content is placed on: a messy piece's flattening turns
    "down" from place to place, and the content's own part decides its up)."""
    g = np.asarray(gravity_up, dtype=np.float64)
    g = g / np.linalg.norm(g)
    if among is not None:
        return _decide(mesh, g, among)
    key = "upright " + " ".join(f"{x:.17g}" for x in g)
    return mesh.remember(key, lambda: _decide(mesh, g))


def _normals(mesh: MeshGeometry) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], FloatArray]:
    """The triangles' unit normals (T, 3) (0 where degenerate), twice their surface
    areas (T,), where they are sound (T,) and their pixel areas (T,): of the mesh
    alone, kept with it (every placement decides its up again)."""

    def make() -> tuple[FloatArray, FloatArray, NDArray[np.bool_], FloatArray]:
        p = mesh.p
        t = mesh.tris
        n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
        area = np.linalg.norm(n, axis=1)
        ok = np.isfinite(area) & (area > 0)
        unit = np.where(ok[:, None], n / np.where(ok, area, 1.0)[:, None], 0.0)
        return unit, area, ok, mesh.pixel_areas

    return mesh.remember("upright normals", make)


def _decide(mesh: MeshGeometry, g: FloatArray, among: NDArray[np.bool_] | None = None) -> Upright:
    """:func:`upright`, made (``g`` unit)."""
    t = mesh.tris
    unit, area, ok, pixel_areas = _normals(mesh)
    if among is not None:
        ok = ok & among
        n = np.where(ok[:, None], unit, 0.0)
    else:
        n = unit
    level = ok & (np.abs(n @ g) > LEVEL_COS)
    votes = None if among is None else ok
    if not level.any():
        return Upright("wall", g, votes)  # nothing level: every vote is gravity's
    w = np.where(ok, pixel_areas, 0.0)
    if among is None:
        # the content's centre: the lit region's centre in the projector's frame; the
        # triangles nearest it hold CENTRE_SHARE of the lit pixels and decide
        uv = mesh.uv
        centres = uv[t].mean(axis=1)
        c = (centres * w[:, None]).sum(axis=0) / max(float(w.sum()), 1e-300)
        order = np.argsort(np.sum((centres - c) ** 2, axis=1), kind="stable")
        cum = np.cumsum(w[order])
        near = order[: int(np.searchsorted(cum, CENTRE_SHARE * cum[-1])) + 1]
    else:
        near = np.flatnonzero(ok)
    if w[near][level[near]].sum() <= 0.5 * w[near].sum():
        return Upright("wall", g, votes)
    # the floor's plane: its level triangles' mean normal (by surface area), turned to
    # gravity's side
    w = np.where(ok, area, 0.0)
    ns = n[level] * np.sign(n[level] @ g)[:, None]
    normal = (ns * w[level][:, None]).sum(axis=0)
    normal /= np.linalg.norm(normal)
    away = FORWARD - (FORWARD @ normal) * normal
    length = float(np.linalg.norm(away))
    if length < FORWARD_MIN:  # looking (nearly) straight down: the device's top helps
        top = TOP - (TOP @ normal) * normal
        away = away + (FORWARD_MIN - length) * top / max(float(np.linalg.norm(top)), 1e-12)
    return Upright("floor", away / np.linalg.norm(away), level)
