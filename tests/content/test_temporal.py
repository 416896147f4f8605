"""A clip's content map in time: faces followed across frames, the smoothed map."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from adaproj_edge.arrays import Image
from adaproj_edge.content.faces import FaceDetector, ScaleBand
from adaproj_edge.content.facetrack import FaceTracker
from adaproj_edge.content.model import SaliencyModel
from adaproj_edge.content.temporal import TemporalContentMap, TemporalSettings
from tests.content.clips import frame
from tests.content.facescenes import astronaut

SIZE = (320, 200)
STEP = (9, 2)  # px a frame the face moves


def face_clip(n: int) -> list[tuple[Image, tuple[int, int]]]:
    """Frames with the astronaut's head moving over blurred noise, and its offset."""
    head = astronaut().image[30:210, 150:300]
    head = cv2.resize(head, (75, 90), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(4)
    bg = cv2.GaussianBlur(rng.integers(0, 255, (SIZE[1], SIZE[0], 3), dtype=np.uint8), (0, 0), 4)
    out = []
    for i in range(n):
        f = bg.copy()
        x, y = 10 + STEP[0] * i, 40 + STEP[1] * i
        f[y : y + 90, x : x + 75] = head
        out.append((np.asarray(f, np.uint8), (x, y)))
    return out


class CountingDetector(FaceDetector):
    """The shipped detector, counting the bands of scales it scans."""

    scans = 0

    def detect_band(self, gray: Image, band: ScaleBand) -> np.ndarray:
        self.scans += 1
        return super().detect_band(gray, band)


def test_tracker_detects_every_n_frames_one_band_a_frame_and_follows_in_between() -> None:
    det = CountingDetector(long_side=320)
    tracker = FaceTracker(det, every=5, slices=3)
    clip = face_clip(24)
    boxes, bands = [], []
    for f, _ in clip:
        scans = det.scans
        boxes.append(tracker.update(f))
        bands.append(det.scans - scans)
    # the first frame scans every scale at once, then a detection starts on frames 5, 10,
    # 15, 20 and takes three frames, one band of scales each
    assert bands == [1, 0, 0, 0, 0] + [1, 1, 1, 0, 0] * 3 + [1, 1, 1, 0]
    assert tracker.detections == 5 and tracker.bands_scanned == 1 + 3 * 4
    assert all(len(b) == 1 for b in boxes)
    first = boxes[0][0]
    for (_, (x, y)), b in zip(clip, boxes, strict=True):
        offset = b[0][:2] - first[:2] - np.array([x - clip[0][1][0], y - clip[0][1][1]])
        assert np.abs(offset).max() <= 3.0  # follows the head to a few pixels
        assert b[0][2] == pytest.approx(first[2], rel=0.2)


def test_a_face_found_by_a_spread_detection_is_placed_where_it_is_now() -> None:
    # a detection spread over frames 5-7 finds the face in frame 5; by frame 7 the face
    # has moved 18 px: it is followed from frame 5 to frame 7, not shown where it was
    det = FaceDetector(long_side=320)
    tracker = FaceTracker(det, every=5, slices=3)
    clip = face_clip(8)
    empty = cv2.GaussianBlur(np.full((SIZE[1], SIZE[0], 3), 90, np.uint8), (0, 0), 2)
    boxes = [tracker.update(empty if i < 3 else f) for i, (f, _) in enumerate(clip)]
    assert [len(b) for b in boxes] == [0] * 7 + [1]
    (now,) = det.detect(clip[7][0])  # a whole detection of frame 7: where the face is
    assert np.abs(boxes[7][0][:2] - now[:2]).max() <= 3.0


def test_tracker_drops_a_face_that_leaves() -> None:
    tracker = FaceTracker(FaceDetector(long_side=320), every=4, keep=1)
    clip = face_clip(3)
    for f, _ in clip:
        assert len(tracker.update(f)) == 1
    empty = cv2.GaussianBlur(np.full((SIZE[1], SIZE[0], 3), 90, np.uint8), (0, 0), 2)
    results = [len(tracker.update(empty)) for _ in range(10)]
    assert results[-1] == 0 and results[0] == 0  # lost at once: nothing to follow
    tracker.reset()
    assert tracker.frames == 0 and len(tracker.update(clip[0][0])) == 1


def centroid(values: np.ndarray) -> float:
    w = np.clip(values.astype(np.float64) - 0.3, 0.0, None) ** 2
    return float((w.sum(axis=0) * np.arange(values.shape[1])).sum() / w.sum())


def disc_clip(n: int, speed: float) -> list[Image]:
    return [frame(i, (320, 200), speed) for i in range(n)]


def test_static_clip_gives_a_constant_map(model: SaliencyModel) -> None:
    still = disc_clip(1, 0.0) * 20
    tmap = TemporalContentMap(SIZE, model, tracker=FaceTracker(FaceDetector()))
    maps = [tmap.update(f).values for f in still]
    assert all(np.array_equal(m, maps[0]) for m in maps)
    assert tmap.saliency_runs == 5  # every 4th frame of 20
    assert maps[0].max() > 0.9


def test_moving_subject_gives_a_smoothly_moving_map(model: SaliencyModel) -> None:
    clip = disc_clip(40, 4.0)

    def path(settings: TemporalSettings) -> np.ndarray:
        tmap = TemporalContentMap(SIZE, model, settings=settings)
        return np.array([centroid(tmap.update(f).values) for f in clip])

    smooth = path(TemporalSettings(saliency_every=4, alpha=0.25))
    steps = np.diff(smooth[8:])
    assert np.all(steps > -0.05)  # follows the subject (rightwards) without going back
    assert smooth[-1] - smooth[8] > 10  # map cells: the subject moved ~37 of them
    assert steps.max() <= 2.5 * steps.mean()  # no jumps
    jumpy = np.diff(path(TemporalSettings(saliency_every=4, alpha=1.0))[8:])
    assert jumpy.max() >= 3.0 * jumpy.mean()  # what it would be without smoothing
    accel = np.sqrt(np.mean(np.diff(steps) ** 2))
    assert accel < 0.5 * np.sqrt(np.mean(np.diff(jumpy) ** 2))


def test_mask_applies_to_every_frame_and_faces_are_followed(model: SaliencyModel) -> None:
    mask = np.zeros((50, 80), np.float32)
    mask[40:, :10] = 1.0
    clip = face_clip(12)
    tmap = TemporalContentMap(
        SIZE, model, mask=mask, tracker=FaceTracker(FaceDetector(long_side=320), every=4)
    )
    for f, (x, y) in clip:
        cmap = tmap.update(f)
        assert cmap.values[45, 2] == 1.0  # the mask, unsmoothed
        assert 0.0 <= cmap.values.min() and cmap.values.max() <= 1.0
        assert len(cmap.faces) == 1
        fx, fy = cmap.faces[0][:2]
        assert x - 5 <= fx <= x + 75 and y - 5 <= fy <= y + 90
    full = cmap.full_size()
    assert full[y + 30 : y + 60, x + 20 : x + 55].mean() > 0.8  # the face is salient


class CountingModel:
    """A saliency stand-in (the frame's brightness) that counts its runs."""

    runs = 0

    def predict(self, image_bgr: Image) -> np.ndarray:
        self.runs += 1
        return np.asarray(image_bgr[..., 1], np.float32) / 255.0


@pytest.mark.parametrize(
    ("saliency_every", "faces_every", "slices"), [(4, 6, 5), (4, 4, 1), (3, 5, 3), (2, 2, 1)]
)
def test_saliency_and_face_detection_take_turns(
    saliency_every: int, faces_every: int, slices: int
) -> None:
    # before, frames 0, 12, 24, ... (saliency every 4th, faces every 6th) paid for both,
    # and a frame that detected faces paid for a whole detection (~32 ms at 1280x720)
    det, model = CountingDetector(long_side=320), CountingModel()
    tracker = FaceTracker(det, every=faces_every, slices=slices)
    settings = TemporalSettings(saliency_every=saliency_every)
    tmap = TemporalContentMap(SIZE, model, tracker=tracker, settings=settings)
    detected, runs, due = [], [], []
    for f, (x, y) in face_clip(25):
        model.runs, scans = 0, det.scans
        due.append(tracker.due)
        cmap = tmap.update(f)
        detected.append(det.scans - scans)
        runs.append(model.runs)
        assert len(cmap.faces) == 1  # followed on every frame, the first too
        fx, fy = cmap.faces[0][:2]
        assert x - 5 <= fx <= x + 75 and y - 5 <= fy <= y + 90
    # the work a frame does is bounded: after the first, one band of the detector or
    # the saliency model, never both, never more than one band
    assert runs[0] == detected[0] == 1
    assert all(r + d <= 1 for r, d in zip(runs[1:], detected[1:], strict=True)), (runs, detected)
    # each as often as asked: the saliency model on its frames, the detector on every
    # other frame it has work on (put off by a saliency frame, never skipped)
    assert sum(runs) == len(range(0, 25, saliency_every))
    assert all(d == (w and not r) for d, w, r in zip(detected[1:], due[1:], runs[1:], strict=True))
    unfinished = tracker.bands_scanned - 1 - slices * (tracker.detections - 1)
    assert 0 <= unfinished < slices  # a detection is its bands, one a frame
    assert tracker.detections - 1 >= (25 - 1) // (faces_every + slices + 1)


def test_bad_frames_and_settings_refused(model: SaliencyModel) -> None:
    tmap = TemporalContentMap(SIZE, model)
    with pytest.raises(ValueError, match="frame is"):
        tmap.update(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(ValueError, match="alpha"):
        TemporalSettings(alpha=0.0)
    tmap.update(disc_clip(1, 0.0)[0])
    tmap.reset()
    assert tmap.frames == 0
