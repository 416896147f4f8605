"""Per-pose results (content-free warps and what displays them), cached so that
returning to a pose is instant.

The key combines the device orientation (from the IMU, in ``orientation_bin_rad``
bins) with a compact signature of the surface (the median depth of a 3x3 split of
the lattice, in ``depth_bin_m`` bins). A key match is only a candidate: before reuse
the cached entry's surface is compared with the current one node by node, so two
different scenes that share a key never swap warps. The runtime judges the difference
against what the depth sensor's noise can make of one surface
(:func:`surfaces_agree`: two estimates of a wall differ by the noise, one of a wall
moved 3 cm or with a box in front of it by far more); :func:`surfaces_match` is the
plain relative check. Depths that agree within the noise still let the surface turn in
frame P by a degree or two (the device turned in front of a wall turned away from it):
a warp made for it and shown now tips the content by as much, so the caller also
compares the planes fitted to both (:func:`surface_turn`). The cache holds any entry with a
``depth`` lattice and a ``frames`` count (:class:`Posed`). At most ``size`` entries
are kept (least recently used go first).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from typing import Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import Float32Array, FloatArray
from adaproj_edge.geometry.depth.sensor import SensorModel

Key = tuple[int, ...]


class Posed(Protocol):
    """What the cache needs of an entry: the lattice depth (R, C) of the surface it was
    made for (NaN where unknown) and how many depth frames were averaged into it."""

    @property
    def depth(self) -> FloatArray:
        """The lattice depth (R, C)."""

    @property
    def frames(self) -> int:
        """Depth frames averaged."""


E = TypeVar("E", bound=Posed)


def surfaces_match(now: FloatArray, then: FloatArray, max_rel: float, min_overlap: float) -> bool:
    """Whether two lattice depths (R, C) are the same surface.

    Valid nodes must agree (at least ``min_overlap`` of the larger valid set known in
    both) and their median relative depth change be at most ``max_rel``. Lattices of
    different shapes (walls snapped on one, not the other) never match. A fine lattice
    is compared at about 21x21 of its nodes.
    """
    if now.shape != then.shape:
        return False
    k = max(1, (min(now.shape) - 1) // 20)
    now, then = now[::k, ::k], then[::k, ::k]
    a, b = np.isfinite(now), np.isfinite(then)
    both = a & b
    if both.sum() < min_overlap * max(int(a.sum()), int(b.sum()), 1):
        return False
    rel = np.abs(now[both] - then[both]) / then[both]
    return bool(np.median(rel) <= max_rel)


def surfaces_agree(
    now: FloatArray,
    then: FloatArray,
    frames: tuple[int, int],
    sensor: SensorModel,
    mean_sigmas: float = 3.0,
    rms_sigmas: float = 1.0,
    min_overlap: float = 0.97,
    sway_m: float = 0.01,
) -> bool:
    """Whether two lattice depths (R, C) are estimates of the same surface, judged
    against the depth sensor's noise.

    Each node's difference is taken in units of what one depth pixel's noise makes of
    it (``sensor.sigma_m`` at the node's depth, growing with ``z^2``), averaged over the
    ``frames`` (now, then) each estimate holds: ``sigma sqrt(1/f_now + 1/f_then)``. A
    node is made from many pixels, so its own error is well under that (on the
    committed sessions the same pose's estimates differ by 0.1-0.6 of it RMS); one
    pixel's sigma per node also covers the errors that neighbouring nodes share. Two
    estimates agree when

    - the RMS of the scaled differences about their mean is at most ``rms_sigmas``
      (what no noise makes: an object placed in front of part of the surface, a part
      of it moved, the surface bent), and
    - their mean, a shift of the whole surface along the rays, is at most ``sway_m``
      (the hand's sway between two visits of a pose: 2-7 mm on a simulated 12-s
      session before a corner) plus ``mean_sigmas`` of the mean's own sigma over the
      ``N`` nodes compared (``sigma / sqrt(N)``): a wall moved 3 cm exceeds it
      between single frames of an OAK-D up to 3.5 m with 100 nodes compared, 4.5 m
      with 200 and 5 m with 441 (a Kinect-class sensor's a little further; frames
      averaged further still).

    Nodes known in both must be at least ``min_overlap`` of the larger valid set (the
    holes a sensor leaves come and go with its noise: a hole at the frame's border is
    filled in one estimate and not the next, up to 5 % of a lattice; a warp served
    across such a hole is replaced by the next fresh solve, a re-placement the hand
    sees). Lattices of different
    shapes never agree; a fine lattice is compared at about 21x21 of its nodes (as
    :func:`surfaces_match`). The lattice's depth in frame P stands for the sensor's
    (the two centres are centimetres apart). A surface turned in frame P is told by
    :func:`surface_turn`.
    """
    if now.shape != then.shape:
        return False
    k = max(1, (min(now.shape) - 1) // 20)
    now, then = now[::k, ::k], then[::k, ::k]
    a, b = np.isfinite(now) & (now > 0), np.isfinite(then) & (then > 0)
    both = a & b
    n = int(both.sum())
    if n == 0 or n < min_overlap * max(int(a.sum()), int(b.sum())):
        return False
    f_now, f_then = (max(1, f) for f in frames)
    sigma = np.maximum(sensor.sigma_m(then[both]) * math.sqrt(1.0 / f_now + 1.0 / f_then), 1e-9)
    d = now[both] - then[both]
    shift = float(np.mean(d))
    spread = math.sqrt(float(np.mean(((d - shift) / sigma) ** 2)))
    shift_sigma = math.sqrt(float(np.mean(sigma * sigma)) / n)
    return spread <= rms_sigmas and abs(shift) <= sway_m + mean_sigmas * shift_sigma


MIN_FIT_NODES = 12  # nodes known in both for :func:`surface_turn` to tell


def surface_turn(points: FloatArray | Float32Array, then: FloatArray) -> float:
    """The angle (radians) between the planes fitted to two estimates of a surface on
    the same lattice: ``points`` (R, C, 3), the current one in frame P, and ``then``
    (R, C), an earlier lattice depth along the same rays (NaN where unknown); inf when
    they share too few nodes to tell, or only nodes on a line.

    A plane ``n . X = 1`` has inverse depth linear in the normalised image
    coordinates (``n . (x/z, y/z, 1) = 1/z``), so each fit is one small least-squares
    solve, and the angle between the two ``n`` is the turn of the surface in frame P:
    a turn of the device, whatever the surface's distance (a move along its normal only
    scales ``n``). A fine lattice is fitted at about 21x21 of its nodes.
    """
    if points.shape[:2] != then.shape:
        return math.inf
    k = max(1, (min(then.shape) - 1) // 20)
    p = points[::k, ::k].reshape(-1, 3).astype(np.float64)
    z_then = then[::k, ::k].reshape(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rays = p / p[:, 2:3]
    both = np.isfinite(rays).all(axis=1) & (p[:, 2] > 0) & np.isfinite(z_then) & (z_then > 0)
    if both.sum() < MIN_FIT_NODES:
        return math.inf
    A = rays[both]
    inv = np.stack([1.0 / p[both, 2], 1.0 / z_then[both]], axis=1)
    n, _, rank, _ = np.linalg.lstsq(A, inv, rcond=None)  # (3, 2): both fits at once
    if rank < 3:  # the nodes on one line: no plane to tell
        return math.inf
    a, b = n[:, 0], n[:, 1]
    cos = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-300)
    return math.acos(min(1.0, max(-1.0, cos)))


def common_nodes(
    a: NDArray[np.float64], b: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Two lattices over the same frame brought to their common nodes: the finer one
    subsampled when its spacing divides the coarser one's (a surface whose walls were
    snapped is 8x finer than one whose were not); None when they share no nodes."""
    if a.shape == b.shape:
        return a, b
    fine, coarse = (a, b) if a.size > b.size else (b, a)
    k = [(f - 1) // max(c - 1, 1) for f, c in zip(fine.shape, coarse.shape, strict=True)]
    if k[0] < 1 or k[0] != k[1] or fine[:: k[0], :: k[1]].shape != coarse.shape:
        return None
    sub = fine[:: k[0], :: k[1]]
    return (sub, coarse) if a.size > b.size else (coarse, sub)


def surface_signature(depth: FloatArray, depth_bin_m: float) -> Key:
    """Median depth of each cell of a 3x3 split of the lattice, binned (-1: empty)."""
    rows, cols = depth.shape
    out = []
    for i in range(3):
        for j in range(3):
            block = depth[i * rows // 3 : (i + 1) * rows // 3, j * cols // 3 : (j + 1) * cols // 3]
            good = block[np.isfinite(block)]
            out.append(int(np.floor(np.median(good) / depth_bin_m)) if good.size else -1)
    return tuple(out)


def pose_key(
    orientation: FloatArray,
    depth: FloatArray,
    orientation_bin_rad: float,
    depth_bin_m: float,
    up: FloatArray | None = None,
    up_bin: float = 0.01,
) -> Key:
    """The cache key of an orientation (rotation vector, 3), a lattice depth and, when
    given, the warp's "up" (unit vector, 3; binned per component by ``up_bin``)."""
    o = tuple(int(np.floor(x / orientation_bin_rad)) for x in orientation)
    u = () if up is None else tuple(int(np.floor(x / up_bin)) for x in up)
    return o + surface_signature(depth, depth_bin_m) + u


def _relative(max_rel: float, min_overlap: float) -> Callable[[FloatArray, Posed], bool]:
    """The plain check of :meth:`PoseCache.get` (:func:`surfaces_match`)."""
    return lambda depth, e: surfaces_match(depth, e.depth, max_rel, min_overlap)


class PoseCache(Generic[E]):
    """Bounded LRU of entries by :func:`pose_key`."""

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._items: OrderedDict[Key, E] = OrderedDict()
        self.hits = 0
        self.misses = 0
        self.rejected = 0
        self.found_by_surface = 0

    def __len__(self) -> int:
        return len(self._items)

    def get(
        self,
        key: Key,
        depth: FloatArray,
        max_rel: float = 0.01,
        min_overlap: float = 0.97,
        min_frames: int = 0,
        accept: Callable[[E], bool] | None = None,
        match: Callable[[FloatArray, E], bool] | None = None,
    ) -> E | None:
        """The entry for ``key`` if it fits the current ``depth``, else any entry that
        does (most recent first; it is filed under ``key`` from then on); counts the
        outcome. ``match(depth, entry)`` judges the fit (:func:`surfaces_agree` against
        the sensor's noise, say); without it, :func:`surfaces_match` within ``max_rel``
        and ``min_overlap``.

        The key is where to look first: a pose whose orientation or depth signature sits
        near a bin edge gets another key from one estimate to the next, and is still
        found by its surface (with the few entries kept, checking them all costs well
        under a millisecond). Entries made from fewer than ``min_frames`` averaged
        depth frames, or that ``accept`` refuses (made for another "up"), are passed
        over but kept."""
        ok = accept or (lambda e: True)
        same = match or _relative(max_rel, min_overlap)
        item = self._items.get(key)
        if item is not None and item.frames >= min_frames and ok(item):
            if same(depth, item):
                self._items.move_to_end(key)
                self.hits += 1
                return item
            self.rejected += 1
            del self._items[key]
        found = self._find(depth, same, min_frames, ok)
        if found is not None:
            other, cand = found
            del self._items[other]
            self._items[key] = cand
            self.hits += 1
            self.found_by_surface += 1
            return cand
        self.misses += 1
        return None

    def nearest(
        self,
        depth: FloatArray,
        max_rel: float = 0.01,
        min_overlap: float = 0.97,
        min_frames: int = 0,
        accept: Callable[[E], bool] | None = None,
        match: Callable[[FloatArray, E], bool] | None = None,
    ) -> E | None:
        """The most recent entry that fits ``depth`` (and ``accept``; ``match`` as in
        :meth:`get`), whatever its key; neither counted nor moved (what a new entry of
        the same surface is made from)."""
        same = match or _relative(max_rel, min_overlap)
        found = self._find(depth, same, min_frames, accept or (lambda e: True))
        return None if found is None else found[1]

    def _find(
        self,
        depth: FloatArray,
        same: Callable[[FloatArray, E], bool],
        min_frames: int,
        ok: Callable[[E], bool],
    ) -> tuple[Key, E] | None:
        """The most recent entry (and its key) made from at least ``min_frames`` frames
        that ``ok`` accepts and whose surface ``same`` finds to fit ``depth``."""
        for key in reversed(list(self._items)):
            item = self._items[key]
            if item.frames >= min_frames and ok(item) and same(depth, item):
                return key, item
        return None

    def put(self, key: Key, item: E) -> None:
        """File ``item`` under ``key`` (the least recently used entry goes beyond
        ``size``; a cache of size 0 keeps nothing)."""
        if self.size <= 0:
            return
        self._items[key] = item
        self._items.move_to_end(key)
        while len(self._items) > self.size:
            self._items.popitem(last=False)

    def clear(self) -> None:
        """Drop every entry (the hit and miss counts stay)."""
        self._items.clear()
