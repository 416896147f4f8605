"""The content map of a clip, coherent in time.

Running the saliency model on every frame costs ~5 ms of a 33 ms frame (CPU time on the
development machine), and a map that jumps from frame to frame would make the
content-aware warp flicker. The :class:`TemporalContentMap` therefore

- runs the saliency model every ``saliency_every`` frames (the target in between is
  the last one computed),
- follows the faces on every frame with a :class:`~adaproj_edge.content.facetrack.FaceTracker`
  (a detection every few frames, spread over several frames one band of scales at a
  time, tracking in between), the two detectors taking turns: the detector's work due
  on a frame the saliency model runs on is put off to the next frame, so after the
  first frame no frame does more than one of them (a whole face detection, ~32 ms at
  1280x720 on one core, with the model made frames late; a band is ~6.5 ms),
- smooths the saliency exponentially in time: each frame moves it a fraction
  ``alpha`` of the way to its target, so a subject that moves drags the map smoothly
  behind it and a still scene gives a map that does not change at all,
- takes the faces where they are in this frame (the tracker already moves them
  smoothly), max a smoothed trail of where they were, so a face that is lost for a
  few frames fades out instead of blinking,
- takes the max with the item's user mask, unsmoothed, on every frame.

It is pure apart from the frame counter: frames in, maps out, no clock. The first frame
gives its own map (no fade-in). A jump in the clip (a loop, a seek) should call
:meth:`TemporalContentMap.reset`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import Float32Array, FloatArray, Image
from adaproj_edge.content.contentmap import (
    DEFAULT_GRID,
    DEFAULT_THRESHOLD,
    ContentMap,
    coarse_size,
    combine_maps,
    resize_map,
)
from adaproj_edge.content.faces import NO_FACES, face_map
from adaproj_edge.content.facetrack import FaceTracker


class Saliency(Protocol):
    """What gives a frame's saliency: :class:`~adaproj_edge.content.model.SaliencyModel`
    on the device; a replay without the model passes a stand-in."""

    def predict(self, image_bgr: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Saliency of a whole frame, (h, w) float32 in [0, 1] at any size of its aspect."""
        ...


@dataclass(frozen=True)
class TemporalSettings:
    """How the map follows the clip.

    Attributes
    ----------
    saliency_every : int
        The model runs on frames 0, k, 2k, ... (k = ``saliency_every``).
    alpha : float
        In (0, 1]: the fraction of the way to the target the map moves each frame
        (1: no smoothing). 0.25 at 30 fps settles 90 % of a change in 8 frames.
    """

    saliency_every: int = 4
    alpha: float = 0.25

    def __post_init__(self) -> None:
        if self.saliency_every < 1 or not 0.0 < self.alpha <= 1.0:
            raise ValueError("need saliency_every >= 1 and 0 < alpha <= 1")


class TemporalContentMap:
    """Content maps for the frames of one clip, in order.

    Parameters
    ----------
    content_size : (w, h)
        The clip's frame size.
    model : Saliency
        The saliency model (one session, reused; anything with its ``predict``).
    mask : (h_m, w_m) float array in [0, 1], optional
        The item's user mask at any size of the clip's aspect (applies to every frame).
    tracker : FaceTracker, optional
        Follows the faces; None leaves faces out.
    settings : TemporalSettings
    threshold : float
        T of eq. 5.
    grid : (rows, cols)
        The warp grid the maps are sized for.
    """

    def __init__(
        self,
        content_size: tuple[int, int],
        model: Saliency,
        *,
        mask: NDArray[np.floating] | None = None,
        tracker: FaceTracker | None = None,
        settings: TemporalSettings | None = None,
        threshold: float = DEFAULT_THRESHOLD,
        grid: tuple[int, int] = DEFAULT_GRID,
    ) -> None:
        self.content_size = content_size
        self.model = model
        self.tracker = tracker
        self.settings = settings or TemporalSettings()
        self.threshold = threshold
        self.size = coarse_size(content_size, grid)
        self.mask = None if mask is None else resize_map(mask, self.size, area=True)
        self.frames = 0
        self.saliency_runs = 0
        self._saliency: Float32Array | None = None
        self._smooth: FloatArray | None = None
        self._faces: FloatArray | None = None

    def reset(self) -> None:
        """Start again as on a first frame (after a loop or a seek)."""
        self.frames = 0
        self._saliency = None
        self._smooth = None
        self._faces = None
        if self.tracker is not None:
            self.tracker.reset()

    def update(self, frame_bgr: Image) -> ContentMap:
        """The content map for the next frame of the clip.

        Parameters
        ----------
        frame_bgr : (h, w, 3) or (h, w) uint8
            The frame, of ``content_size``.

        Returns
        -------
        ContentMap
            Values (h', w') float32 in [0, 1]; ``faces`` holds the faces followed in this
            frame.
        """
        h, w = frame_bgr.shape[:2]
        if (w, h) != self.content_size:
            raise ValueError(f"frame is {w}x{h}, the clip is {self.content_size}")
        every = self.settings.saliency_every
        salient = self._saliency is None or self.frames % every == 0
        if salient or self._saliency is None:
            self.saliency_runs += 1
            self._saliency = resize_map(self.model.predict(frame_bgr), self.size, area=False)
        boxes = NO_FACES.copy()
        if self.tracker is not None:
            # the detectors take turns: the face detector's work due on a saliency frame
            # runs on the next frame (the first frame, which needs both, and a model run
            # on every frame excepted)
            first = self._smooth is None
            detect = self.tracker.due and (not salient or first or every == 1)
            boxes = self.tracker.update(frame_bgr, detect)
        now = face_map(boxes, self.content_size, self.size)
        faces = np.zeros(self.size[::-1]) if now is None else now.astype(np.float64)
        sal = self._saliency.astype(np.float64)
        if self._smooth is None or self._faces is None:
            self._smooth, self._faces = sal, faces
        else:
            a = self.settings.alpha
            self._smooth = self._smooth + a * (sal - self._smooth)
            self._faces = self._faces + a * (faces - self._faces)
        self.frames += 1
        maps: list[NDArray[np.floating]] = [self._smooth.astype(np.float32)]
        if now is not None or self._faces.any():
            maps.append(np.maximum(faces, self._faces).astype(np.float32))
        if self.mask is not None:
            maps.append(self.mask)
        return ContentMap(combine_maps(maps), self.content_size, self.threshold, boxes)
