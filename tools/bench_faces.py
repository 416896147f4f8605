#!/usr/bin/env python3
"""Face detectors for the content map: speed and hit rate, one core.

For each cascade (the shipped LBP frontal-face cascade, and any ``--cascade FILE`` given,
e.g. the Haar cascades of an OpenCV 4.x wheel's ``cv2/data``) and each scan size (the
long side of the image the cascade scans), prints:

- the median time of one detection on a 1280x800 face scene (the projector's size);
- hits: scenes of ``tests/content/facescenes.py`` whose face is found (IoU > 0.3), of
  100, and the astronaut photo;
- false alarms: boxes on the 100 non-face scenes, and boxes in face scenes that are not
  the face.

"80x50" is the content map's own resolution (a 16:10 content, 20x20 grid): faces there
are a few pixels wide, below the cascade's 24-pixel window. "full" scans the 1280x800
picture as it is. The ratio column is time relative to the shipped cascade at the
default scan size, measured in the same run. Last, the per-frame cost of following a
face between detections (``FaceTracker``) on a 1280x800 clip, next to a detection on
the same frames.

Usage::

    .venv/bin/python tools/bench_faces.py [--cascade F.xml ...] [--sizes 80,320,480,640,full]
        [--scenes 100] [--neighbours 4]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.content.facescenes (the face set)

from adaproj_edge.content.faces import DEFAULT_LONG_SIDE, FaceDetector  # noqa: E402
from adaproj_edge.content.facetrack import FaceTracker  # noqa: E402
from adaproj_edge.resources import face_cascade  # noqa: E402
from tests.content.facescenes import (  # noqa: E402
    Scene,
    astronaut,
    face_scenes,
    iou,
    non_face_scenes,
)

DEVICE = (1280, 800)


def evaluate(
    det: FaceDetector, faces: list[Scene], others: list[Scene], big: np.ndarray
) -> dict[str, float]:
    """Hit rate, false alarms and the median time on ``big`` of one detector."""
    hits = wrong = 0
    for s in faces:
        assert s.face is not None
        found = [iou(tuple(b), s.face) > 0.3 for b in det.detect(s.image)]
        hits += any(found)
        wrong += len(found) - sum(found)
    alarms = sum(len(det.detect(s.image)) for s in others)
    a = astronaut()
    assert a.face is not None
    astro = any(iou(tuple(b), a.face) > 0.3 for b in det.detect(a.image))
    det.detect(big)
    times = []
    for _ in range(7):
        t0 = time.perf_counter()
        det.detect(big)
        times.append(time.perf_counter() - t0)
    return {
        "ms": 1e3 * statistics.median(times),
        "hits": hits,
        "astro": float(astro),
        "wrong": wrong,
        "alarms": alarms,
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--cascade", type=Path, action="append", default=[], help="another cascade")
    p.add_argument("--sizes", default="80,320,480,640,full", help="scan long sides")
    p.add_argument("--scenes", type=int, default=100, help="face and non-face scenes (<= 100)")
    p.add_argument("--neighbours", type=int, default=4, help="min_neighbours of the cascade")
    args = p.parse_args()
    cv2.setNumThreads(1)

    faces = face_scenes(args.scenes)
    others = non_face_scenes(args.scenes)
    big = cv2.resize(faces[0].image, DEVICE, interpolation=cv2.INTER_CUBIC)
    sizes = [s.strip() for s in args.sizes.split(",")]
    cascades = [face_cascade(), *args.cascade]
    base = evaluate(
        FaceDetector(long_side=DEFAULT_LONG_SIDE, min_neighbours=args.neighbours),
        faces,
        others,
        big,
    )["ms"]
    n = len(faces)
    print(
        f"{'cascade':34s} {'scan':>5s} {'ms 1280x800':>11s} {'ratio':>6s} "
        f"{'hits':>8s} {'astro':>5s} {'wrong':>5s} {'alarms':>6s}"
    )
    for path in cascades:
        for size in sizes:
            long_side = max(DEVICE) if size == "full" else int(size)
            det = FaceDetector(path, long_side=long_side, min_neighbours=args.neighbours)
            r = evaluate(det, faces, others, big)
            print(
                f"{path.stem:34s} {size:>5s} {r['ms']:11.1f} {r['ms'] / base:5.2f}x "
                f"{int(r['hits']):4d}/{n:<3d} {'yes' if r['astro'] else 'no':>5s} "
                f"{int(r['wrong']):5d} {int(r['alarms']):4d}/{n}"
            )
    tracking(faces[0])
    return 0


def tracking(scene: Scene, frames: int = 30) -> None:
    """Median ms per frame of a moving face: the first frame (a whole scan), frames that
    scan a band of a detection spread over frames, and frames that only follow."""
    assert scene.face is not None
    big = cv2.resize(scene.image, DEVICE, interpolation=cv2.INTER_CUBIC)
    tracker = FaceTracker(FaceDetector(), every=6)
    whole, band, follow = [], [], []
    for i in range(frames):
        f = np.roll(big, 6 * i, axis=1)
        scanned = tracker.bands_scanned
        t0 = time.perf_counter()
        tracker.update(f)
        t = time.perf_counter() - t0
        (whole if i == 0 else band if tracker.bands_scanned > scanned else follow).append(t)
    print(
        f"tracking 1280x800, a detection every {tracker.every} frames in {tracker.slices} "
        f"bands: first frame (whole scan) {1e3 * whole[0]:.1f} ms, band frame "
        f"{1e3 * statistics.median(band):.1f} ms, followed frame "
        f"{1e3 * statistics.median(follow):.2f} ms (median; {len(band)} band, "
        f"{len(follow)} followed)"
    )


if __name__ == "__main__":
    raise SystemExit(main())
