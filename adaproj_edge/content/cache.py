"""Content maps per content item, recomputing only what changed.

Each item (a name in the content store) keeps its coarse saliency and its faces, keyed
by a digest of the image, and its coarse user mask, keyed by a digest of the mask bytes.
A new image reruns the model and the face detector (and re-fits the mask to the new
size); a new mask only decodes the mask; the max and the threshold are always redone
(they are cheap).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.contentmap import (
    DEFAULT_GRID,
    DEFAULT_THRESHOLD,
    ContentMap,
    Map,
    coarse_size,
    compose,
    resize_map,
)
from adaproj_edge.content.faces import NO_FACES, FaceDetector
from adaproj_edge.content.mask import decode_mask
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.errors import InputError, MaskError


def digest(data: bytes | NDArray[np.generic]) -> str:
    """Content digest of bytes or of an array (shape and dtype included)."""
    h = hashlib.blake2b(digest_size=16)
    if isinstance(data, bytes):
        h.update(data)
    else:
        arr = np.ascontiguousarray(data)
        h.update(f"{arr.shape}{arr.dtype}".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


@dataclass
class _Item:
    image_digest: str
    content_size: tuple[int, int]
    saliency: Map
    faces: FloatArray
    mask_digest: str | None = None
    mask_png: bytes | None = None
    mask: Map | None = None


@dataclass
class CacheStats:
    """How often each expensive step ran (for tests and logs)."""

    saliency_runs: int = 0
    face_runs: int = 0
    mask_decodes: int = 0


@dataclass
class ContentMapper:
    """Content maps for named content items, cached.

    Parameters
    ----------
    model : SaliencyModel
        The saliency model (one session, reused).
    threshold : float
        T of eq. 5.
    grid : (rows, cols)
        The warp grid the maps are sized for.
    max_items : int
        Least recently used items beyond this many are forgotten.
    detector : FaceDetector, optional
        Finds the faces; None leaves faces out (C = max(saliency, mask)).
    """

    model: SaliencyModel
    threshold: float = DEFAULT_THRESHOLD
    grid: tuple[int, int] = DEFAULT_GRID
    max_items: int = 8
    detector: FaceDetector | None = None
    stats: CacheStats = field(default_factory=CacheStats, init=False)
    _items: OrderedDict[str, _Item] = field(default_factory=OrderedDict, init=False, repr=False)

    def set_content(self, name: str, image_bgr: NDArray[np.uint8]) -> None:
        """Give item ``name`` its image; model and detector run only if it changed."""
        d = digest(image_bgr)
        item = self._items.get(name)
        if item is not None and item.image_digest == d:
            self._items.move_to_end(name)
            return
        h, w = image_bgr.shape[:2]
        size = coarse_size((w, h), self.grid)
        self.stats.saliency_runs += 1
        sal = resize_map(self.model.predict(image_bgr), size, area=False)
        faces = NO_FACES.copy()
        if self.detector is not None:
            self.stats.face_runs += 1
            faces = self.detector.detect(image_bgr)
        new = _Item(d, (w, h), sal, faces)
        if item is not None and item.mask_png is not None:
            try:
                self._fit_mask(new, item.mask_png, item.mask_digest)
            except MaskError:
                pass  # the old mask does not fit the new content: the content goes without
        self._items[name] = new
        self._items.move_to_end(name)
        while len(self._items) > self.max_items:
            self._items.popitem(last=False)

    def set_mask(self, name: str, png: bytes | None) -> None:
        """Give item ``name`` a user mask (PNG bytes), or remove it with None.

        Raises
        ------
        MaskError
            The mask is unreadable or does not fit the content; the item is unchanged
            and stays usable (with its previous mask, if any).
        InputError
            No content was set for ``name``.
        """
        item = self._item(name)
        if png is None:
            item.mask_digest, item.mask_png, item.mask = None, None, None
            return
        d = digest(png)
        if d != item.mask_digest:
            self._fit_mask(item, png, d)

    def set_mask_values(self, name: str, mask: Map | None) -> None:
        """Give item ``name`` a user mask already decoded at the content's size (h, w)
        float32 in [0, 1] (:func:`~adaproj_edge.content.mask.load_mask`), or remove
        it with None.

        Raises
        ------
        InputError
            No content was set for ``name``, or the mask is not at its size.
        """
        item = self._item(name)
        if mask is None:
            item.mask_digest, item.mask_png, item.mask = None, None, None
            return
        w, h = item.content_size
        if mask.shape != (h, w):
            raise InputError(f"mask of shape {mask.shape} does not match the content {w}x{h}")
        d = digest(mask)
        if d != item.mask_digest:
            self.stats.mask_decodes += 1
            size = coarse_size(item.content_size, self.grid)
            item.mask = resize_map(mask, size, area=True)
            item.mask_png, item.mask_digest = None, d

    def content_map(self, name: str) -> ContentMap:
        """The current content map of item ``name``."""
        item = self._item(name)
        values = compose(item.saliency, item.faces, item.mask, item.content_size)
        return ContentMap(values, item.content_size, self.threshold, item.faces)

    def forget(self, name: str) -> None:
        """Drop item ``name`` (no error if unknown)."""
        self._items.pop(name, None)

    def __contains__(self, name: object) -> bool:
        return name in self._items

    def _item(self, name: str) -> _Item:
        try:
            return self._items[name]
        except KeyError:
            raise InputError(f"no content named {name!r}") from None

    def _fit_mask(self, item: _Item, png: bytes, d: str | None) -> None:
        self.stats.mask_decodes += 1
        full = decode_mask(png, item.content_size, "mask")
        size = coarse_size(item.content_size, self.grid)
        item.mask = resize_map(full, size, area=True)
        item.mask_png, item.mask_digest = png, d
