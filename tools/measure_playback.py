#!/usr/bin/env python3
"""The device's clip playback against an independent full solve of every frame, on the
scene and clip of ``tests/app/test_playback.py``'s ground-truth test (convex sphere,
the hand still, 12 fps, the subject found by colour; the same scorer: rays cast at the
analytic surface, ``tests/distortion.py``).

Plays the clip through the runtime (its planner given the temporal settings asked
for) and, on every frame, also solves the frame's content map independently and cold on
the full grid (``compute_warp`` on the runtime's surface with the runtime's warp
settings, as ``tests/warp/test_temporal.py``'s reference). Prints per frame the
subject's size inconsistency of the shown warp and of the independent solve over the
pose's content-free warp's, and shown / independent; then the worst of each over the
frames the test scores (5, 11, 17, 23) and over all frames.

    .venv/bin/python tools/measure_playback.py                # the device's defaults
    .venv/bin/python tools/measure_playback.py --line-fit     # warp.temporal.LINE_FIT
    .venv/bin/python tools/measure_playback.py --low-pass     # warp.temporal.LOW_PASS
    .venv/bin/python tools/measure_playback.py --turn-ratio 0 --window 0.3 ...  # (the
        options of tools/measure_video.py)

(about 1 min on one core.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.app.test_playback (the scene, clip and scorer)

import numpy as np  # noqa: E402

from adaproj_edge.geometry.analytic import get_surface  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from adaproj_edge.warp.planner import compute_warp  # noqa: E402
from adaproj_edge.warp.temporal import WarpSmoother  # noqa: E402
from tests.app import test_playback as pb  # noqa: E402
from tests.app.records import feed_records  # noqa: E402
from tests.distortion import in_mask, measure  # noqa: E402
from tools.measure_video import add_temporal_args, temporal_from  # noqa: E402

SCORED = (5, 11, 17, 23)  # the frames the test scores


def guard_choice(meta: dict[str, object]) -> object:
    """What the guard kept for a warp (its meta's ``guard.choice``)."""
    guard = meta.get("guard")
    return guard.get("choice") if isinstance(guard, dict) else None


def main() -> None:
    apply_thread_policy(1)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    add_temporal_args(ap)
    args = ap.parse_args()
    temporal = temporal_from(args)
    print(temporal)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "subject.avi"
        truth = pb.write_subject_clip(path)
        rt, clock, _ = pb.runtime()
        planner = rt.warps.planner
        planner.plan_settings = replace(planner.plan_settings, temporal=temporal)
        planner.smoother = WarpSmoother(temporal)
        feed_records(rt, clock, pb.still_records())
        t0 = pb.play(rt, clock, path, pb.THRESHOLD)
        entry = rt._entry
        assert entry is not None and rt.surface is not None
        K = pb.CAL.projector.K
        surface = get_surface(pb.SCENE)
        free = measure(rt.warps.float_map(entry.warp), surface, K)
        rows = []
        for i in range(pb.N):
            clock.advance_to(t0 + round(i / pb.FPS * 1e9) + pb.MS)
            rt.tick()
            warp, step = rt.shown_warp, rt.playback.current if rt.playback else None
            assert warp is not None and step is not None and step.frame.index == i
            independent = compute_warp(rt.surface, pb.SIZE, step.content_map, rt._warp_settings())
            mask = truth[i].astype(np.float32)
            d_free = free.select(in_mask(free, mask))
            sizes = []
            for w in (warp, independent):
                d = measure(rt.warps.float_map(w), surface, K)
                assert d.folds == 0
                sizes.append(d.select(in_mask(d, mask)).size_std / d_free.size_std)
            rows.append((i, sizes[0], sizes[1], sizes[0] / sizes[1], warp.meta.get("iterations")))
            print(
                f"frame {i:2d}: / content-free: shown {sizes[0]:.3f}, independent "
                f"{sizes[1]:.3f}; shown / independent {sizes[0] / sizes[1]:.2f} "
                f"(steps {rows[-1][4]}; independent: {guard_choice(independent.meta)})",
                flush=True,
            )
    a = np.array([r[1:4] for r in rows])
    s = a[list(SCORED)]
    print(
        f"frames {SCORED}: worst / content-free: shown {s[:, 0].max():.3f}, independent "
        f"{s[:, 1].max():.3f}; worst shown / independent {s[:, 2].max():.2f}"
    )
    print(
        f"all frames: worst / content-free: shown {a[:, 0].max():.3f} (frame "
        f"{int(a[:, 0].argmax())}), independent {a[:, 1].max():.3f} (frame "
        f"{int(a[:, 1].argmax())}); shown / independent mean {a[:, 2].mean():.2f}, worst "
        f"{a[:, 2].max():.2f} (frame {int(a[:, 2].argmax())})"
    )


if __name__ == "__main__":
    main()
