"""Depth discontinuities are edges, not slopes: the lattice cut at silhouettes.

Where an object stands in front of a wall, neighbouring lattice nodes (or the nodes
either side of a small gap of unknown ones: the band one stereo camera cannot see)
differ by far more than the sensor's noise and the surface's slope explain. Such a
pair is a silhouette, not a steep surface: the lattice is cut there. A pair of
neighbours (``gap`` unknown nodes between them, 0 to :data:`MAX_GAP`) is cut when

    |s_b - s_a| > slope (gap + 1) max(|d_before|, |d_after|) + k sigma(max(s_a, s_b))

where ``d_before``, ``d_after`` are the depth changes per node just before and after
the pair along the same line, when they go the same way (a tilted wall or a floor
seen grazing explains large differences; an object's edge, where the difference
turns around, does not). Beside a hole they are measured across it, to the nearest
known node (up to :data:`MAX_GAP` unknown nodes away): at a crease with an untextured
patch beside it the pair on the hole's side is unknown and the pair on the other
side turns around with the crease, and reading the unknown pair as flat cut the
crease's own nodes (a slit down a wall corner). ``sigma`` is the sensor's depth error
there (:class:`~adaproj_edge.geometry.depth.sensor.SensorModel`): judged per pair from
its depth and the baseline, not a fixed threshold.

The lattice is coarse next to the depth image, and on a surface seen obliquely (a
corridor's wall, its depth growing fast from node to node) the slope explains a
silhouette between two nodes. The depth image does not: there the jump is sharp, or a
"curtain" a few pixels wide that a sensor's edge smoothing makes of it, and runs
within a few degrees of the ray, while the wall either side does not
(:func:`jump_pixels`). A lattice edge whose segment in the depth image crosses such
pixels, between nodes whose depths differ beyond the noise, is cut too
(:func:`cut_at_jumps`).

Before that, a node the smoothing moved by more than that noise allows gets its
measured depth back (:func:`keep_edges`): near a silhouette a fit may reach across it
and put the node between the two sides. At a cut between neighbours the farther
node is dropped (no triangle of the lattice then spans the jump); a gap at a cut is
never filled in. Of the pieces left (4-connected known nodes), the one under the
projector's aim (its optical axis) is kept, else (none there, or one under a quarter of
the largest's size) the largest; the others are dropped (no content stretched over the
"curtains" at jumps).

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.depth.workspace import Workspace

MAX_GAP = 3  # unknown nodes between a pair judged for a cut
MAX_EDGE_SAMPLES = 256  # samples along a lattice edge in the depth image, at most


def jump_pixels(
    hi: NDArray[Any],
    span: NDArray[Any],
    sensor: SensorModel,
    sigmas: float,
    ray_deg: float,
    work: Workspace,
) -> BoolArray:
    """The depth image's jump pixels, from the largest depth ``hi`` (h, w) and the
    depth span ``span`` (h, w) of each pixel's 3x3 neighbourhood of valid depths: where
    the span is more than a surface ``ray_deg`` from the ray makes it (2 pixels across,
    ``2 hi / f`` metres sideways, take ``2 hi / (f tan(ray_deg))`` along the ray) plus
    ``sigmas`` of the sensor's depth error at ``hi`` (its steps and noise on such a
    surface). A silhouette's jump, and the "curtain" a sensor's edge smoothing spreads
    it into over a few pixels, run nearly along the ray; a wall or a floor seen
    obliquely, however steep in depth, does not.

    The array returned is scratch of ``work`` (valid until its next frame)."""
    shape = hi.shape
    c = np.float32(sigmas * sensor.disparity_total_px / sensor.fb)
    noise = np.multiply(hi, c, out=work.get("jnoise", shape, np.float32))
    noise *= hi  # sigmas sigma(hi) = sigmas c hi^2
    along = np.float32(2.0 / (sensor.focal_px * np.tan(np.radians(ray_deg))))
    graze = np.multiply(hi, along, out=work.get("jgraze", shape, np.float32))
    noise += graze
    out: BoolArray = np.greater(span, noise, out=work.get("jumps", shape, np.bool_))
    return out


def cut_at_jumps(
    s: FloatArray,
    rays: FloatArray,
    calibration: Calibration,
    jumps: BoolArray,
    sensor: SensorModel,
    sigmas: float,
) -> tuple[FloatArray, BoolArray]:
    """``s`` (rows, cols) with the farther node of every lattice edge that crosses a
    jump pixel (``jumps``, the depth image's (h, w), :func:`jump_pixels`) dropped, and
    the mask of the nodes dropped.

    The lattice is coarse next to the depth image: a silhouette between two nodes on a
    wall seen obliquely, whose slope explains a large difference between them
    (:func:`cut_lattice`), is still a sharp jump in the image. An edge (4-neighbours
    known, points ``s * rays`` (rows, cols, 3) in frame P) is cut when its segment in
    the depth image passes over a jump pixel strictly between its two ends and the two
    depths differ by more than ``sigmas`` of the sensor's depth error (two nodes on the
    same side of a silhouette, beside it, are not cut apart)."""
    T = calibration.T_P_D
    R, t = T[:3, :3], T[:3, 3]
    x = (rays * s[..., None] - t) @ R  # frame D
    K = calibration.depth.K
    with np.errstate(invalid="ignore", divide="ignore"):
        uv = (x @ K.T)[..., :2] / x[..., 2:3]
    h, w = jumps.shape
    drop = np.zeros(s.shape, bool)
    for axis in (0, 1):
        a = (slice(None, -1), slice(None)) if axis == 0 else (slice(None), slice(None, -1))
        b = (slice(1, None), slice(None)) if axis == 0 else (slice(None), slice(1, None))
        sa, sb = s[a], s[b]
        with np.errstate(invalid="ignore"):
            apart = np.abs(sb - sa) > sigmas * sensor.sigma_m(np.fmax(sa, sb))
        pa, pb = uv[a][apart], uv[b][apart]
        ok = np.isfinite(pa).all(axis=1) & np.isfinite(pb).all(axis=1)
        if not ok.any():
            continue
        pa, pb = pa[ok], pb[ok]
        n = int(min(np.ceil(np.abs(pb - pa).max()) + 1, MAX_EDGE_SAMPLES))
        f = np.arange(1, n) / n  # strictly between the ends
        q = pa[:, None, :] + f[None, :, None] * (pb - pa)[:, None, :]
        u = np.rint(q[..., 0]).astype(np.int64)
        v = np.rint(q[..., 1]).astype(np.int64)
        inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        hit = np.zeros(u.shape, bool)
        hit[inside] = jumps[v[inside], u[inside]]
        crossed = np.zeros(sa.shape, bool)
        idx = np.flatnonzero(apart)[ok]
        crossed.ravel()[idx] = hit.any(axis=1)
        r, c = np.nonzero(crossed)
        far_b = sb[r, c] > sa[r, c]
        if axis == 0:
            drop[np.where(far_b, r + 1, r), c] = True
        else:
            drop[r, np.where(far_b, c + 1, c)] = True
    return np.where(drop, np.nan, s), drop


def _slopes_along_rows(s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per node of ``s`` (rows, cols), the depth change per node to the nearest known
    node before it and after it along its row, across at most :data:`MAX_GAP` unknown
    nodes (NaN where there is none): ``(s[c] - s[c - k]) / k`` and ``(s[c + k] - s[c])
    / k``. Beside a hole the neighbouring pair is unknown, but the surface's slope
    there is not: it is measured across the hole."""
    cols = s.shape[1]
    before = np.full(s.shape, np.nan)
    after = np.full(s.shape, np.nan)
    with np.errstate(invalid="ignore"):
        for k in range(1, min(MAX_GAP + 1, cols - 1) + 1):
            d = (s[:, k:] - s[:, :-k]) / k  # d[:, c] = (s[c + k] - s[c]) / k
            b, a = before[:, k:], after[:, :-k]
            np.copyto(b, d, where=np.isnan(b))
            np.copyto(a, d, where=np.isnan(a))
    return before, after


def _cuts_along_rows(
    s: FloatArray, sensor: SensorModel, sigmas: float, slope: float
) -> tuple[BoolArray, BoolArray]:
    """Cuts along each row of ``s`` (rows, cols): the nodes to drop (the far node of a
    cut between neighbours) and the unknown nodes of a cut gap (never filled)."""
    rows, cols = s.shape
    drop = np.zeros(s.shape, bool)
    gap_nodes = np.zeros(s.shape, bool)
    known = np.isfinite(s)
    slope_before, slope_after = _slopes_along_rows(s)
    empty = np.ones((rows, cols), bool)  # the nodes between a and b are all unknown
    for g in range(min(MAX_GAP, cols - 2) + 1):
        if g > 0:
            empty = empty[:, :-1] & ~known[:, g : g + cols - g]
        n = cols - g - 1  # pairs (j, j + g + 1)
        if n <= 0:
            break
        a, b = s[:, :n], s[:, g + 1 : g + 1 + n]
        ok = np.isfinite(a) & np.isfinite(b) & empty[:, :n]
        if not ok.any():
            continue
        d = b - a
        before = slope_before[:, :n]  # per node, from a back to its known neighbour
        after = slope_after[:, g + 1 : g + 1 + n]  # from b on to its known neighbour
        with np.errstate(invalid="ignore"):
            same_b = np.where(np.sign(before) == np.sign(d), np.abs(before), 0.0)
            same_a = np.where(np.sign(after) == np.sign(d), np.abs(after), 0.0)
            explained = slope * (g + 1) * np.maximum(same_b, same_a)
            limit = explained + sigmas * sensor.sigma_m(np.fmax(a, b))
            cut = ok & (np.abs(d) > limit)
        if not cut.any():
            continue
        r, c = np.nonzero(cut)
        if g == 0:
            far = np.where(a[r, c] > b[r, c], c, c + 1)
            drop[r, far] = True
        else:
            for k in range(1, g + 1):
                gap_nodes[r, c + k] = True
    return drop, gap_nodes


def keep_edges(
    smoothed: FloatArray, raw: FloatArray, sensor: SensorModel, sigmas: float
) -> FloatArray:
    """``smoothed`` (rows, cols) with the ``raw`` depth back where the two differ by more
    than ``sigmas`` of the sensor's depth error: a fit that reached across a silhouette
    (its node then lies between the two sides, a "curtain"), not noise removed."""
    with np.errstate(invalid="ignore"):
        off = np.abs(smoothed - raw) > sigmas * sensor.sigma_m(raw)
    return np.where(off, raw, smoothed)


def cut_lattice(
    s: FloatArray, sensor: SensorModel, sigmas: float, slope: float
) -> tuple[FloatArray, BoolArray]:
    """``s`` (rows, cols) with the far node of every cut between neighbours dropped
    (NaN), and the mask of nodes that must stay unknown (those dropped and the gaps at
    cuts: hole filling leaves them alone)."""
    drop_r, gap_r = _cuts_along_rows(s, sensor, sigmas, slope)
    drop_c, gap_c = _cuts_along_rows(s.T, sensor, sigmas, slope)
    drop = drop_r | drop_c.T
    blocked = drop | gap_r | gap_c.T
    return np.where(drop, np.nan, s), blocked


MIN_AIMED_SHARE = 0.25  # of the largest piece's nodes: a smaller aimed piece is passed over


def keep_aimed_piece(
    s: FloatArray, aim: tuple[int, int], min_share: float = MIN_AIMED_SHARE
) -> FloatArray:
    """``s`` (rows, cols) with only one piece of 4-connected known nodes kept: the one
    holding node ``aim`` (row, col) when it has at least ``min_share`` of the largest
    piece's nodes, else the largest (the aim on a chair's leg or a gap between objects
    would leave too little to project on)."""
    known = np.isfinite(s)
    labels, n = ndimage.label(known)
    if n <= 1:
        return s
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    keep = int(labels[aim])
    if keep == 0 or sizes[keep] < min_share * sizes.max():
        keep = int(np.argmax(sizes))
    return np.where(labels == keep, s, np.nan)


def aim_node(
    shape: tuple[int, int], principal: tuple[float, float], size: tuple[int, int]
) -> tuple[int, int]:
    """The lattice node (row, col) of a (rows, cols) lattice over a ``size`` = (width,
    height) projector frame nearest its principal point ``principal`` = (cx, cy)."""
    rows, cols = shape
    w, h = size
    col = round(principal[0] / max(w - 1, 1) * (cols - 1))
    row = round(principal[1] / max(h - 1, 1) * (rows - 1))
    return int(np.clip(row, 0, rows - 1)), int(np.clip(col, 0, cols - 1))
