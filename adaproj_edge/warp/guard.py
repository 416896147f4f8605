"""Never worse than conformal on what matters: the content-aware warp checked against the
conformal one on the salient region, by the engine's own measure.

The content-aware energy trades angle for size consistency on the subject; on most
surfaces both improve, but where the mesh cannot follow the surface (a crease, relief
finer than the grid) the trade can go wrong. :func:`guard` scores both candidates the
way the displayed distortion is scored - per mesh triangle, the Jacobian of the map
content -> surface, angle error ``sigma1 / sigma2 - 1`` and the spread of
``log sqrt(sigma1 sigma2)`` over the triangles that show salient content, each
weighted by its projector area and the salient share of it - and keeps the
content-aware warp when it is no worse on both, else the largest blend toward the
conformal warp that is (the conformal warp itself in the end); on a large subject the
content-aware and conformal warps are also tried with their size flattened
(:mod:`~adaproj_edge.warp.flatten`). ``meta`` says which and why. Both the full-grid
path (:func:`~adaproj_edge.warp.engine.content_aware`) and the device's coarse-to-fine
refinement (:class:`~adaproj_edge.warp.planner.WarpPlanner`) call it with their two
vertex sets.

The full-grid path also gives the surface: there a candidate the mesh finds better by
less than :data:`SURE` is judged as the per-pixel display shows it
(:mod:`~adaproj_edge.warp.displayed`: within a cell, relief and the seams' blending add
angle error the mesh does not see), and so is every candidate when a crease runs
through the subject (the mesh measures a creased triangle by its unfolded shape alone;
on a floor seen grazing under a cylinder, seed 1 case 193 of ``tools/stress_warp.py``,
it found the content-aware warp 0.21x the conformal warp's size inconsistency where the
display showed 1.025x). The device's display interpolates the mesh itself, so its guard
keeps the mesh measure.

About 430 lines: the measure, the choice and the judge of what is kept belong together.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import ContentMap
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.displayed import DisplaySamples, creased
from adaproj_edge.warp.flatten import flattened
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.orientation import unfolded
from adaproj_edge.warp.placement import DEFAULT_UP, Placement, place

# the content-aware warp must be this much better than the conformal one on each count
# (the mesh measure differs a little from the per-pixel one of the display)
MARGIN = 0.03
# a candidate this much better on the mesh is taken without looking at the display (by
# the mesh and as displayed, the angle error's ratio differed by up to 6 % on the bumps)
SURE = 0.10
# and distortion below this counts as none (a developable surface: both are exact)
FLOOR = 2e-4
BLENDS = (0.75, 0.5, 0.25)  # share of the content-aware warp in the blends tried
# a content-aware warp above this share of the conformal warp's size inconsistency on the
# subject (the issues' goal for it) is tried with its size flattened first
FLATTEN_ABOVE = 0.6


@dataclass(frozen=True)
class SubjectDistortion:
    """Distortion of the salient part of a warp, by the mesh.

    angle : weighted mean of sigma1 / sigma2 - 1
    size : weighted standard deviation of log sqrt(sigma1 sigma2)
    weight : total weight (projector pixels x salient share); 0 when nothing salient shows
    """

    angle: float
    size: float
    weight: float

    def as_dict(self) -> dict[str, float]:
        """The measures as a JSON-ready dict (the warp's ``meta``)."""
        return {"angle": self.angle, "size": self.size, "weight": self.weight}


@dataclass(frozen=True)
class Choice:
    """What :func:`guard` keeps: positions (n, 2), their placement, the share ``t`` of the
    content-aware warp (1: it alone, 0: the conformal warp), and ``meta``."""

    v: FloatArray
    placement: Placement
    t: float
    meta: dict[str, Any]


def triangle_distortion(
    mesh: MeshGeometry, content_xy: FloatArray, keep: NDArray[np.bool_] | None = None
) -> tuple[FloatArray, FloatArray]:
    """Angle error and log size of the mesh triangles (all, or those where ``keep``
    (T,) holds) for content positions ``content_xy`` (n, 2): the map content -> surface,
    surface in metres."""
    q = np.take(content_xy, mesh.tris.T, axis=0)  # (3, T, 2): gathered per corner
    return _distortion(q, mesh, keep)


def _distortion(
    q: FloatArray, mesh: MeshGeometry, keep: NDArray[np.bool_] | None
) -> tuple[FloatArray, FloatArray]:
    """:func:`triangle_distortion` from the triangles' content corners ``q`` (3, T, 2)."""
    u, v = q[1] - q[0], q[2] - q[0]  # content edges from corner 0
    pu, pv = mesh.remember("shape edges", lambda: _shape_edges(mesh))
    if keep is not None:
        u, v, pu, pv = (np.compress(keep, x, axis=0) for x in (u, v, pu, pv))
    # the Jacobian content -> surface: [pu pv] [u v]^-1, in closed form
    det = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    a = (pu[:, 0] * v[:, 1] - pv[:, 0] * u[:, 1]) / det
    b = (pv[:, 0] * u[:, 0] - pu[:, 0] * v[:, 0]) / det
    c = (pu[:, 1] * v[:, 1] - pv[:, 1] * u[:, 1]) / det
    d = (pv[:, 1] * u[:, 0] - pu[:, 1] * v[:, 0]) / det
    # singular values of a 2x2 matrix in closed form
    s_plus = np.hypot(a + d, c - b)
    s_minus = np.hypot(a - d, c + b)
    s1 = 0.5 * (s_plus + s_minus)
    s2 = np.maximum(0.5 * np.abs(s_plus - s_minus), 1e-300)
    return s1 / s2 - 1.0, 0.5 * np.log(np.maximum(s1 * s2, 1e-300))


def _shape_edges(mesh: MeshGeometry) -> tuple[FloatArray, FloatArray]:
    """The edges (T, 2) from corner 0 to corners 1 and 2 of each surface triangle in
    its own plane (:attr:`MeshGeometry.shapes`)."""
    p = mesh.shapes
    return np.ascontiguousarray(p[:, 1] - p[:, 0]), np.ascontiguousarray(p[:, 2] - p[:, 0])


def subject_distortion(
    mesh: MeshGeometry,
    content_xy: FloatArray,
    content_map: ContentMap,
    display: DisplaySamples | None = None,
) -> SubjectDistortion:
    """The distortion of the salient content (C >= T) shown by the mesh triangles with
    content positions ``content_xy`` (n, 2): as the display shows it, sampled, given
    ``display`` (:class:`~adaproj_edge.warp.displayed.DisplaySamples` of ``mesh``);
    else by the mesh, per triangle weighted by its salient share."""
    if display is not None:
        angle, log_size, weight = display.distortion(content_xy, content_map)
        total = float(weight.sum())
        if total <= 0:
            return SubjectDistortion(0.0, 0.0, 0.0)
        return _summary(weight, angle, log_size, total)
    return _measured(mesh, content_xy, content_map)[0]


def _measured(
    mesh: MeshGeometry, content_xy: FloatArray, content_map: ContentMap
) -> tuple[SubjectDistortion, FloatArray]:
    """:func:`subject_distortion` by the mesh, and the triangles' weights (T,) it used
    (:func:`subject_weights`)."""
    q = np.take(content_xy, mesh.tris.T, axis=0)  # (3, T, 2)
    weight = _salient_weights(mesh, content_xy, q, content_map)
    total = float(weight.sum())
    if total <= 0:
        return SubjectDistortion(0.0, 0.0, 0.0), weight
    keep = weight > 0
    angle, log_size = _distortion(q, mesh, keep)
    return _summary(weight[keep], angle, log_size, total), weight


def subject_weights(
    mesh: MeshGeometry, content_xy: FloatArray, content_map: ContentMap
) -> FloatArray:
    """Each mesh triangle's weight (T,) in the subject's measures, for content positions
    ``content_xy`` (n, 2): its projector area times its salient share."""
    q = np.take(content_xy, mesh.tris.T, axis=0)
    return _salient_weights(mesh, content_xy, q, content_map)


def _salient_weights(
    mesh: MeshGeometry, content_xy: FloatArray, q: FloatArray, content_map: ContentMap
) -> FloatArray:
    """:func:`subject_weights` given the triangles' content corners ``q`` (3, T, 2)."""
    # the salient share of a triangle: C >= T at its corners and at its centroid
    centroids = (q[0] + q[1] + q[2]) / 3.0
    salient = content_map.weights(np.concatenate([content_xy, centroids]))
    n = content_xy.shape[0]
    t = mesh.tris
    share = (salient[t[:, 0]] + salient[t[:, 1]] + salient[t[:, 2]] + salient[n:]) / 4.0
    weight: FloatArray = share * mesh.remember("pixel areas", lambda: mesh.pixel_areas)
    return weight


def _summary(
    weight: FloatArray, angle: FloatArray, log_size: FloatArray, total: float
) -> SubjectDistortion:
    """Weighted mean angle error and spread of the log size."""
    mean_log = float(weight @ log_size / total)
    spread = float(np.sqrt(weight @ (log_size - mean_log) ** 2 / total))
    return SubjectDistortion(float(weight @ angle / total), spread, total)


def no_worse(
    a: SubjectDistortion,
    b: SubjectDistortion,
    margin: float = MARGIN,
    angle_margin: float | None = None,
) -> bool:
    """Whether ``a`` is no worse than ``b`` in angle and in size, by ``margin`` (in
    angle by ``angle_margin`` when given)."""
    am = margin if angle_margin is None else angle_margin
    return bool(
        a.angle <= max(b.angle * (1 - am), FLOOR) and a.size <= max(b.size * (1 - margin), FLOOR)
    )


def _aligned(v: FloatArray, to: FloatArray) -> FloatArray:
    """``v`` (n, 2) moved by the similarity that best matches it to ``to`` (n, 2)."""
    z = v[:, 0] + 1j * v[:, 1]
    t = to[:, 0] + 1j * to[:, 1]
    zc, tc = z - z.mean(), t - t.mean()
    s = np.vdot(zc, tc) / max(float(np.vdot(zc, zc).real), 1e-300)
    out = s * zc + t.mean()
    return np.stack([out.real, out.imag], axis=1)


def conformal_measure(
    mesh: MeshGeometry,
    conformal: tuple[FloatArray, Placement],
    content_map: ContentMap,
    memo: dict[str, Any],
) -> tuple[FloatArray, SubjectDistortion, FloatArray]:
    """The conformal warp's content positions (n, 2), its measure on the subject and
    the triangles' weights (:func:`guard`'s yardstick), kept in ``memo`` (made once:
    :func:`guard`'s ``memo``, which a device may fill before its first refinement)."""
    if "conformal" not in memo:
        v, placement = conformal
        xy = placement.apply(v)
        memo["conformal"] = xy, *_measured(mesh, xy, content_map)
    known: tuple[FloatArray, SubjectDistortion, FloatArray] = memo["conformal"]
    return known


def guard(
    mesh: MeshGeometry,
    aware: tuple[FloatArray, Placement],
    conformal: tuple[FloatArray, Placement],
    content_map: ContentMap,
    up: FloatArray | tuple[float, float, float] = DEFAULT_UP,
    margin: float = MARGIN,
    surface: Surface | None = None,
    flatten: bool = False,
    provisional: bool = False,
    memo: dict[str, Any] | None = None,
) -> Choice:
    """Keep the content-aware warp, a blend, or the conformal warp: the one with most of
    the content-aware warp that is no worse than the conformal warp on the salient
    region, in angle error and in size inconsistency.

    With ``flatten``, a content-aware warp whose size inconsistency is above
    :data:`FLATTEN_ABOVE` of the conformal warp's (a large subject on a doubly curved
    surface) is first tried with its size flattened (:mod:`~adaproj_edge.warp.flatten`:
    the same angle error, the smooth part of its size spread over the subject removed);
    that candidate is kept when it has less size spread and is no worse than the
    conformal warp, and the blends start from it. Where no candidate or blend is kept,
    the conformal warp flattened the same way is, when it has less size spread by the
    margin and no more angle error.

    Parameters
    ----------
    mesh : MeshGeometry
    aware, conformal : (positions (n, 2), placement)
        The two candidates, each with the placement made for it.
    content_map : ContentMap
    up : "up" in frame P, for placing a blend.
    margin : how much better than the conformal warp a candidate must look
        (:data:`MARGIN`).
    surface : the surface the mesh was built from; given, a candidate the mesh finds
        better by less than :data:`SURE` is judged as the per-pixel display shows it
        (:mod:`~adaproj_edge.warp.displayed`); else by the mesh alone.
    provisional : a flattened candidate is first judged where the warp it flattens is
        placed (the map fixes the subject's centre with unit derivative, so the subject
        stays about where it was), and placed - then judged again where it is placed -
        only when that first judgement keeps it; its blends are judged at that same
        placement, as every blend is judged at its candidate's (the device's
        :func:`guard_grid`: a placement costs ~0.7 ms of its update, and on a bumpy
        wall neither flattened candidate was ever kept).
    memo : where what is measured of the conformal warp alone (its measure, its
        flattened candidate and what became of it) is kept for the next call with the
        same mesh, conformal warp, content map and "up" (the device's refinements of
        one content-free warp); not used when ``surface`` is given.

    Returns
    -------
    Choice; its ``meta`` holds ``choice`` ("content-aware", "flattened", "blend",
    "conformal flattened", "conformal"), ``reason``, ``t`` (the content-aware share)
    and the measures (``flattened``, ``conformal flattened``: what the flattening gave,
    when it was tried).
    """
    va, pa = aware
    vc, pc = conformal
    memo = {} if memo is None or surface is not None else memo
    xy_aware = pa.apply(va)  # (each placed once, used again below)
    m_aware, w_aware = _measured(mesh, xy_aware, content_map)
    xy_conf, m_conf, w_conf = conformal_measure(mesh, conformal, content_map, memo)
    meta: dict[str, Any] = {"aware": m_aware.as_dict(), "conformal": m_conf.as_dict()}
    if m_aware.weight <= 0 or m_conf.weight <= 0:
        meta.update(choice="content-aware", reason="no salient content shows", t=1.0)
        return Choice(va, pa, 1.0, meta)
    judge = _Judge(mesh, content_map, xy_conf, m_conf, surface, margin, meta)
    # the candidates, least size spread first: (meta name, positions, placement, measure)
    candidates = [("content-aware", va, pa, m_aware)]
    # (a conformal warp without size spread leaves nothing to flatten: a developable
    # surface)
    flatten = flatten and m_aware.size > FLATTEN_ABOVE * m_conf.size and m_conf.size > FLOOR
    if flatten:
        flat = _flattened(mesh, va, pa, content_map, up, meta, "flattened", provisional, w_aware)
        if flat is not None and flat[2].size < m_aware.size:
            candidates.insert(0, ("flattened", *flat))
    for name, v, p, m in candidates:
        if judge.no_worse(xy_aware if name == "content-aware" else p.apply(v), m, name):
            if name == "flattened" and provisional:
                placed = _placed(mesh, v, p, content_map, up, meta, name, judge)
                if placed is None:
                    continue
                p = placed
            reason = "no worse in angle and size"
            if name == "flattened":
                reason = "its size flattened over the subject, less size spread; " + reason
            meta.update(choice=name, reason=reason, t=1.0)
            return Choice(v, p, 1.0, meta)
    # blends toward the conformal warp from the candidate of least size spread
    name, va, pa, _ = candidates[0]
    base = _aligned(vc, va)
    for t in BLENDS:
        vt = t * va + (1 - t) * base
        if not unfolded(vt, mesh.tris):
            continue
        # judged where the candidate's placement puts it (the measures do not change
        # with a similarity, and what is salient barely moves): only the blend kept is
        # placed (a placement costs more than the measure); but with a crease through
        # the subject what it straddles moves with the placement, so there the blend is
        # judged where it is placed (the named cylinder on a floor, one-left subject:
        # the blend t = 0.25 as displayed 0.98x the conformal warp's angle error where
        # the content-aware warp was placed, 0.81x where it is)
        pt = place(mesh, vt, content_map.content_size, up, pa) if judge.on_crease() else None
        xy = (pa if pt is None else pt).apply(vt)
        m = subject_distortion(mesh, xy, content_map)
        if judge.no_worse(xy, m, "blend"):
            if pt is None:
                pt = place(mesh, vt, content_map.content_size, up, pa)
            meta.update(
                choice="blend",
                reason=f"the {name} warp alone is worse in angle or size",
                t=t,
                blend=m.as_dict(),
                blend_of=name,
            )
            return Choice(vt, pt, t, meta)
    if flatten:
        # the conformal warp with its size flattened: its angles are the conformal
        # warp's (up to the mesh's interpolation of the flattening map), so it is held
        # to no more angle error, and to the margin in size (judged where it is placed:
        # judged at the conformal warp's placement and placed only when kept, the
        # bumps' face subject was shown at 1.14x the conformal warp's size spread; so a
        # provisional judgement keeps it only once it is placed and judged again)
        key = "conformal flattened"
        meta[key] = {}  # (its place among the meta's keys, before what the judge adds)
        if key not in memo:
            memo[key] = _conformal_flattened(
                mesh, vc, pc, content_map, up, judge, provisional, w_conf
            )
        meta[key], kept = dict(memo[key][0]), memo[key][1]
        if kept is not None:
            meta.update(
                choice="conformal flattened",
                reason="no blend is better in both angle and size; the conformal warp "
                "with its size flattened over the subject has less size spread at no "
                "more angle error",
                t=0.0,
            )
            return Choice(kept[0], kept[1], 0.0, meta)
    meta.update(choice="conformal", reason="no blend is better in both angle and size", t=0.0)
    return Choice(vc, pc, 0.0, meta)


def _conformal_flattened(
    mesh: MeshGeometry,
    vc: FloatArray,
    pc: Placement,
    content_map: ContentMap,
    up: FloatArray | tuple[float, float, float],
    judge: _Judge,
    provisional: bool,
    weight: FloatArray,
) -> tuple[dict[str, Any], tuple[FloatArray, Placement] | None]:
    """The conformal warp ``vc`` (placed by ``pc``) with its size flattened, as
    :func:`guard` judges it last: what the flattening gave (its ``meta`` entry) and the
    positions and placement to keep, or None when it is not kept (``weight``: the
    triangles' weights (T,) at ``pc``)."""
    key = "conformal flattened"
    meta: dict[str, Any] = {}
    flat = _flattened(mesh, vc, pc, content_map, up, meta, key, provisional, weight)
    if flat is None or not judge.no_worse(flat[1].apply(flat[0]), flat[2], key, 0.0):
        return meta[key], None
    placed = flat[1]
    if provisional:
        again = _placed(mesh, flat[0], pc, content_map, up, meta, key, judge, 0.0)
        if again is None:
            return meta[key], None
        placed = again
    return meta[key], (flat[0], placed)


def _flattened(
    mesh: MeshGeometry,
    v: FloatArray,
    placement: Placement,
    content_map: ContentMap,
    up: FloatArray | tuple[float, float, float],
    meta: dict[str, Any],
    key: str,
    provisional: bool = False,
    weight: FloatArray | None = None,
) -> tuple[FloatArray, Placement, SubjectDistortion] | None:
    """Positions ``v`` (n, 2) with their size flattened over the subject, their placement
    and mesh measure; None when the flattening does not apply (``meta[key]`` says what
    it gave). ``provisional``: not placed, but measured at ``placement`` (the warp it
    flattens was placed there), which is returned (see :func:`guard`). ``weight``: the
    triangles' weights (T,) of ``v`` at ``placement``, when known."""
    if weight is None:
        weight = subject_weights(mesh, placement.apply(v), content_map)
    _, log_size = triangle_distortion(mesh, v)
    vf = flattened(mesh, v, log_size, weight)
    if vf is None:
        meta[key] = {"reason": "nothing to fit, too large a rescaling, or a fold"}
        return None
    pf = placement if provisional else place(mesh, vf, content_map.content_size, up, placement)
    m = subject_distortion(mesh, pf.apply(vf), content_map)
    meta[key] = {**m.as_dict(), "placed": False} if provisional else m.as_dict()
    return vf, pf, m


def _placed(
    mesh: MeshGeometry,
    v: FloatArray,
    at: Placement,
    content_map: ContentMap,
    up: FloatArray | tuple[float, float, float],
    meta: dict[str, Any],
    key: str,
    judge: _Judge,
    angle_margin: float | None = None,
) -> Placement | None:
    """The placement of the flattened candidate ``v`` (n, 2) that a provisional judgement
    at ``at`` kept (:func:`guard`), when it is still no worse there (None: it is not);
    ``meta[key]`` then holds its measure where it is placed."""
    p = place(mesh, v, content_map.content_size, up, at)
    m = subject_distortion(mesh, p.apply(v), content_map)
    meta[key] = m.as_dict()
    return p if judge.no_worse(p.apply(v), m, key, angle_margin) else None


class _Judge:
    """Whether a candidate is no worse than the conformal warp: by the mesh, and where
    the mesh finds it better by less than :data:`SURE` and a ``surface`` is given, as
    the per-pixel display shows it (built on first need; its figures go in ``meta``
    under ``displayed``)."""

    def __init__(
        self,
        mesh: MeshGeometry,
        content_map: ContentMap,
        conformal_xy: FloatArray,
        m_conf: SubjectDistortion,
        surface: Surface | None,
        margin: float,
        meta: dict[str, Any],
    ) -> None:
        self.mesh, self.content_map, self.surface = mesh, content_map, surface
        self.conformal_xy, self.m_conf, self.margin = conformal_xy, m_conf, margin
        self.meta = meta
        self._d_conf: SubjectDistortion | None = None
        self._display: DisplaySamples | None = None
        self._crease: bool | None = None

    def on_crease(self) -> bool:
        """Whether the display judges and a crease runs through the subject (the
        conformal warp's salient mesh triangles): the mesh measures such a triangle by
        its unfolded shape alone, blind to how the display bends on either side of the
        crease within it. A conformal warp without distortion by the mesh (a corner
        of planes) says the unfolding explains the surface: the mesh is right there."""
        if self.surface is None or max(self.m_conf.angle, self.m_conf.size) <= FLOOR:
            return False
        if self._crease is None:
            fold = creased(self.mesh)
            self._crease = bool(
                fold.any()
                and subject_weights(self.mesh, self.conformal_xy, self.content_map)[fold].any()
            )
        return self._crease

    def no_worse(
        self, xy: FloatArray, m: SubjectDistortion, name: str, angle_margin: float | None = None
    ) -> bool:
        """Whether positions ``xy`` (n, 2), of mesh measure ``m``, are no worse (in angle
        by ``angle_margin`` when given)."""
        if not no_worse(m, self.m_conf, self.margin, angle_margin):
            return False
        if self.surface is None or (no_worse(m, self.m_conf, SURE) and not self.on_crease()):
            return True
        if self._display is None:
            self._display = DisplaySamples.of(self.mesh, self.surface)
            self._d_conf = subject_distortion(
                self.mesh, self.conformal_xy, self.content_map, self._display
            )
            self.meta["displayed"] = {"conformal": self._d_conf.as_dict()}
        assert self._d_conf is not None
        d = subject_distortion(self.mesh, xy, self.content_map, self._display)
        self.meta["displayed"][name] = d.as_dict()
        return bool(d.weight > 0 and no_worse(d, self._d_conf, self.margin, angle_margin))


def guard_grid(
    image_xy: FloatArray,
    mesh: MeshGeometry,
    conformal: tuple[FloatArray, Placement],
    content_map: ContentMap,
    up: FloatArray | tuple[float, float, float] = DEFAULT_UP,
    memo: dict[str, Any] | None = None,
) -> tuple[FloatArray, dict[str, Any]]:
    """:func:`guard` for a warp given as content pixels of its grid's vertices (the
    device's coarse-to-fine result: what is displayed, not the coarse mesh, must be no
    worse than the conformal warp).

    Parameters
    ----------
    image_xy : (R, C, 2) float array
        Content pixels of the grid vertices (NaN where no surface).
    mesh : MeshGeometry
        The grid's mesh (its vertices ``mesh.verts`` index the flattened grid).
    conformal : (positions (n, 2), placement)
    content_map : ContentMap
    up : "up" in frame P.
    memo : dict, optional
        Kept by the caller for the next call with the same mesh, conformal warp,
        content map and ``up`` (:func:`guard`'s ``memo``).

    Returns
    -------
    The vertices kept, (R, C, 2), and the guard's meta.
    """
    flat = image_xy.reshape(-1, 2)
    # content pixels already: the content's rectangle is the frame (its centre warm-starts
    # the placements of a flattened warp or a blend)
    w, h = content_map.content_size
    as_is = Placement(0.0, 1.0, np.zeros(2), np.array([0.5 * w - 0.5, 0.5 * h - 0.5]))
    aware = (flat[mesh.verts], as_is)
    choice = guard(
        mesh, aware, conformal, content_map, up, flatten=True, provisional=True, memo=memo
    )
    if choice.meta["choice"] == "content-aware":
        return image_xy, choice.meta
    out = np.full_like(flat, np.nan)
    out[mesh.verts] = choice.placement.apply(choice.v)
    return out.reshape(image_xy.shape), choice.meta
