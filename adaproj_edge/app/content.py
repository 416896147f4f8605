"""Content items of the runtime and their content maps.

Content comes in through one path (:func:`~adaproj_edge.content.intake.read_content`):
from the link's store, or the built-in poster. Its content map is made by a
:data:`ContentMapFn`: on the device the saliency model max the user mask
(:class:`SaliencyMaps`, which reruns the model only for a new image), in replays the
user mask alone (:func:`mask_content_map`: no model needed).

A clip's frames get their maps from a :data:`ClipMapsFn`
(:func:`clip_maps_of`): on the device the same saliency model through a
:class:`~adaproj_edge.content.temporal.TemporalContentMap` with faces tracked; in
replays the replay's :data:`ContentMapFn` (the mask alone) through one.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from adaproj_edge.arrays import Float32Array, Image
from adaproj_edge.content.builtin import poster, poster_mask
from adaproj_edge.content.cache import ContentMapper
from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD, ContentMap
from adaproj_edge.content.faces import FaceDetector
from adaproj_edge.content.facetrack import FaceTracker
from adaproj_edge.content.intake import read_content
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.content.temporal import TemporalContentMap
from adaproj_edge.link.device import Content, Settings

ContentMapFn = Callable[[str, Image, Float32Array | None, float], ContentMap]
"""(name, image, mask at the image's size or None, threshold) -> content map."""


@dataclass
class Item:
    """A content item: its image, content map (None: uniform) and settings; a clip also
    has its file (``image``, ``content_map``: its first frame's) and the user mask."""

    name: str
    image: Image
    content_map: ContentMap | None
    settings: Settings = field(default_factory=Settings)
    clip: Path | None = None
    mask: Float32Array | None = None

    @property
    def size(self) -> tuple[int, int]:
        """The content's (w, h) in pixels."""
        return int(self.image.shape[1]), int(self.image.shape[0])


def mask_content_map(
    name: str, image: Image, mask: Float32Array | None, threshold: float
) -> ContentMap:
    """A content map from the user mask alone, at the content's size (uniform without
    one)."""
    h, w = image.shape[:2]
    values = np.zeros((h, w), np.float32) if mask is None else mask
    return ContentMap(np.asarray(values, np.float32), (w, h), threshold)


class SaliencyMaps:
    """Saliency (the default ONNX model, one session, loaded at first use) max the faces
    found (:class:`~adaproj_edge.content.faces.FaceDetector`) max the user mask, per
    named item: model and detector rerun only when an item's image changes."""

    def __init__(self, model: SaliencyModel | None = None) -> None:
        self._model = model
        self._mapper: ContentMapper | None = None

    def model(self) -> SaliencyModel:
        """The one saliency model (session) of stills and clips, loaded at first use."""
        if self._model is None:
            self._model = SaliencyModel()
        return self._model

    def __call__(
        self, name: str, image: Image, mask: Float32Array | None, threshold: float
    ) -> ContentMap:
        """The content map of item ``name``."""
        if self._mapper is None:
            self._mapper = ContentMapper(self.model(), detector=FaceDetector())
        self._mapper.set_content(name, image)
        self._mapper.set_mask_values(name, mask)
        m = self._mapper.content_map(name)
        return ContentMap(m.values, m.content_size, threshold, m.faces)

    def clip_maps(self, item: Item) -> TemporalContentMap:
        """The content maps of clip ``item``'s frames: this model (shared, and warmed
        here, so that the clip's first frames do not pay the session's first runs),
        faces detected and tracked, the item's mask."""
        model = self.model()
        model.warm()
        return TemporalContentMap(
            item.size,
            model,
            mask=item.mask,
            tracker=FaceTracker(FaceDetector()),
            threshold=item.settings.threshold,
        )


ClipMapsFn = Callable[[Item], TemporalContentMap]
"""Clip item -> the content maps of its frames, in order."""


class MapFnSaliency:
    """A :data:`ContentMapFn` standing in for the saliency model on a clip's frames (no
    mask: :class:`~adaproj_edge.content.temporal.TemporalContentMap` adds the item's)."""

    def __init__(self, fn: ContentMapFn, name: str, threshold: float) -> None:
        self.fn, self.name, self.threshold = fn, name, threshold

    def predict(self, image_bgr: Image) -> Float32Array:
        """The map ``fn`` gives the frame, values in [0, 1]."""
        return np.asarray(self.fn(self.name, image_bgr, None, self.threshold).values, np.float32)


def clip_maps_of(fn: ContentMapFn) -> ClipMapsFn:
    """How the runtime maps a clip's frames when its still content maps come from ``fn``:
    :meth:`SaliencyMaps.clip_maps` for the device's, ``fn`` per frame otherwise."""
    if isinstance(fn, SaliencyMaps):
        return fn.clip_maps

    def maps(item: Item) -> TemporalContentMap:
        t = item.settings.threshold
        return TemporalContentMap(
            item.size, MapFnSaliency(fn, item.name, t), mask=item.mask, threshold=t
        )

    return maps


def load_item(content: Content, content_map_fn: ContentMapFn) -> Item:
    """The item of ``content`` (files in the store): read, checked, its content map made.

    Raises
    ------
    AdaprojError
        The image or mask cannot be used (the message says which and why).
    """
    files = read_content(content.image, content.mask)
    name = content.image.name
    cmap = content_map_fn(name, files.image, files.mask, content.settings.threshold)
    clip = content.image if files.video else None
    return Item(name, files.image, cmap, content.settings, clip, files.mask)


class Inbox:
    """Content items handed over from the link's thread, taken up by the runtime's."""

    def __init__(self) -> None:
        self._items: list[Item] = []
        self._lock = threading.Lock()

    def put(self, item: Item) -> None:
        """Queue ``item`` (any thread)."""
        with self._lock:
            self._items.append(item)

    def take(self) -> list[Item]:
        """The items queued since the last call, oldest first."""
        with self._lock:
            items, self._items = self._items, []
        return items


def builtin_item(threshold: float = DEFAULT_THRESHOLD) -> Item:
    """The built-in poster with its mask as content map (no saliency model needed)."""
    img = poster()
    return Item("poster", img, mask_content_map("poster", img, poster_mask(), threshold))
