"""The relative irradiance at any projector pixel of an estimated surface.

The device's surface is a lattice: a node per warp-grid vertex, made finer where its
walls were snapped onto planes (:func:`~adaproj_edge.geometry.planes.snap_planes`).
Between its nodes a lattice is bilinear, so the normals of points interpolated there
are its cells' facets: on a curved surface they turn at every cell's edge, each node's
depth noise tilts the cells around it, and a crease inside a cell is spread over it
(the brightness gain made from them prints all three on the picture). So the light at
a pixel (``V(r) cos(incidence) / d^2``, :mod:`adaproj_edge.geometry.irradiance`) is
taken here from what the estimate knows better than its cells:

- **on a snapped plane** it is exact: the pixel's ray ``r`` meets the plane
  ``n . X = c`` at ``X``, where ``cos(incidence) / |X|^2 = |c| / |X|^3``. A pixel is on
  the planes when every known corner of its lattice cell lies on one of those the
  surface's ``meta`` lists (:func:`~adaproj_edge.geometry.planes.plane_equations`).
  Of two planes with nodes near the pixel that meet in a crease, it takes the nearer
  inside a corner and the farther outside one (which, their nodes say: each lies in
  front of the other plane inside a corner, behind it outside one), so the light jumps
  where the planes meet, not where the snapped lattice's cells put the crease;
- **elsewhere** the light of the lattice's own nodes (their normals from their
  neighbours, each beside a crease from its own side), blurred over ``SMOOTH_DEG`` and
  interpolated bilinearly in log: smooth light stays smooth, and the nodes' depth noise
  is averaged out rather than printed.

On a lattice at least as fine as the pixels asked for, the points there are as good
as the nodes: the light is taken from the normals of the points themselves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.depth.lattice import lattice_uv
from adaproj_edge.geometry.irradiance import Vignetting, relative_irradiance
from adaproj_edge.geometry.planes import on_planes, plane_equations
from adaproj_edge.geometry.surface import Surface

SMOOTH_DEG = 2.0
"""The lattice nodes' light is blurred over this many degrees of the projector's view
(a Gaussian's sigma): about one warp-grid cell at 1280x800 (the nodes' depth noise
tilts their normals by a few per cent of light, uncorrelated from node to node)."""


@dataclass(frozen=True)
class PixelLight:
    """The light at a lattice of projector pixels, and how far to trust it.

    Attributes
    ----------
    light : (h, w) float array
        The relative irradiance, NaN where the surface is unknown.
    roughness : float
        :func:`roughness` of the light it was made from: the lattice nodes' own
        (before they were blurred) or, with ``smoothed`` False, the pixels'.
    smoothed : bool
        Whether the nodes' light was blurred over ``SMOOTH_DEG`` (a lattice coarser
        than the pixels).
    """

    light: FloatArray
    roughness: float
    smoothed: bool


NEAR_DEG = 2.0
"""A pixel's plane is one with nodes within this many degrees of the projector's view
(about one warp-grid cell: a snapped lattice's nodes beside a crease may have taken
the other wall's plane that far from it)."""
CREASE_AGREE = 0.9
"""Two planes meet in a crease when this share of their nodes (net) lies on the same
side of the other plane (all of them, on a fold; about half, on a step)."""


def irradiance_at(
    surface: Surface, uv: FloatArray, vignetting: Vignetting | None = None
) -> PixelLight:
    """The relative irradiance at the projector pixels ``uv`` (h, w, 2), a regular
    lattice of the frame.

    Parameters
    ----------
    surface : Surface
        The estimated surface (any lattice; its ``meta`` may list snapped planes).
    uv : (h, w, 2) float array
        Projector pixels, a regular lattice (its spacing sets whether the surface's
        lattice is finer).
    vignetting : Vignetting, optional
        The lens's falloff; None: none.

    Returns
    -------
    PixelLight
    """
    uv = np.asarray(uv, dtype=np.float64)
    lx, ly = surface.lattice_scale()
    h, w = uv.shape[:2]
    gx = float(uv[0, -1, 0] - uv[0, 0, 0]) / max(w - 1, 1)
    gy = float(uv[-1, 0, 1] - uv[0, 0, 1]) / max(h - 1, 1)
    flat, on = plane_irradiance(surface, uv, vignetting)
    if on.all():  # exact throughout
        return PixelLight(flat, 0.0, False)
    if lx <= gx and ly <= gy:
        e = relative_irradiance(surface.points_at(uv), surface.projector, uv, vignetting)
        rough, smoothed = roughness(e), False
    else:
        nodes = node_light(surface, vignetting)
        rough, smoothed = roughness(nodes), True
        e = node_irradiance(surface, uv, vignetting, nodes)
    return PixelLight(np.where(on, flat, e), rough, smoothed)


def node_light(surface: Surface, vignetting: Vignetting | None = None) -> FloatArray:
    """The relative irradiance (rows, cols) of the surface's lattice nodes (normals
    from their neighbours, crease-aware), unsmoothed."""
    p = surface.projector
    pts = surface.points.astype(np.float64)
    return relative_irradiance(pts, p, lattice_uv(p, surface.shape), vignetting)


def node_irradiance(
    surface: Surface,
    uv: FloatArray,
    vignetting: Vignetting | None = None,
    nodes: FloatArray | None = None,
) -> FloatArray:
    """The relative irradiance (...) at projector pixels ``uv`` (..., 2) interpolated
    bilinearly, in log, from the light of the surface's lattice nodes (``nodes``, when
    :func:`node_light` was made already) blurred over ``SMOOTH_DEG``; NaN where the
    pixel's nearest node is unknown (as :meth:`Surface.depth_at` has it)."""
    p = surface.projector
    if nodes is None:
        nodes = node_light(surface, vignetting)
    with np.errstate(invalid="ignore", divide="ignore"):
        log_e = np.log(nodes)
    sigma_px = math.radians(SMOOTH_DEG) * math.sqrt(float(p.K[0, 0]) * float(p.K[1, 1]))
    lx, ly = surface.lattice_scale()
    log_e = _smoothed(log_e, sigma_px / lx, sigma_px / ly)
    # the surface's own bilinear stencil, reading the log light where it reads depth
    packed = np.zeros((*surface.shape, 3), np.float32)
    packed[..., 2] = log_e
    out: FloatArray = np.exp(surface.stencil(uv).depth(packed))
    return out


def roughness(irradiance: FloatArray) -> float:
    """The median |second difference| of log ``irradiance`` (h, w) along rows and
    columns, where defined (0 when nowhere)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        le = np.log(irradiance)
    d2 = np.concatenate(
        [np.abs(np.diff(le, 2, axis=1)).ravel(), np.abs(np.diff(le, 2, axis=0)).ravel()]
    )
    d2 = d2[np.isfinite(d2)]
    return float(np.median(d2)) if d2.size else 0.0


def _smoothed(a: FloatArray, sx: float, sy: float) -> FloatArray:
    """``a`` (h, w; NaN: unknown) blurred with a Gaussian of ``sx`` by ``sy`` nodes
    over its known nodes only (normalised: an edge or a hole does not pull it down)."""
    if sx <= 0 or sy <= 0:
        return a
    known = np.isfinite(a)

    def blur(b: FloatArray) -> FloatArray:
        got = cv2.GaussianBlur(b, (0, 0), sx, sigmaY=sy, borderType=cv2.BORDER_CONSTANT)
        return np.asarray(got, dtype=np.float64)

    num = blur(np.where(known, a, 0.0))
    den = blur(known.astype(np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = np.where(known, num / den, np.nan)
    return out


def plane_irradiance(
    surface: Surface, uv: FloatArray, vignetting: Vignetting | None = None
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The exact relative irradiance (...) at projector pixels ``uv`` (..., 2) that lie
    on the surface's snapped planes, and where they do (...) bool (nowhere when its
    ``meta`` lists none).

    A pixel lies on the planes when every known corner of its lattice cell lies on one.
    Its plane is one of those with nodes within ``NEAR_DEG`` of it: of two that meet in
    a crease, the nearer inside a corner and the farther outside one (the lattice's
    nodes beside a crease may have been snapped to the other wall: its cells do not say
    where the crease runs); of two that do not (a step: a box before a wall), and among
    what is left, one its cell's corners lie on, nearest the lattice's depth there.
    """
    shape = np.shape(uv)[:-1]
    eq = plane_equations(surface.meta)
    if eq.shape[0] == 0:
        return np.full(shape, np.nan), np.zeros(shape, bool)
    p = surface.projector
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    pts = surface.points.astype(np.float64)
    node_on = on_planes(pts.reshape(-1, 3), eq)  # (nodes, k)
    known = np.isfinite(pts[..., 2]).reshape(-1)
    st = surface.stencil(uv)
    corners = (st.at - 2) // 3  # (4, N) the cell's corner nodes
    on = node_on[corners]  # (4, N, k)
    kn = known[corners]  # (4, N)
    flat = np.all(np.any(on, axis=2) | ~kn, axis=0) & np.any(kn, axis=0) & ~st.outside
    cornered = np.any(on, axis=0)  # (N, k): the planes the cell's corners lie on
    nearest = corners[0] + np.rint(st.gy - st.y0).astype(np.intp) * surface.shape[1]
    nearest += np.rint(st.gx - st.x0).astype(np.intp)
    near = _near_planes(surface, node_on)[nearest] | cornered  # (N, k)
    side = _crease_sides(pts.reshape(-1, 3), node_on, eq)  # (k, k)
    rays = p.rays(uv)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = eq[:, 3] / (rays @ eq[:, :3].T)  # (N, k) each plane's depth on the ray
    z = np.where(near & (z > 0), z, np.nan)
    beaten = np.zeros(z.shape, bool)
    for k in range(eq.shape[0]):
        for j in range(eq.shape[0]):
            if side[k, j] != 0:  # k and j meet in a crease: the wrong side loses
                with np.errstate(invalid="ignore"):
                    beaten[:, k] |= side[k, j] * (z[:, k] - z[:, j]) > 0
    free = np.isfinite(z) & ~beaten
    prefer = np.where(np.any(free & cornered, axis=1, keepdims=True), free & cornered, free)
    z_lattice = st.depth(surface.points).reshape(-1, 1)
    gap = np.where(prefer, np.abs(z - z_lattice), np.inf)
    pick = np.argmin(np.where(np.isfinite(gap), gap, np.where(prefer, 0.0, np.inf)), axis=1)
    zp = z[np.arange(z.shape[0]), pick]
    flat &= np.any(prefer, axis=1) & np.isfinite(zp) & np.isfinite(z_lattice[:, 0])
    dist = np.linalg.norm(rays * zp[:, None], axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        e = np.abs(eq[pick, 3]) / dist**3
    if vignetting is not None and not vignetting.none:
        e = e * vignetting.at(p, uv)
    flat &= np.isfinite(e) & (e > 0)
    e = np.where(flat, e, np.nan)
    return e.reshape(shape), flat.reshape(shape)


def _near_planes(surface: Surface, node_on: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """(nodes, k): the planes with a node within ``NEAR_DEG`` of each node."""
    p = surface.projector
    rows, cols = surface.shape
    r_px = math.radians(NEAR_DEG) * math.sqrt(float(p.K[0, 0]) * float(p.K[1, 1]))
    lx, ly = surface.lattice_scale()
    kernel = np.ones((2 * math.ceil(r_px / ly) + 1, 2 * math.ceil(r_px / lx) + 1), np.uint8)
    out = np.zeros(node_on.shape, bool)
    for k in range(node_on.shape[1]):
        on = node_on[:, k].reshape(rows, cols).astype(np.uint8)
        out[:, k] = np.asarray(cv2.dilate(on, kernel), bool).reshape(-1)
    return out


def _crease_sides(
    points: FloatArray, node_on: NDArray[np.bool_], eq: FloatArray
) -> NDArray[np.int8]:
    """(k, k): +1 where two planes meet in a crease seen from inside (each plane's nodes
    lie in front of the other plane: the nearer is the surface), -1 from outside (the
    farther), 0 where their nodes do not agree on it (a step, not a crease)."""
    k = eq.shape[0]
    side = np.zeros((k, k), np.int8)
    with np.errstate(invalid="ignore", divide="ignore"):
        rays = points / points[:, 2:3]
        z = eq[:, 3] / (rays @ eq[:, :3].T)  # (nodes, k)
    for a in range(k):
        for b in range(a + 1, k):
            only = (node_on[:, a] ^ node_on[:, b]) & np.isfinite(z[:, a] + z[:, b])
            own = np.where(node_on[:, a], z[:, a], z[:, b])[only]
            other = np.where(node_on[:, a], z[:, b], z[:, a])[only]
            if own.size == 0:
                continue
            vote = float(np.mean(np.sign(other - own)))
            if abs(vote) >= CREASE_AGREE:
                side[a, b] = side[b, a] = 1 if vote > 0 else -1
    return side
