"""Faces followed across the frames of a clip: detect every N frames, track in between.

A detection costs tens of milliseconds (``models/lbpcascade_frontalface.md``; ~32 ms
of CPU at 1280x720 on the development machine); a frame at 30 fps has 33. So
:class:`FaceTracker` starts a detection every ``every``-th frame and spreads it over the
next ``slices`` frames that do detector work: each scans one band of the cascade's
scales (:meth:`~adaproj_edge.content.faces.FaceDetector.scale_bands`, bands of about
equal work, smallest faces first) of the image of the frame the detection started on,
and when the last band is done the candidates of all bands are grouped together: the
boxes a whole detection of that frame gives (tested). A caller may put the detector's
work off by a frame: the content map does, so that no frame runs both a band of the
detector and the saliency model. The first detection after a reset scans every band at
once (the first frame's map has its faces).

In between, and on the frames of a detection, each face is followed by normalised
cross-correlation of its last appearance (a template cut from the scanned image)
within a window around its last position, which costs well under a millisecond per
face. A finished detection speaks of the frame it started on: a face found there that
is being followed takes the detected box moved by how far the face has been followed
since; a new face is followed from that frame to this one. A face the detector no
longer finds is kept for ``keep`` more detections (a turned head, a blink of the
detector), then dropped; a face that can no longer be followed is dropped at once.

The tracker counts frames, not seconds: no clock, and the same frames always give the
same boxes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.content.faces import NO_FACES, FaceDetector, ScaleBand

DEFAULT_SLICES = 5
"""Frames a detection is spread over (~6.5 ms of a ~32 ms detection each at 1280x720)."""


@dataclass
class _Track:
    box: FloatArray  # x, y, w, h in scanned pixels
    template: Image
    misses: int = 0
    anchor: FloatArray | None = None  # the box on the frame the running detection scans


@dataclass
class _Scan:
    """A detection under way: the scan image of its frame, the bands left to scan and
    the candidates found so far."""

    gray: Image
    bands: list[ScaleBand]
    found: list[FloatArray] = field(default_factory=list)


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
        Start a detection on frames 0, ``every``, 2 ``every``, ...
    slices : int
        Frames a detection is spread over (bands of the cascade's scales, one a frame);
        1 scans the whole image on the frame the detection starts.
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
        slices: int = DEFAULT_SLICES,
        keep: int = 1,
        min_score: float = 0.5,
        search: float = 0.5,
    ) -> None:
        if every < 1 or slices < 1 or keep < 0 or search <= 0:
            raise ValueError("need every >= 1, slices >= 1, keep >= 0, search > 0")
        self.detector = detector
        self.every = every
        self.slices = slices
        self.keep = keep
        self.min_score = min_score
        self.search = search
        self.frames = 0
        self.detections = 0
        self.bands_scanned = 0
        self._since: int | None = None  # frames since the last detection started (None: none)
        self._tracks: list[_Track] = []
        self._scan: _Scan | None = None

    def reset(self) -> None:
        """Forget every face (a new clip, or a jump in the clip); next frame detects."""
        self.frames = 0
        self._since = None
        self._tracks = []
        self._scan = None

    @property
    def due(self) -> bool:
        """Whether the detector has work on the next frame: a detection under way, the
        first frame, or ``every`` frames or more since the last detection started."""
        return self._scan is not None or self._since is None or self._since >= self.every

    def update(self, frame_bgr: Image, detect: bool | None = None) -> FloatArray:
        """The faces in the next frame of the clip.

        Parameters
        ----------
        frame_bgr : (h, w, 3) or (h, w) uint8
            The frame, in the clip's order.
        detect : bool, optional
            Let the detector work on this frame (True: one band of the detection under
            way, or start one) or only follow the faces (False); None: when
            :attr:`due` (detections start on frames 0, ``every``, 2 ``every``, ...
            unless a caller put the work off: the next one then starts ``every``
            frames after it).

        Returns
        -------
        (n, 4) float64
            ``x, y, w, h`` of each face in frame pixels, largest first.
        """
        gray, scale = self.detector.scan_image(frame_bgr)
        if self.due if detect is None else detect:
            self._work(gray)
        else:
            self._follow(gray)
        if self._since is not None:
            self._since += 1
        self.frames += 1
        if not self._tracks:
            return NO_FACES.copy()
        boxes = np.array([t.box for t in self._tracks], np.float64) / scale
        return boxes[np.argsort(-boxes[:, 2] * boxes[:, 3], kind="stable")]

    def _work(self, gray: Image) -> None:
        """The detector's work on this frame: start a detection (the whole of it on a
        first frame) or scan the next band of the one under way; finish it when its
        last band is done."""
        scan = self._scan
        if scan is None:
            first = self._since is None
            bands = self.detector.scale_bands(gray.shape, 1 if first else self.slices)
            scan = self._scan = _Scan(gray, bands)
            self._since = 0
            if len(bands) > 1:  # the faces move on while the detection is under way
                self._follow(gray)
            for t in self._tracks:
                t.anchor = t.box.copy()
        else:
            self._follow(gray)
        if scan.bands:
            scan.found.append(self.detector.detect_band(scan.gray, scan.bands.pop(0)))
            self.bands_scanned += 1
        if not scan.bands:
            self._scan = None
            found = np.concatenate(scan.found) if scan.found else NO_FACES
            self._detected(scan.gray, self.detector.group(found), gray)

    def _detected(self, scanned: Image, found: FloatArray, gray: Image) -> None:
        """Take the faces ``found`` in ``scanned`` (the image the detection scanned) into
        the tracks, on the frame whose scan image is ``gray``."""
        self.detections += 1
        claimed: set[int] = set()
        tracks: list[_Track] = []
        for box in found:
            scores = [
                box_iou(box, t.anchor) if i not in claimed and t.anchor is not None else 0.0
                for i, t in enumerate(self._tracks)
            ]
            track = _Track(box.copy(), _cut(scanned, box))
            if scores and max(scores) > 0.2:
                i = int(np.argmax(scores))
                claimed.add(i)
                followed = self._tracks[i]
                assert followed.anchor is not None
                track.box[:2] += followed.box[:2] - followed.anchor[:2]
            elif scanned is not gray and not self._follow_one(gray, track):
                continue  # a new face, lost between the scanned frame and this one
            tracks.append(track)
        for i, t in enumerate(self._tracks):
            t.anchor = None
            if i not in claimed and t.misses < self.keep:
                if all(box_iou(t.box, n.box) < 0.2 for n in tracks):
                    t.misses += 1
                    tracks.append(t)
        self._tracks = [t for t in tracks if t.template.size]

    def _follow(self, gray: Image) -> None:
        self._tracks = [t for t in self._tracks if self._follow_one(gray, t)]

    def _follow_one(self, gray: Image, t: _Track) -> bool:
        """Move ``t`` to where its template matches best near its box; False: lost."""
        h, w = gray.shape[:2]
        x, y, bw, bh = t.box
        th, tw = t.template.shape[:2]
        pad_x, pad_y = round(self.search * bw), round(self.search * bh)
        x0, y0 = max(0, round(x) - pad_x), max(0, round(y) - pad_y)
        x1, y1 = min(w, round(x) + tw + pad_x), min(h, round(y) + th + pad_y)
        window = gray[y0:y1, x0:x1]
        if window.shape[0] < th or window.shape[1] < tw:
            return False
        scores = cv2.matchTemplate(window, t.template, cv2.TM_CCOEFF_NORMED)
        _, best, _, (bx, by) = cv2.minMaxLoc(scores)
        if not np.isfinite(best) or best < self.min_score:
            return False
        t.box = np.array([x0 + bx, y0 + by, bw, bh], np.float64)
        return True


def _cut(gray: Image, box: FloatArray) -> Image:
    """The part of ``gray`` under ``box`` (clipped to the image)."""
    h, w = gray.shape[:2]
    x, y, bw, bh = (round(float(v)) for v in box)
    return np.ascontiguousarray(gray[max(0, y) : min(h, y + bh), max(0, x) : min(w, x + bw)])
