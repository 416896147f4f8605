"""The per-pixel display map of a warp (:func:`~adaproj_edge.render.maps.map_from_warp`),
its pixel weights kept for the next warp of the same mesh.

The weights (:meth:`~adaproj_edge.render.maps.PixelWeights.build`, about a second a
frame) depend on the warp's grid, vertex depths and projector and on the surface, not
on where the vertices land in the content: every mode and subject of one surface maps
through the same ones. They are kept under a digest of all those inputs, so a warp of
another grid, depth, projector or surface (points or metadata) builds its own, and the
map is the one ``map_from_warp(warp, surface)`` gives, bit for bit (the same function
of the same arrays). A few meshes are kept, the last used (each ~60 MB).
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.maps import PixelWeights, map_from_warp
from adaproj_edge.warp.warpmap import Warp

KEPT = 4  # meshes: a surface's modes and subjects come one after another in a test file
_weights: OrderedDict[bytes, PixelWeights] = OrderedDict()


def _update(h: hashlib.blake2b, *arrays: NDArray[np.generic] | None) -> None:
    for a in arrays:
        if a is None:
            h.update(b"none")
        else:
            c = np.ascontiguousarray(a)
            h.update(f"{c.dtype}{c.shape}".encode())
            h.update(c.tobytes())


def _projector(h: hashlib.blake2b, p: Projector) -> None:
    h.update(f"{p.width}x{p.height}".encode())
    _update(h, np.asarray(p.K, dtype=np.float64))


def weights_key(warp: Warp, surface: Surface) -> bytes:
    """A digest of everything :meth:`PixelWeights.build` reads for ``warp`` on ``surface``."""
    h = hashlib.blake2b(digest_size=20)
    _update(h, warp.grid_uv, warp.depth, surface.points)
    _projector(h, warp.projector)
    _projector(h, surface.projector)
    h.update(json.dumps(surface.meta, sort_keys=True, default=repr).encode())
    return h.digest()


def shown_map(warp: Warp, surface: Surface | None) -> NDArray[np.float32]:
    """``map_from_warp(warp, surface)``, its pixel weights kept per mesh (see the module)."""
    if surface is None or warp.depth is None:
        return map_from_warp(warp, surface)
    key = weights_key(warp, surface)
    weights = _weights.pop(key, None)
    if weights is None:
        weights = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, surface)
    _weights[key] = weights
    while len(_weights) > KEPT:
        _weights.popitem(last=False)
    return map_from_warp(warp, surface, weights)
