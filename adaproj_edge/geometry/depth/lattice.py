"""The projector-ray lattice: its nodes, their spacing on the surface, and the clean-up
of step 4-5: spikes rejected, small holes filled, a confidence per node."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.depth.settings import DepthSettings
from adaproj_edge.geometry.projector import Projector


def lattice_uv(projector: Projector, shape: tuple[int, int]) -> FloatArray:
    """Projector pixel coordinates (rows, cols, 2) of a lattice whose corners are the
    corner pixel centres (the Surface convention)."""
    rows, cols = shape
    xs = np.linspace(0.0, projector.width - 1.0, cols)
    ys = np.linspace(0.0, projector.height - 1.0, rows)
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def depth_sigma(z: FloatArray, calibration: Calibration, disparity_sigma_px: float) -> FloatArray:
    """Stereo depth noise (m) at depth ``z``: z^2 / (f B) * sigma_disparity."""
    d = calibration.depth
    return z * z / (d.focal * d.baseline_m) * disparity_sigma_px


def node_spacing_m(projector: Projector, shape: tuple[int, int], depth_m: float) -> float:
    """Distance between neighbouring lattice nodes on a surface ``depth_m`` away."""
    rows, cols = shape
    step_px = min(
        (projector.width - 1) / max(cols - 1, 1), (projector.height - 1) / max(rows - 1, 1)
    )
    return depth_m * step_px / float(projector.K[0, 0])


def reject_spikes(s: FloatArray, rel: float) -> FloatArray:
    """Drop nodes that stick out of their neighbours in every direction (rows, cols)."""
    p = np.pad(s, 1, constant_values=np.nan)
    c = p[1:-1, 1:-1]
    dev = []
    for (y0, x0), (y1, x1) in (
        ((0, 1), (2, 1)),
        ((1, 0), (1, 2)),
        ((0, 0), (2, 2)),
        ((0, 2), (2, 0)),
    ):
        a = p[y0 : y0 + c.shape[0], x0 : x0 + c.shape[1]]
        b = p[y1 : y1 + c.shape[0], x1 : x1 + c.shape[1]]
        dev.append(np.abs(c - (a + b) / 2))
    with np.errstate(invalid="ignore"):
        d = np.stack(dev)
        known = np.isfinite(d)
        spike = np.all(~known | (d > rel * c), axis=0) & (known.sum(axis=0) >= 3)
    out = s.copy()
    out[spike] = np.nan
    return out


def fill_holes(
    s: FloatArray,
    max_nodes: int,
    blocked: BoolArray | None = None,
    sensor: SensorModel | None = None,
    settings: DepthSettings | None = None,
    node_angle: float | None = None,
) -> tuple[FloatArray, BoolArray]:
    """Fill NaN regions (holes: 4-connected) of the lattice ``s`` (rows, cols).

    A hole of at most ``max_nodes`` nodes that touches neither the border nor a
    ``blocked`` node (a silhouette's, see :mod:`~adaproj_edge.geometry.depth.cuts`) gets
    a harmonic fill (each filled node the mean of its neighbours). With a ``sensor``,
    a larger one, or one at the border, not touching a ``blocked`` node, is filled
    from a smooth surface fitted to the known nodes around it when that ring is one
    surface within the sensor's error (:func:`fill_from_ring`; ``node_angle`` is the
    angle between neighbouring lattice rays, rad); a doorway, a window or an object's
    edge stays a hole.

    Returns the filled lattice and the mask of filled nodes.
    """
    hole = ~np.isfinite(s)
    labels, n = ndimage.label(hole)
    if n == 0:
        return s, np.zeros_like(hole)
    sizes = np.bincount(labels.ravel())
    border = np.unique(np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    free = np.ones(n + 1, bool)
    free[0] = False
    if blocked is not None:
        free[np.unique(labels[blocked])] = False
    small = free & (sizes <= max_nodes)
    small[border] = False
    fill = small[labels]
    out = s
    if fill.any():
        out = np.where(fill, np.nanmean(s), s)
        # Jacobi steps on the filled nodes alone: none is on the border, and their four
        # neighbours (above, below, left, right) are known or filled (a hole is a whole
        # 4-connected NaN region), so each becomes the plain mean of the four
        at = np.flatnonzero(fill)
        cols = s.shape[1]
        around = np.stack([at - cols, at + cols, at - 1, at + 1])
        flat = out.reshape(-1)
        for _ in range(4 * max_nodes + 20):
            flat[at] = flat[around].sum(axis=0) / 4
    if sensor is None:
        return out, fill
    settings = settings or DepthSettings()
    cap = settings.max_fit_hole_share * s.size
    at_border = np.zeros(n + 1, bool)
    at_border[border] = True
    boxes = ndimage.find_objects(labels)
    pad = settings.ring_nodes + settings.border_fill_nodes + 1
    rows, cols = s.shape
    pieces, apart = _cut_apart(s, blocked)
    # inside the frame up to a cap; at the border any size (filled only a few nodes deep)
    for label in np.flatnonzero(free & ~small & ((sizes <= cap) | at_border)):
        box = boxes[label - 1]
        assert box is not None
        win = (
            slice(max(box[0].start - pad, 0), min(box[0].stop + pad, rows)),
            slice(max(box[1].start - pad, 0), min(box[1].stop + pad, cols)),
        )
        region = labels[win] == label
        if apart is not None:
            ring = ndimage.binary_dilation(region, iterations=settings.ring_nodes)
            near = np.unique(pieces[win][ring])
            if apart[np.ix_(near, near)].any():
                continue  # the ring spans a cut: a fill would join what it separated
        got = fill_from_ring(s[win], region, sensor, settings, bool(at_border[label]), node_angle)
        if got is not None:
            if out is s:
                out = s.copy()
            done = np.zeros_like(fill)
            done[win] = np.isfinite(got)
            out[done] = got[np.isfinite(got)]
            fill |= done
    return out, fill


def _cut_apart(
    s: FloatArray, blocked: BoolArray | None
) -> tuple[NDArray[np.int32], BoolArray | None]:
    """The pieces of ``s`` (rows, cols) (4-connected known nodes, labelled from 1; 0
    where unknown) and which of them a cut separates, (n + 1, n + 1): pieces beside
    one run of ``blocked`` nodes (4-connected: the nodes a cut dropped, a cut gap),
    which is not one piece; None without a blocked node. A hole whose ring reaches two
    such pieces lies at the cut (where it meets a void, say): a surface fitted to that
    ring would join across it what the cut separated."""
    pieces, n = ndimage.label(np.isfinite(s))
    if blocked is None or not blocked.any() or n < 2:
        return pieces, None
    runs, m = ndimage.label(blocked)
    touch = np.zeros((m + 1, n + 1), bool)
    for a, b in (
        ((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
        ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
    ):
        touch[runs[a], pieces[b]] = True
        touch[runs[b], pieces[a]] = True
    touch[0, :] = False
    touch[:, 0] = False
    apart = (touch.T.astype(np.int32) @ touch.astype(np.int32)) > 0
    np.fill_diagonal(apart, False)
    return pieces, apart


def fill_from_ring(
    s: FloatArray,
    region: BoolArray,
    sensor: SensorModel,
    settings: DepthSettings,
    at_border: bool,
    node_angle: float | None = None,
) -> FloatArray | None:
    """Depths (rows, cols) for the hole ``region`` of ``s`` (NaN elsewhere and where
    left open) from a smooth surface fitted to its ring, or None when the ring is not
    one surface.

    The ring is the known nodes within ``ring_nodes`` of the hole. Along the lattice's
    rays (z = 1, evenly spaced) a plane's inverse depth is affine in the node's (row,
    col): that is fitted first, then (inside the frame only) a quadric, for a curved
    surface. A fit is accepted when the ring's depths lie within the sensor's error of
    it: RMS within ``ring_sigmas`` and every node within twice that of
    ``sigma(z) + step(z) + bias(z)`` (the residual of a smoothed lattice on one
    surface; a silhouette's ring is off by the jump: at 2 m a step of 0.15 m across a
    hole is refused, one of 0.1 m, which a ring on three sides takes for a slope, not).
    Nor is a fit accepted that is seen within ``90 - fill_max_incidence_deg`` degrees
    of grazing at a node it fills (``node_angle`` given): a small error of the fit is
    a large one along the ray there, and such a hole is often the band beside a
    silhouette. A hole inside the frame is filled whole; one at the frame's border
    only within ``border_fill_nodes`` of its ring (the fit is not trusted far into an
    unknown void), and not at all where the surface beside it curves on to grazing
    there (a column's limb, where the surface ends: :func:`_turns_grazing`).
    """
    known = np.isfinite(s)
    ring = ndimage.binary_dilation(region, iterations=settings.ring_nodes) & known
    if not (ring & ndimage.binary_dilation(region)).any():
        return None
    rr, cc = np.nonzero(ring)
    if rr.size < 8:
        return None
    z = s[ring]
    inv = 1.0 / z
    tol = sensor.sigma_m(z) + sensor.step_m(z) + sensor.bias_m(z)
    hr, hc = np.nonzero(region)
    scale = float(max(s.shape))
    degrees = (1,) if at_border else (1, 2)
    for degree in degrees:
        a = _design(rr / scale, cc / scale, degree)
        if a.shape[0] < 2 * a.shape[1]:
            break  # too few nodes
        coef, _, rank, _ = np.linalg.lstsq(a, inv, rcond=None)
        if rank < a.shape[1]:
            break  # the ring along one line: no surface to speak of
        with np.errstate(divide="ignore", invalid="ignore"):
            off = np.abs(z - 1.0 / (a @ coef)) / tol
        if not np.all(np.isfinite(off)):
            continue
        if np.sqrt(np.mean(off**2)) > settings.ring_sigmas or off.max() > 2 * settings.ring_sigmas:
            continue
        with np.errstate(divide="ignore"):
            zh = 1.0 / (_design(hr / scale, hc / scale, degree) @ coef)
        lo, hi = z.min(), z.max()
        span = hi - lo
        if not np.all(np.isfinite(zh)) or np.any(zh <= 0):
            continue
        if not at_border and (zh.min() < lo - span or zh.max() > hi + span):
            continue  # a fit that bulges between its ring's nodes
        if node_angle is not None:
            # inverse depth's gradient per node over inverse depth, per ray angle: about
            # the tangent of the angle of incidence
            gr, gc = _gradient(hr / scale, hc / scale, degree, coef)
            tan = np.hypot(gr, gc) / scale * zh / node_angle
            if tan.max() > np.tan(np.radians(settings.fill_max_incidence_deg)):
                continue
        out = np.full(s.shape, np.nan)
        out[hr, hc] = zh
        if at_border:
            far = ndimage.distance_transform_cdt(~known, metric="chessboard")
            out[far > settings.border_fill_nodes] = np.nan
            if node_angle is not None and _turns_grazing(
                s, region, np.isfinite(out), node_angle, settings
            ):
                return None
            z_ok = (settings.min_depth_m <= out) & (out <= settings.max_depth_m)
            out[~z_ok] = np.nan
        return out
    return None


def _turns_grazing(
    s: FloatArray,
    region: BoolArray,
    fill: BoolArray,
    node_angle: float,
    settings: DepthSettings,
) -> bool:
    """Whether the surface beside the border hole ``region`` of ``s`` (rows, cols)
    curves on to grazing incidence (beyond ``fill_max_incidence_deg``) at a node a
    plane fitted to its ring would fill (``fill``): the limb of a column or a cone,
    where the surface ends. A plane takes the ring's mean slope and carries the surface
    on past its silhouette; a quadric fitted to the known nodes a few more nodes deep
    (``ring_nodes`` + 2: enough to show a turn across a straight limb) shows it."""
    near = ndimage.binary_dilation(region, iterations=settings.ring_nodes + 2)
    rr, cc = np.nonzero(near & np.isfinite(s))
    scale = float(max(s.shape))
    a = _design(rr / scale, cc / scale, 2)
    if a.shape[0] < 2 * a.shape[1]:
        return False
    got, _, rank, _ = np.linalg.lstsq(a, 1.0 / s[rr, cc], rcond=None)
    if rank < a.shape[1]:
        return False
    coef: FloatArray = np.asarray(got, dtype=np.float64)
    fr, fc = np.nonzero(fill)
    r, c = fr / scale, fc / scale
    with np.errstate(divide="ignore", invalid="ignore"):
        zq = 1.0 / (_design(r, c, 2) @ coef)
        gr, gc = _gradient(r, c, 2, coef)
        tan = np.hypot(gr, gc) / scale * zq / node_angle
    limit = np.tan(np.radians(settings.fill_max_incidence_deg))
    return bool(np.any(~np.isfinite(zq) | (zq <= 0) | (tan > limit)))


def _gradient(
    r: FloatArray, c: FloatArray, degree: int, coef: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The derivatives (d/dr, d/dc) of the polynomial ``coef`` of :func:`_design`."""
    if degree == 1:
        return np.full_like(r, coef[1]), np.full_like(c, coef[2])
    return coef[1] + 2 * coef[3] * r + coef[4] * c, coef[2] + coef[4] * r + 2 * coef[5] * c


def _design(r: FloatArray, c: FloatArray, degree: int) -> FloatArray:
    """Columns of a polynomial of ``degree`` (1 or 2) in (r, c)."""
    one = np.ones_like(r)
    if degree == 1:
        return np.stack([one, r, c], axis=1)
    return np.stack([one, r, c, r * r, r * c, c * c], axis=1)


def node_confidence(
    points: FloatArray,
    support: FloatArray,
    filled: BoolArray,
    calibration: Calibration,
    settings: DepthSettings,
) -> NDArray[np.float32]:
    """Confidence (rows, cols) in [0, 1] of lattice ``points`` (rows, cols, 3)."""
    z = points[..., 2]
    valid = np.isfinite(z)
    c_support = np.clip(support / 0.8, 0.0, 1.0)
    sigma = depth_sigma(np.where(valid, z, 0.0), calibration, settings.disparity_sigma_px)
    c_noise = np.exp(-((sigma / settings.sigma_ref_m) ** 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        dx = np.gradient(points, axis=1)
        dy = np.gradient(points, axis=0)
        n = np.cross(dx, dy)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        ray = points / np.linalg.norm(points, axis=-1, keepdims=True)
        cos = np.abs(np.sum(n * ray, axis=-1))
    c_angle = np.clip((np.nan_to_num(cos, nan=0.5) - 0.1) / 0.3, 0.0, 1.0)
    c = np.where(filled, 0.5, c_support) * c_noise * c_angle
    return np.where(valid, c, 0.0).astype(np.float32)


def supersampling(
    projector: Projector, shape: tuple[int, int], zs: FloatArray, settings: DepthSettings
) -> int:
    """How many times finer than ``shape`` to sample, so that nodes are at most
    ``smooth_m / 2`` apart on the surface (1 for fine lattices, at most 4)."""
    good = zs[np.isfinite(zs)]
    return supersampling_at(
        projector, shape, float(np.median(good)) if good.size else None, settings
    )


def supersampling_at(
    projector: Projector, shape: tuple[int, int], z_median: float | None, settings: DepthSettings
) -> int:
    """:func:`supersampling` for a surface at median depth ``z_median`` (None: 1.5 m)."""
    z = 1.5 if z_median is None else z_median
    k = np.ceil(node_spacing_m(projector, shape, z) / (settings.smooth_m / 2))
    return int(np.clip(k, 1, settings.max_supersample))


def dense_shape(projector: Projector, step: int = 4) -> tuple[int, int]:
    """Lattice shape with one node every ``step`` projector pixels."""
    return (projector.height - 1) // step + 1, (projector.width - 1) // step + 1
