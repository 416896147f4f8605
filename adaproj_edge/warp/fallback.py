"""Never dark: the steps a warp falls back through when the one asked for cannot be made.

The chain, best first:

``content-aware``
    The content-aware refinement (:mod:`~adaproj_edge.warp.engine`).
``content-free``
    The content-free warp E' of the surface as measured.
``repaired``
    The content-free warp with the cells where it folds left out and solved again
    (:func:`repair`): the vertices of every folded triangle are dropped with all the
    triangles around them, up to ``REPAIR_ROUNDS`` times and ``REPAIR_MAX_DROP`` of the
    mesh. One bad triangle (a flying pixel on a floor's border, say) costs a notch in
    the picture, never the whole warp.
``keystone``
    The dominant plane (:func:`keystone_surface`): a plane fitted robustly to the
    surface's points, extended over the largest piece of the lattice that lies on it
    (its holes filled); its content-free warp is a keystone homography.
``last-good``
    Nothing could be made: the caller keeps showing the last good picture (the app's
    part; the planner raises :class:`~adaproj_edge.errors.WarpError` with every step's
    reason).

Each warp says where it ended in ``meta["chain"]``: ``{"step": step, "down": [[step,
reason], ...]}``, the steps it went down from and why (:func:`chain_of`). Pure: no
clock, no logging; the app logs and counts the steps down.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.ndimage

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.mesh import MeshGeometry, WarpCache
from adaproj_edge.warp.orientation import signed_areas
from adaproj_edge.warp.warpmap import Grid, Warp

Step = Literal["content-aware", "content-free", "repaired", "keystone", "last-good"]
STEPS: tuple[Step, ...] = ("content-aware", "content-free", "repaired", "keystone", "last-good")

REPAIR_ROUNDS = 3  # solves after the first, each with the new folds' cells dropped
REPAIR_MAX_DROP = 0.25  # of the mesh's triangles: beyond that a repair is not local
PLANE_SAMPLES = 4000  # points the plane is fitted to (a sample of the lattice)
PLANE_TRIALS = 96  # RANSAC trials
PLANE_TOL_M = 0.01  # inlier distance: this plus PLANE_TOL_REL of the depth
PLANE_TOL_REL = 0.02
MIN_COS = 0.1  # the plane's rays must meet it at least this far from grazing

Down = list[tuple[str, str]]  # (step, reason): the steps gone down from, and why


def chain(step: str, down: Down | None = None) -> dict[str, Any]:
    """The ``meta["chain"]`` of a warp that ended at ``step`` after the steps ``down``."""
    return {"step": step, "down": [[s, r] for s, r in (down or [])]}


def chain_of(warp: Warp) -> tuple[str, Down]:
    """The step ``warp`` ended at and the steps it went down from, with their reasons
    (a warp without a chain - loaded from an older file, plain - is its own step)."""
    c = warp.meta.get("chain")
    if not isinstance(c, dict):
        return str(warp.meta.get("mode", "standard")), []
    return str(c.get("step")), [(str(s), str(r)) for s, r in c.get("down", [])]


@dataclass(frozen=True)
class Repaired:
    """A repaired content-free solve.

    Attributes
    ----------
    mesh : MeshGeometry
        The mesh with the folded cells left out.
    v_conformal, v : (n, 2) float arrays
        Its conformal and content-free positions (no triangle folded).
    dropped : int
        Grid triangles left out.
    """

    mesh: MeshGeometry
    v_conformal: FloatArray
    v: FloatArray
    dropped: int


@dataclass(frozen=True)
class Solved:
    """A content-free solve of the full grid's mesh, kept for a repair to start from.

    Attributes
    ----------
    mesh : MeshGeometry
        The mesh of the surface on the grid, nothing left out (not refined).
    v_conformal, v : (n, 2) float arrays
        Its conformal and content-free positions (folded, or a repair is not asked for).
    """

    mesh: MeshGeometry
    v_conformal: FloatArray
    v: FloatArray


Conformal = Callable[[MeshGeometry], FloatArray]
ContentFree = Callable[[MeshGeometry, FloatArray, float], tuple[FloatArray, FloatArray]]


def repair(
    surface: Surface,
    grid: Grid,
    cache: WarpCache | None,
    conformal: Conformal,
    content_free: ContentFree,
    lam: float,
    first: Solved | None = None,
) -> Repaired:
    """The content-free warp of ``surface`` on ``grid`` with the cells where it folds
    left out: every folded triangle's corners are dropped with all their triangles,
    the rest (its largest edge-connected piece) solved again, until nothing folds.

    ``first``: the solve of the whole mesh already made (the chain's content-free step,
    which folded); the repair starts from its folds instead of solving it again.

    Raises
    ------
    WarpError
        It still folds after ``REPAIR_ROUNDS`` repairs, the repair would leave out
        more than ``REPAIR_MAX_DROP`` of the mesh, or a solve fails.
    """
    mesh = first.mesh if first is not None else MeshGeometry.build(surface, grid, cache)
    total = mesh.tris.shape[0]
    drop = np.zeros(2 * grid.rows * grid.cols, dtype=bool)
    for k in range(REPAIR_ROUNDS + 1):
        if k == 0 and first is not None:
            v_conf, v = first.v_conformal, first.v
        else:
            v_conf = conformal(mesh)
            v, _ = content_free(mesh, v_conf, lam)
        bad = ~(signed_areas(v, mesh.tris) > 0)
        if not bad.any():
            return Repaired(mesh, v_conf, v, int(drop.sum()))
        corners = np.unique(mesh.tris[bad])
        star = np.isin(mesh.tris, corners).any(axis=1)
        drop[mesh.topology.rows[star]] = True
        if drop.sum() > REPAIR_MAX_DROP * total:
            raise WarpError(
                f"the warp folds over in {int(bad.sum())} triangles; too many to leave out"
            )
        mesh = MeshGeometry.build(surface, grid, cache, drop=drop)
    raise WarpError(f"the warp still folds over after {REPAIR_ROUNDS} repairs")


def dominant_plane(points: FloatArray) -> tuple[FloatArray, float, FloatArray]:
    """The plane most of ``points`` (N, 3) lie on: RANSAC on a fixed-seed sample (the
    same points give the same plane), refitted to its inliers.

    Returns
    -------
    normal : (3,) float array
        Unit normal, facing the origin (the projector) - ``normal . X = d`` with d < 0.
    d : float
    tolerance : (N,) float array
        Each point's inlier distance (``PLANE_TOL_M`` + ``PLANE_TOL_REL`` of its depth:
        a stereo sensor's error grows with depth).
    """
    if points.shape[0] < 3:
        raise WarpError("too few surface points to fit a plane to")
    rng = np.random.default_rng(0)
    sample = points
    if points.shape[0] > PLANE_SAMPLES:
        sample = points[rng.choice(points.shape[0], PLANE_SAMPLES, replace=False)]
    tol = PLANE_TOL_M + PLANE_TOL_REL * np.abs(sample[:, 2])
    best: tuple[int, FloatArray, float] | None = None
    for _ in range(PLANE_TRIALS):
        p0, p1, p2 = sample[rng.choice(sample.shape[0], 3, replace=False)]
        n = np.cross(p1 - p0, p2 - p0)
        norm = float(np.linalg.norm(n))
        if norm <= 1e-12:
            continue
        n = n / norm
        count = int(np.count_nonzero(np.abs(sample @ n - n @ p0) < tol))
        if best is None or count > best[0]:
            best = (count, n, float(n @ p0))
    if best is None:
        raise WarpError("the surface's points lie on a line; no plane to fit")
    _, n, d = best
    for _ in range(2):  # refit to the inliers (least squares), twice
        inl = sample[np.abs(sample @ n - d) < tol]
        if inl.shape[0] < 3:
            break
        c = inl.mean(axis=0)
        n = np.linalg.svd(inl - c, full_matrices=False)[2][2]
        d = float(n @ c)
    if d > 0:
        n, d = -n, -d
    return n, d, PLANE_TOL_M + PLANE_TOL_REL * np.abs(points[:, 2])


def keystone_surface(surface: Surface) -> Surface:
    """The dominant plane of ``surface`` (:func:`dominant_plane`) over the largest piece
    of its lattice that lies on it, holes and small notches closed: what a
    keystone-corrected projector shows, as a surface (its content-free warp is the
    keystone homography).

    Raises
    ------
    WarpError
        No plane can be fitted, or it is seen edge-on.
    """
    pts = surface.points.astype(np.float64)
    valid = surface.valid
    n, d, tol = dominant_plane(pts[valid])
    on = np.zeros(valid.shape, dtype=bool)
    on[valid] = np.abs(pts[valid] @ n - d) < tol
    labels, count = scipy.ndimage.label(on)
    if count == 0:
        raise WarpError("no piece of the surface lies on its dominant plane")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    # the piece's notches and holes closed: off-plane nodes inside it (flying pixels,
    # speckle) are the plane's as a keystone shows it
    piece = labels == int(np.argmax(sizes))
    piece = scipy.ndimage.binary_closing(piece, iterations=2, border_value=1)
    piece = scipy.ndimage.binary_fill_holes(piece)
    h, w = surface.shape
    sx, sy = surface.lattice_scale()
    uu, vv = np.meshgrid(np.arange(w) * sx, np.arange(h) * sy)
    rays = surface.projector.rays(np.stack([uu, vv], axis=-1))
    den = rays @ n
    cos = np.abs(den) / np.linalg.norm(rays, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d / den
    ok = piece & (t > 0) & (cos > MIN_COS)
    if not ok.any():
        raise WarpError("the dominant plane is seen edge-on")
    plane = np.where(ok[..., None], rays * t[..., None], np.nan).astype(np.float32)
    meta = {**surface.meta, "keystone": {"normal": n.round(6).tolist(), "d": round(d, 6)}}
    return Surface(plane, surface.projector, meta)
