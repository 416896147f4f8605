"""Face photos for the tests and ``tools/bench_faces.py``, built from what scikit-image ships.

- :func:`astronaut`: ``skimage.data.astronaut()`` (NASA, public domain) with a face box
  marked by hand on the 512 x 512 picture (hairline to chin, ear to ear).
- :func:`face_scenes`: the 100 faces of ``skimage.data.lfw_subset()`` (Labeled Faces in
  the Wild, 25 x 25 crops) enlarged and blended, in a skin tint with feathered edges,
  into 640 x 400 scenes cut from scikit-image's texture and photo samples, next to a
  saturated "flag" (the kind of thing GBVS ranks above a face); the box of each pasted
  face is the ground truth. :func:`non_face_scenes` pastes the subset's 100 non-face
  crops the same way (false alarms).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from skimage import data

from adaproj_edge.content.facetrack import box_iou

SCENE = (640, 400)
ASTRONAUT_FACE = (168, 45, 118, 150)
"""x, y, w, h of her face in ``astronaut()`` (hand-marked: hairline to chin)."""


@dataclass(frozen=True)
class Scene:
    """A picture (BGR) and the box of its one face (x, y, w, h), or None."""

    image: NDArray[np.uint8]
    face: tuple[int, int, int, int] | None


def astronaut() -> Scene:
    """The astronaut photo, BGR 512 x 512, with her face's box."""
    return Scene(cv2.cvtColor(data.astronaut(), cv2.COLOR_RGB2BGR), ASTRONAUT_FACE)


def _backgrounds() -> list[NDArray[np.uint8]]:
    colour = [data.coffee(), data.rocket(), data.chelsea(), data.hubble_deep_field()]
    gray = [data.grass(), data.gravel(), data.brick(), data.text(), data.coins()]
    out = [cv2.cvtColor(c, cv2.COLOR_RGB2BGR) for c in colour]
    return out + [cv2.cvtColor(g, cv2.COLOR_GRAY2BGR) for g in gray]


def _paste(
    crops: NDArray[np.uint8], seed: int, sizes: tuple[int, int]
) -> list[tuple[NDArray[np.uint8], tuple[int, int, int, int]]]:
    rng = np.random.default_rng(seed)
    bgs = _backgrounds()
    w, h = SCENE
    out = []
    for crop in crops:
        bg = bgs[int(rng.integers(len(bgs)))]
        bh, bw = bg.shape[:2]
        cut = min(bh, bw * h // w)
        y0, x0 = int(rng.integers(0, bh - cut + 1)), int(rng.integers(0, bw - cut * w // h + 1))
        scene = cv2.resize(bg[y0 : y0 + cut, x0 : x0 + cut * w // h], SCENE)
        s = int(rng.integers(sizes[0], sizes[1] + 1))
        x, y = int(rng.integers(0, w - s)), int(rng.integers(0, h - s))
        _flag(scene, rng, (x, y, s))
        patch = cv2.resize(crop, (s, s), interpolation=cv2.INTER_CUBIC).astype(np.float64)
        skin = np.array([0.62, 0.75, 0.95]) * rng.uniform(0.8, 1.1)  # BGR
        alpha = np.zeros((s, s), np.float64)
        cv2.ellipse(alpha, (s // 2, s // 2), (int(s * 0.48), int(s * 0.5)), 0, 0, 360, 1.0, -1)
        alpha = cv2.GaussianBlur(alpha, (0, 0), s / 20)[:, :, None]
        region = scene[y : y + s, x : x + s].astype(np.float64)
        mixed = alpha * patch[:, :, None] * skin + (1 - alpha) * region
        scene[y : y + s, x : x + s] = np.clip(mixed, 0, 255).astype(np.uint8)
        out.append((np.asarray(scene, np.uint8), (x, y, s, s)))
    return out


def _flag(scene: NDArray[np.uint8], rng: np.random.Generator, face: tuple[int, int, int]) -> None:
    """Red and white stripes with a blue canton, somewhere away from the face."""
    h, w = scene.shape[:2]
    fw, fh = int(rng.integers(100, 180)), int(rng.integers(60, 110))
    fx, fy, s = face
    for _ in range(50):
        x, y = int(rng.integers(0, w - fw)), int(rng.integers(0, h - fh))
        if x > fx + s or x + fw < fx or y > fy + s or y + fh < fy:
            break
    stripes = max(5, fh // 10)
    for i in range(stripes):
        colour = (40, 30, 210) if i % 2 == 0 else (245, 245, 245)
        y0, y1 = y + i * fh // stripes, y + (i + 1) * fh // stripes
        scene[y0:y1, x : x + fw] = colour
    scene[y : y + fh // 2, x : x + fw * 2 // 5] = (140, 40, 20)


def _lfw(faces: bool) -> NDArray[np.uint8]:
    crops = data.lfw_subset()
    part = crops[:100] if faces else crops[100:]
    return np.asarray(np.round(part * 255.0), np.uint8)


def face_scenes(n: int = 100, seed: int = 1, sizes: tuple[int, int] = (56, 160)) -> list[Scene]:
    """``n`` scenes (up to 100), each with one pasted LFW face of ``sizes`` px."""
    return [Scene(img, box) for img, box in _paste(_lfw(True)[:n], seed, sizes)]


def non_face_scenes(n: int = 100, seed: int = 2, sizes: tuple[int, int] = (56, 160)) -> list[Scene]:
    """``n`` scenes with a pasted LFW non-face crop and no face."""
    return [Scene(img, None) for img, _ in _paste(_lfw(False)[:n], seed, sizes)]


def iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Intersection over union of two ``x, y, w, h`` boxes."""
    return box_iou(np.asarray(a, np.float64), np.asarray(b, np.float64))


def region_ratio(values: NDArray[np.floating], box: tuple[int, int, int, int]) -> float:
    """Mean of a full-size map inside ``box`` over its mean outside it."""
    x, y, w, h = box
    inside = np.zeros(values.shape[:2], bool)
    inside[y : y + h, x : x + w] = True
    return float(values[inside].mean() / max(float(values[~inside].mean()), 1e-9))
