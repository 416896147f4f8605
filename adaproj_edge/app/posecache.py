"""Content-free warps cached per pose, so that returning to a pose is instant.

The key combines the device orientation (from the IMU, in ``orientation_bin_rad``
bins) with a compact signature of the surface (the median depth of a 3x3 split of
the lattice, in ``depth_bin_m`` bins). A key match is only a candidate: before reuse
the cached warp's surface is compared with the current one node by node
(:meth:`CachedWarp.matches`), so two different scenes that share a key never swap
warps. At most ``size`` entries are kept (least recently used go first).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.render.frame import RemapMaps
from adaproj_edge.render.maps import PixelWeights
from adaproj_edge.warp.placement import Placement
from adaproj_edge.warp.warpmap import Warp

Key = tuple[int, ...]


@dataclass
class CachedWarp:
    """A content-free warp, its display maps, and what it needs for a warm start.

    ``depth`` is the surface's lattice depth (rows, cols) it was computed from, NaN
    where unknown; ``v``/``placement``/``verts`` the solver's positions for them;
    ``pixels`` the reduced-resolution pixel weights of its mesh (any warp of this mesh
    maps through them); ``maps`` the renderer's maps of the warp itself, made when it
    is first shown (a content-aware update shows its own).
    """

    warp: Warp
    depth: FloatArray
    v: FloatArray
    placement: Placement
    verts: NDArray[np.intp]
    pixels: PixelWeights
    maps: RemapMaps | None = None
    frames: int = 1  # depth frames averaged into the surface it was made from

    def matches(self, depth: FloatArray, max_rel: float, min_overlap: float) -> bool:
        """Whether the current lattice ``depth`` is the surface this warp was made for:
        valid nodes agree (``min_overlap``) and their median relative depth change is
        below ``max_rel``."""
        if depth.shape != self.depth.shape:  # e.g. walls snapped on one, not the other
            return False
        # a fine lattice (snapped walls) is compared at about 21x21 of its nodes
        k = max(1, (min(depth.shape) - 1) // 20)
        now, then = depth[::k, ::k], self.depth[::k, ::k]
        a, b = np.isfinite(now), np.isfinite(then)
        both = a & b
        if both.sum() < min_overlap * max(int(a.sum()), int(b.sum()), 1):
            return False
        rel = np.abs(now[both] - then[both]) / then[both]
        return bool(np.median(rel) <= max_rel)


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
    orientation: FloatArray, depth: FloatArray, orientation_bin_rad: float, depth_bin_m: float
) -> Key:
    """The cache key of an orientation (rotation vector, 3) and a lattice depth."""
    o = tuple(int(np.floor(x / orientation_bin_rad)) for x in orientation)
    return o + surface_signature(depth, depth_bin_m)


class PoseCache:
    """Bounded LRU of :class:`CachedWarp` by :func:`pose_key`."""

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._items: OrderedDict[Key, CachedWarp] = OrderedDict()
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
    ) -> CachedWarp | None:
        """The entry for ``key`` if it fits the current ``depth``, else any entry that
        does (most recent first; it is filed under ``key`` from then on); counts the
        outcome.

        The key is where to look first: a pose whose orientation or depth signature sits
        near a bin edge gets another key from one estimate to the next, and is still
        found by its surface (with the few entries kept, checking them all costs well
        under a millisecond). The surface alone decides the content-free warp (the
        runtime's "up" is the projector's), so a surface match is a warp match.
        Entries made from fewer than ``min_frames`` averaged depth frames are passed
        over (a noisier surface than the current one) but kept."""
        item = self._items.get(key)
        if item is not None and item.frames >= min_frames:
            if item.matches(depth, max_rel, min_overlap):
                self._items.move_to_end(key)
                self.hits += 1
                return item
            self.rejected += 1
            del self._items[key]
        for other in reversed(list(self._items)):
            cand = self._items[other]
            if cand.frames >= min_frames and cand.matches(depth, max_rel, min_overlap):
                del self._items[other]
                self._items[key] = cand
                self.hits += 1
                self.found_by_surface += 1
                return cand
        self.misses += 1
        return None

    def put(self, key: Key, item: CachedWarp) -> None:
        if self.size <= 0:
            return
        self._items[key] = item
        self._items.move_to_end(key)
        while len(self._items) > self.size:
            self._items.popitem(last=False)

    def clear(self) -> None:
        self._items.clear()
