#!/usr/bin/env python3
"""Make docs/playback-frames.jpg: a few frames of the committed clip push session
(tests/fixtures/app/push-clip.mcap) as the device projected them in its replay.

    .venv/bin/python tools/playback_picture.py [--out docs/playback-frames.jpg]

Replays the session (every frame kept, in a temporary directory), takes the clip's
frames shown content-aware every ``--every`` seconds from the push, and writes them
side by side at quarter size, captioned with the session time.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.render.sheet import row  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from tests.app.golden import PUSH_CLIP_SESSION  # noqa: E402


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "playback-frames.jpg")
    ap.add_argument("--count", type=int, default=4, help="frames in the picture")
    ap.add_argument("--every", type=float, default=0.35, help="seconds between them")
    args = ap.parse_args()
    np.seterr(all="ignore")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        replay_session(PUSH_CLIP_SESSION, out, ReplayOptions(score=False, all_frames=True))
        summary = json.loads((out / "summary.json").read_text())
        start = next(e["t_s"] for e in summary["events"] if e["event"] == "clip")
        frames = [(i + 1, f["t_s"], f["kind"]) for i, f in enumerate(summary["frames"])]
        images, captions = [], []
        for k in range(args.count):
            want = start + 0.05 + k * args.every
            n, t, _ = min(
                (f for f in frames if f[2] == "content-aware"), key=lambda f: abs(f[1] - want)
            )
            img = cv2.imread(str(out / "frames" / f"{n:05d}.png"))
            h, w = img.shape[:2]
            images.append(cv2.resize(img, (w // 4, h // 4), interpolation=cv2.INTER_AREA))
            captions.append(f"{t:.2f} s ({t - start:.2f} s into the clip)")
    picture = row(images, captions, images[0].shape[0])
    cv2.imwrite(str(args.out), picture, [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(f"wrote {args.out} ({args.out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
