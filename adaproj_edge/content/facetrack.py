"""Faces followed across the frames of a clip: detect every N frames, track in between.

A detection costs tens of milliseconds (``models/lbpcascade_frontalface.md``); a frame
at 30 fps has 33. :class:`FaceTracker` runs the detector on every ``every``-th frame (a
caller may put a detection off by a frame: the content map does, so that no frame runs
both the detector and the saliency model) and in between follows each face by
normalised cross-correlation of its last appearance (a template cut from the scanned
image) within a window around its last position,
which costs well under a millisecond per face. A face the detector no longer finds is
kept for ``keep`` more detections (a turned head, a blink of the detector), then
dropped; a face that can no longer be followed is dropped at once.

The tracker counts frames, not seconds: no clock, and the same frames always give the
same boxes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.content.faces import NO_FACES, FaceDetector


@dataclass
class _Track:
    box: FloatArray  # x, y, w, h in scanned pixels
    template: Image
    misses: int = 0


def box_iou(a: FloatArray, b: FloatArray) -> float:
    """Intersection over union of two ``x, y, w, h`` boxes (4,)."""
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return float(inter / union) if union > 0 else 0.0


class FaceTracker:
    """Faces in successive frames of one clip.

    Parameters
    ----------
    detector : FaceDetector
        Finds faces (its ``long_side`` sets the scan size, shared with the tracking).
    every : int
        Run the detector on frames 0, ``every``, 2 ``every``, ...
    keep : int
        Detections a face may be missed by before it is dropped.
    min_score : float
        Normalised correlation below which a face is lost between detections.
    search : float
        Half-width of the search window around a face, in face sizes.
    """

    def __init__(
        self,
        detector: FaceDetector,
        *,
        every: int = 6,
        keep: int = 1,
        min_score: float = 0.5,
        search: float = 0.5,
    ) -> None:
        if every < 1 or keep < 0 or search <= 0:
            raise ValueError("need every >= 1, keep >= 0, search > 0")
        self.detector = detector
        self.every = every
        self.keep = keep
        self.min_score = min_score
        self.search = search
        self.frames = 0
        self.detections = 0
        self._since: int | None = None  # frames since the last detection (None: none yet)
        self._tracks: list[_Track] = []

    def reset(self) -> None:
        """Forget every face (a new clip, or a jump in the clip); next frame detects."""
        self.frames = 0
        self._since = None
        self._tracks = []

    @property
    def due(self) -> bool:
        """Whether the detector is due on the next frame: the first frame, or ``every``
        frames or more since the last detection."""
        return self._since is None or self._since >= self.every

    def update(self, frame_bgr: Image, detect: bool | None = None) -> FloatArray:
        """The faces in the next frame of the clip.

        Parameters
        ----------
        frame_bgr : (h, w, 3) or (h, w) uint8
            The frame, in the clip's order.
        detect : bool, optional
            Run the detector on this frame (True) or follow the faces (False); None:
            when :attr:`due` (frames 0, ``every``, 2 ``every``, ... unless a caller
            put a detection off: the next one is then ``every`` frames after it).

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of each face in frame pixels, largest first.
        """
        gray, scale = self.detector.scan_image(frame_bgr)
        if self.due if detect is None else detect:
            self._detect(gray)
            self._since = 0
        else:
            self._follow(gray)
        if self._since is not None:
            self._since += 1
        self.frames += 1
        if not self._tracks:
            return NO_FACES.copy()
        boxes = np.array([t.box for t in self._tracks], np.float64) / scale
        return boxes[np.argsort(-boxes[:, 2] * boxes[:, 3], kind="stable")]

    def _detect(self, gray: Image) -> None:
        self.detections += 1
        found = self.detector.detect_scanned(gray)
        claimed: set[int] = set()
        tracks: list[_Track] = []
        for box in found:
            scores = [
                box_iou(box, t.box) if i not in claimed else 0.0 for i, t in enumerate(self._tracks)
            ]
            if scores and max(scores) > 0.2:
                claimed.add(int(np.argmax(scores)))
            tracks.append(_Track(box.copy(), _cut(gray, box)))
        for i, t in enumerate(self._tracks):
            if i not in claimed and t.misses < self.keep:
                if all(box_iou(t.box, n.box) < 0.2 for n in tracks):
                    t.misses += 1
                    tracks.append(t)
        self._tracks = [t for t in tracks if t.template.size]

    def _follow(self, gray: Image) -> None:
        kept = []
        h, w = gray.shape[:2]
        for t in self._tracks:
            x, y, bw, bh = t.box
            th, tw = t.template.shape[:2]
            pad_x, pad_y = round(self.search * bw), round(self.search * bh)
            x0, y0 = max(0, round(x) - pad_x), max(0, round(y) - pad_y)
            x1, y1 = min(w, round(x) + tw + pad_x), min(h, round(y) + th + pad_y)
            window = gray[y0:y1, x0:x1]
            if window.shape[0] < th or window.shape[1] < tw:
                continue
            scores = cv2.matchTemplate(window, t.template, cv2.TM_CCOEFF_NORMED)
            _, best, _, (bx, by) = cv2.minMaxLoc(scores)
            if not np.isfinite(best) or best < self.min_score:
                continue
            t.box = np.array([x0 + bx, y0 + by, bw, bh], np.float64)
            kept.append(t)
        self._tracks = kept


def _cut(gray: Image, box: FloatArray) -> Image:
    """The part of ``gray`` under ``box`` (clipped to the image)."""
    h, w = gray.shape[:2]
    x, y, bw, bh = (round(float(v)) for v in box)
    return np.ascontiguousarray(gray[max(0, y) : min(h, y + bh), max(0, x) : min(w, x + bw)])
