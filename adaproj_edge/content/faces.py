"""Faces in the content: detected with a shipped cascade, drawn as soft ellipses.

GBVS is bottom-up and knows nothing of faces, yet they are what people look at first.
:class:`FaceDetector` finds frontal faces with OpenCV's LBP cascade
(``models/lbpcascade_frontalface.xml``, card beside it) on a copy of the image whose long
side is ``long_side`` pixels; :func:`face_map` turns the boxes into a map in [0, 1] that
is 1 over each face (an ellipse a little taller than the box: forehead and chin) and
falls smoothly to 0 around it. The content map takes the pixel-wise max of that, the
saliency and the user mask.

Everything here is pure: arrays in, arrays out. The cascade object is read-only after
loading; OpenCV's own thread count is the caller's policy (``cv2.setNumThreads``).
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from adaproj_edge.arrays import Float32Array, FloatArray, Image
from adaproj_edge.errors import ModelError
from adaproj_edge.resources import face_cascade

DEFAULT_LONG_SIDE = 480
"""Long side (px) of the image the cascade scans: faces from 24 px there (5 % of it)."""

NO_FACES: FloatArray = np.zeros((0, 4), np.float64)
"""An empty (0, 4) box array."""

ScaleBand = tuple[tuple[int, int], tuple[int, int]]
"""The smallest and largest window ``(w, h)`` of a band of the cascade's scales."""

FACE_SCALE = (0.62, 0.8)
"""Semi-axes of a face's ellipse in box widths and heights (the box is eyes-to-mouth)."""
FACE_DROP = 0.1
"""The ellipse's centre sits this many box heights below the box's centre (chin)."""
SOFTNESS = 0.5
"""The map falls from 1 to 0 between elliptic radius 1 and 1 + SOFTNESS."""
EQUALISE = (2.0, 8)
"""Contrast-limited local equalisation of the scan image (OpenCV CLAHE): clip limit and
tiles per side. A global histogram equalisation stretches a low-contrast picture's
texture everywhere: on skimage's cat (chelsea) the cheek's fur became a 142-px "face"
whose ellipse reached the image's left edge; locally, with the stretch limited, the
shipped test scenes give 93 of 101 faces found against 87 (tools/bench_faces.py)."""


class FaceDetector:
    """Frontal faces by a boosted cascade (OpenCV ``CascadeClassifier``).

    Parameters
    ----------
    path : path-like
        The cascade file (OpenCV XML); default the shipped LBP frontal-face cascade.
    long_side : int
        The image is scanned at this long side (px), never enlarged.
    scale_factor : float
        Step between scanned face sizes.
    min_neighbours : int
        Overlapping raw detections needed to keep one (higher: fewer false faces).
    min_size : int
        Smallest face scanned, in pixels of the scanned image (the cascade is 24 px).

    Raises
    ------
    ModelError
        The file is missing or is not a cascade OpenCV can load.
    """

    def __init__(
        self,
        path: str | os.PathLike[str] | None = None,
        *,
        long_side: int = DEFAULT_LONG_SIDE,
        scale_factor: float = 1.1,
        min_neighbours: int = 4,
        min_size: int = 24,
    ) -> None:
        self.path = Path(path) if path is not None else face_cascade()
        if not self.path.is_file():
            raise ModelError(f"face cascade not found: {self.path}")
        try:
            self._cascade = cv2.CascadeClassifier(str(self.path))
        except Exception as e:  # OpenCV raises cv2.error or SystemError on a bad file
            raise ModelError(f"{self.path} is not a cascade OpenCV can load: {e}") from None
        if self._cascade.empty():
            raise ModelError(f"{self.path} is not a cascade OpenCV can load")
        if long_side < min_size or scale_factor <= 1.0 or min_neighbours < 0:
            raise ValueError("need long_side >= min_size, scale_factor > 1, min_neighbours >= 0")
        self.long_side = long_side
        self.scale_factor = scale_factor
        self.min_neighbours = min_neighbours
        self.min_size = min_size

    def scan_image(self, image_bgr: Image) -> tuple[Image, float]:
        """The grey, locally equalised copy the cascade scans (:data:`EQUALISE`), and its
        scale (scanned / content).

        Parameters
        ----------
        image_bgr : (h, w, 3) or (h, w) uint8

        Returns
        -------
        gray : (h_s, w_s) uint8
        scale : float
            Scanned pixels per content pixel (<= 1).
        """
        gray = image_bgr if image_bgr.ndim == 2 else cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
        h, w = gray.shape[:2]
        scale = min(1.0, self.long_side / max(w, h))
        if scale < 1.0:
            k = int(1.0 / scale)
            if k >= 2:  # OpenCV's integer-factor area average is ~10x faster than a general one
                gray = cv2.resize(gray, None, fx=1.0 / k, fy=1.0 / k, interpolation=cv2.INTER_AREA)
            size = (max(1, round(w * scale)), max(1, round(h * scale)))
            gray = cv2.resize(gray, size, interpolation=cv2.INTER_AREA)
        clip, tiles = EQUALISE
        equalised = cv2.createCLAHE(clipLimit=clip, tileGridSize=(tiles, tiles)).apply(gray)
        return np.asarray(equalised, np.uint8), scale

    def detect_scanned(self, gray: Image) -> FloatArray:
        """Face boxes in a prepared scan image (:meth:`scan_image`), its pixels.

        Parameters
        ----------
        gray : (h_s, w_s) uint8

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of each face, largest first.
        """
        if min(gray.shape[:2]) < self.min_size:
            return NO_FACES.copy()
        found = self._cascade.detectMultiScale(
            gray,
            scaleFactor=self.scale_factor,
            minNeighbors=self.min_neighbours,
            minSize=(self.min_size, self.min_size),
        )
        boxes = np.asarray(found, np.float64).reshape(-1, 4)
        return boxes[np.argsort(-boxes[:, 2] * boxes[:, 3], kind="stable")]

    def scale_bands(self, scan_shape: tuple[int, ...], n: int) -> list[ScaleBand]:
        """The scales :meth:`detect_scanned` scans, split into at most ``n`` bands of about
        equal work, smallest faces first.

        The cascade scans window sizes ``cvRound(w0 * s**k)`` (``s`` the scale factor,
        ``w0`` the cascade's window) from :attr:`min_size` up to the image's size; a
        scale's work is the number of windows it tries (every other pixel below scale 2,
        every pixel above, as OpenCV steps). Scanning the bands one at a time
        (:meth:`detect_band`) and grouping their candidates together (:meth:`group`) gives
        the boxes of :meth:`detect_scanned`.

        Parameters
        ----------
        scan_shape : (h_s, w_s, ...)
            Shape of the scan image (:meth:`scan_image`).
        n : int
            Bands wanted (>= 1).

        Returns
        -------
        list of ScaleBand
            ``(smallest, largest)`` window ``(w, h)`` of each band; empty when the image
            is smaller than the smallest face.
        """
        h, w = scan_shape[:2]
        w0, h0 = self._cascade.getOriginalWindowSize()
        windows: list[tuple[int, int]] = []
        work: list[float] = []
        factor = 1.0
        while True:  # OpenCV's loop over scales (CascadeClassifierImpl::detectMultiScale)
            ww, wh = int(np.rint(w0 * factor)), int(np.rint(h0 * factor))
            if ww > w or wh > h:
                break
            if ww >= self.min_size and wh >= self.min_size:
                step = 1 if factor > 2.0 else 2
                windows.append((ww, wh))
                tries = ((w / factor - w0) // step + 1) * ((h / factor - h0) // step + 1)
                work.append(max(1.0, tries))
            factor *= self.scale_factor
        if not windows:
            return []
        share = np.cumsum(work) / np.sum(work)  # the work done once each scale is scanned
        ends = sorted({int(np.searchsorted(share, (i + 1) / n - 1e-9)) for i in range(n)})
        starts = [0, *(e + 1 for e in ends[:-1])]
        return [(windows[a], windows[b]) for a, b in zip(starts, ends, strict=True)]

    def detect_band(self, gray: Image, band: ScaleBand) -> FloatArray:
        """The cascade's raw candidates (ungrouped) at the scales of one band.

        Parameters
        ----------
        gray : (h_s, w_s) uint8
            The scan image (:meth:`scan_image`).
        band : ScaleBand
            From :meth:`scale_bands` for this image's shape.

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of every window the cascade accepts, scanned pixels.
        """
        found = self._cascade.detectMultiScale(
            gray, scaleFactor=self.scale_factor, minNeighbors=0, minSize=band[0], maxSize=band[1]
        )
        return np.asarray(found, np.float64).reshape(-1, 4)

    def group(self, candidates: FloatArray) -> FloatArray:
        """Raw candidates of every band of one scan image -> its face boxes.

        OpenCV's own grouping (``groupRectangles``, ``min_neighbours``, eps 0.2, as
        ``detectMultiScale`` groups): the boxes :meth:`detect_scanned` gives.

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of each face, scanned pixels, largest first.
        """
        raw = np.asarray(candidates, np.float64).reshape(-1, 4)
        if self.min_neighbours > 0 and len(raw):
            found, _ = cv2.groupRectangles(raw.astype(np.int32).tolist(), self.min_neighbours, 0.2)
            raw = np.asarray(found, np.float64).reshape(-1, 4)
        return raw[np.argsort(-raw[:, 2] * raw[:, 3], kind="stable")]

    def detect(self, image_bgr: Image) -> FloatArray:
        """Face boxes in content pixels.

        Parameters
        ----------
        image_bgr : (h, w, 3) or (h, w) uint8

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of each face (top-left corner and size, content pixels),
            largest first; ``(0, 4)`` when there is none.
        """
        gray, scale = self.scan_image(image_bgr)
        return self.detect_scanned(gray) / scale


def face_map(
    boxes: FloatArray, content_size: tuple[int, int], map_size: tuple[int, int]
) -> Float32Array | None:
    """The faces as a map over the content: 1 on each face, soft edges, 0 elsewhere.

    Each box becomes an ellipse with semi-axes :data:`FACE_SCALE` times the box's width
    and height, centred :data:`FACE_DROP` box heights below the box's centre; the value
    is 1 inside it and falls smoothly (smoothstep) to 0 at elliptic radius
    ``1 + SOFTNESS``. Samples sit at the map cells' centres (the convention of
    :meth:`~adaproj_edge.content.contentmap.ContentMap.sample`).

    Parameters
    ----------
    boxes : (n, 4) float
        ``x, y, w, h`` in content pixels.
    content_size : (w, h)
        The content's size in pixels.
    map_size : (w', h')
        The map's size.

    Returns
    -------
    (h', w') float32 in [0, 1], or None
        None when there are no boxes of at least a pixel a side (so a map without faces
        is left exactly as it was).
    """
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    b = b[np.all(np.isfinite(b), axis=1) & (b[:, 2] >= 1.0) & (b[:, 3] >= 1.0)]
    if len(b) == 0:
        return None
    w, h = content_size
    mw, mh = map_size
    xs = (np.arange(mw) + 0.5) * (w / mw) - 0.5
    ys = (np.arange(mh) + 0.5) * (h / mh) - 0.5
    out = np.zeros((mh, mw), np.float64)
    for x, y, bw, bh in b:
        cx, cy = x + bw / 2 - 0.5, y + bh / 2 - 0.5 + FACE_DROP * bh
        ax, ay = FACE_SCALE[0] * bw, FACE_SCALE[1] * bh
        r = np.hypot((xs[None, :] - cx) / ax, (ys[:, None] - cy) / ay)
        t = np.clip((1.0 + SOFTNESS - r) / SOFTNESS, 0.0, 1.0)
        out = np.maximum(out, t * t * (3.0 - 2.0 * t))
    return out.astype(np.float32)
