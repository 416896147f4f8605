"""The content map C: pixel-wise max of saliency, faces and the user mask (paper §3.2,
extended with faces: :mod:`adaproj_edge.content.faces`).

C is kept at a coarse resolution that covers the whole content: the warp only samples it
at its grid vertices (20 × 20 cells by default), so :func:`coarse_size` gives a few
samples per cell and nothing more. The warp's weight at a vertex is ``C >= T`` (eq. 5).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.content.faces import NO_FACES, FaceDetector, face_map
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.errors import InputError

Map = NDArray[np.float32]

DEFAULT_THRESHOLD = 0.67
"""T of eq. 5, the paper's value."""

DEFAULT_GRID = (20, 20)
SAMPLES_PER_CELL = 4


def coarse_size(
    content_size: tuple[int, int],
    grid: tuple[int, int] = DEFAULT_GRID,
    samples_per_cell: int = SAMPLES_PER_CELL,
) -> tuple[int, int]:
    """(w', h') of the content map for a content of ``content_size`` (w, h).

    The long side gets ``samples_per_cell`` samples per cell of the larger grid side
    (80 for a 20 × 20 grid), the short side keeps the content's aspect; never larger
    than the content, never smaller than 2.
    """
    w, h = content_size
    long_side = max(grid) * samples_per_cell
    scale = min(1.0, long_side / max(w, h))
    return max(2, min(w, round(w * scale))), max(2, min(h, round(h * scale)))


def resize_map(values: NDArray[np.floating], size: tuple[int, int], *, area: bool) -> Map:
    """Bring a map covering the content to ``size`` (w, h); area-average or bilinear."""
    interp = cv2.INTER_AREA if area else cv2.INTER_LINEAR
    arr = np.asarray(values, dtype=np.float32)
    if arr.shape == (size[1], size[0]):
        return arr
    return np.asarray(cv2.resize(arr, size, interpolation=interp), dtype=np.float32)


@dataclass(frozen=True)
class ContentMap:
    """C over the content, coarse; what the warp weighs.

    Attributes
    ----------
    values : (h', w') float32 in [0, 1]
        Covers the whole content (the engine takes this array as ``content_map``).
    content_size : (w, h)
        Size of the content in pixels.
    threshold : float
        T of eq. 5.
    faces : (n, 4) float64
        The faces that went into ``values`` (``x, y, w, h``, content pixels); empty
        when none were found or none were looked for.
    """

    values: Map
    content_size: tuple[int, int]
    threshold: float = DEFAULT_THRESHOLD
    faces: FloatArray = field(default_factory=NO_FACES.copy)

    def sample(self, xy: NDArray[np.floating]) -> NDArray[np.float32]:
        """Bilinear C at content pixel coordinates ``xy`` (n, 2); 0 outside the content.

        Map cell centres sit at the centres of the content areas they cover (the same
        convention as the warp engine's sampler).
        """
        w, h = self.content_size
        mh, mw = self.values.shape
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        x, y = pts[:, 0], pts[:, 1]
        # (an unknown position, NaN, is outside: every comparison with it is false)
        inside = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
        # bilinear on the map, its edge values held beyond it (map_coordinates' order 1,
        # "nearest"; written out: a few hundred points a call, many calls a warp)
        ix, tx = _cell((x + 0.5) * (mw / w) - 0.5, mw)
        iy, ty = _cell((y + 0.5) * (mh / h) - 0.5, mh)
        flat = self.values.reshape(-1)
        top = iy * mw + ix
        dx, dy = int(mw > 1), mw * int(mh > 1)  # the next sample (itself on a 1-wide axis)
        v00, v01 = np.take(flat, top), np.take(flat, top + dx)
        v10, v11 = np.take(flat, top + dy), np.take(flat, top + dy + dx)
        vals = (1.0 - ty) * ((1.0 - tx) * v00 + tx * v01) + ty * ((1.0 - tx) * v10 + tx * v11)
        return np.asarray(np.where(inside, vals, 0.0), dtype=np.float32)

    def weights(self, xy: NDArray[np.floating]) -> NDArray[np.float32]:
        """w_a of eq. 5 at content pixel coordinates ``xy`` (n, 2): 1 where C >= T, else 0."""
        return (self.sample(xy) >= self.threshold).astype(np.float32)

    def salient(self) -> NDArray[np.bool_]:
        """(h', w') mask of the map cells with C >= T."""
        return np.asarray(self.values >= self.threshold)

    def full_size(self) -> Map:
        """C brought to the content size, (h, w) float32 (for display and files)."""
        return np.clip(resize_map(self.values, self.content_size, area=False), 0.0, 1.0)


def _cell(c: FloatArray, size: int) -> tuple[NDArray[np.intp], FloatArray]:
    """For map coordinates ``c`` (n,) along an axis of ``size`` samples: the first of the
    two samples to blend and the second's weight, coordinates held to ``[0, size - 1]``
    (a one-sample axis blends its sample with itself; NaN is held to 0)."""
    c = np.fmin(np.fmax(c, 0.0), size - 1.0)  # (fmax: NaN becomes 0, a valid index)
    i = np.minimum(c.astype(np.intp), max(size - 2, 0))
    t: FloatArray = c - i
    return i, t


def combine(
    content_size: tuple[int, int],
    saliency: NDArray[np.floating] | None = None,
    mask: NDArray[np.floating] | None = None,
) -> Map | None:
    """``max(saliency, mask)`` at the content size; None when neither is given (uniform).

    Both inputs must already be (h, w) float maps in [0, 1] at ``content_size`` (w, h).
    """
    w, h = content_size
    maps = [m for m in (saliency, mask) if m is not None]
    if not maps:
        return None
    for m in maps:
        if m.shape != (h, w):
            raise InputError(f"content map of shape {m.shape} does not match the content {w}x{h}")
    return combine_maps(maps)


def combine_maps(maps: list[NDArray[np.floating]]) -> Map:
    """Pixel-wise max of same-shape maps (NaN loses to a number, is 0 alone), in [0, 1]."""
    out: Map = np.asarray(maps[0], dtype=np.float32)
    for m in maps[1:]:
        out = np.fmax(out, np.asarray(m, dtype=np.float32))
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0).astype(np.float32)


def compose(
    saliency: Map,
    boxes: FloatArray,
    mask: Map | None,
    content_size: tuple[int, int],
) -> Map:
    """C = max(saliency, faces, mask) on the grid of ``saliency``.

    Parameters
    ----------
    saliency : (h', w') float32 in [0, 1]
        Saliency already at the map size.
    boxes : (n, 4) float
        Faces (``x, y, w, h``, content pixels); none leaves C exactly
        ``max(saliency, mask)``.
    mask : (h', w') float32 in [0, 1], optional
        The user mask already at the map size.
    content_size : (w, h)

    Returns
    -------
    (h', w') float32 in [0, 1]
    """
    mh, mw = saliency.shape
    maps: list[NDArray[np.floating]] = [saliency]
    faces = face_map(boxes, content_size, (mw, mh))
    if faces is not None:
        maps.append(faces)
    if mask is not None:
        maps.append(mask)
    return combine_maps(maps)


def content_map_for(
    image_bgr: NDArray[np.uint8],
    mask: NDArray[np.floating] | None = None,
    model: SaliencyModel | None = None,
    *,
    threshold: float = DEFAULT_THRESHOLD,
    grid: tuple[int, int] = DEFAULT_GRID,
    faces: bool = True,
    detector: FaceDetector | None = None,
) -> ContentMap:
    """The content map of one image: max of saliency by ``model``, faces and ``mask``.

    Parameters
    ----------
    image_bgr : (h, w, 3) or (h, w) uint8
        The content.
    mask : (h_m, w_m) float array in [0, 1], optional
        The user mask, at any resolution of the content's aspect (e.g. from
        :func:`~adaproj_edge.content.mask.load_mask`); it is area-averaged to the map size.
    model : SaliencyModel, optional
        Defaults to a new session of the default model; pass one to reuse it.
    threshold : float
        T of eq. 5.
    grid : (rows, cols)
        The warp grid the map is sized for (:func:`coarse_size`).
    faces : bool
        Look for faces (off: C = max(saliency, mask), as before faces were added).
    detector : FaceDetector, optional
        Defaults to a new detector with the shipped cascade; pass one to reuse it.

    Returns
    -------
    ContentMap
        With the faces found in ``faces`` (content pixels).
    """
    h, w = image_bgr.shape[:2]
    size = coarse_size((w, h), grid)
    model = model or SaliencyModel()
    saliency = resize_map(model.predict(image_bgr), size, area=False)
    boxes = (detector or FaceDetector()).detect(image_bgr) if faces else NO_FACES.copy()
    small_mask = None if mask is None else resize_map(mask, size, area=True)
    return ContentMap(compose(saliency, boxes, small_mask, (w, h)), (w, h), threshold, boxes)
