#!/usr/bin/env python3
"""The content-aware video warp's quality per frame, on the clips of
``tests/warp/test_temporal.py`` (the same fixtures and scorer, analytic ground truth).

For each clip (``--motions``: right, stops, fast, turns) plays the frames through
a planner made as the device's (coarse to fine for stills, warm starts) with the
temporal settings given, beside an independent full solve of every frame, and prints:
the subject's size inconsistency over the independent solve's (mean, worst and its
frame), over the content-free warp's (worst), the RMS vertex acceleration against the
independent solves', and the steps per frame.

    .venv/bin/python tools/measure_video.py             # the device's defaults
    .venv/bin/python tools/measure_video.py --line-fit  # warp.temporal.LINE_FIT
    .venv/bin/python tools/measure_video.py --low-pass  # warp.temporal.LOW_PASS
    .venv/bin/python tools/measure_video.py --turn-ratio 0 --window 0.3  # ...

(slow: about 30 s a clip on one core; the saliency model runs on every 4th frame.)
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.warp.test_temporal (the clips and scorer)

import numpy as np  # noqa: E402

from adaproj_edge.content.model import SaliencyModel  # noqa: E402
from adaproj_edge.content.temporal import TemporalContentMap  # noqa: E402
from adaproj_edge.geometry.analytic import simulate_surface  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402
from adaproj_edge.warp.planner import compute_warp  # noqa: E402
from adaproj_edge.warp.temporal import LINE_FIT, LOW_PASS, TemporalWarpSettings  # noqa: E402
from tests.warp import test_temporal as clips  # noqa: E402

PRESETS = {"line_fit": LINE_FIT, "low_pass": LOW_PASS}


def add_temporal_args(ap: argparse.ArgumentParser) -> None:
    """The temporal settings' options (each unset one: the device's default)."""
    ap.add_argument("--steps", type=int)
    ap.add_argument("--band", type=float)
    ap.add_argument("--time-constant", type=float, help="s")
    ap.add_argument("--window", type=float, help="s (0: the low-pass filter)")
    ap.add_argument(
        "--full-grid", action=argparse.BooleanOptionalAction, help="not the stills' grid"
    )
    ap.add_argument("--turn-ratio", type=float, help="0: no turns")
    ap.add_argument("--turn-window", type=float, help="s")
    ap.add_argument("--residual-gain", type=float)
    ap.add_argument("--line-fit", action="store_true", help="start from warp.temporal.LINE_FIT")
    ap.add_argument("--low-pass", action="store_true", help="start from warp.temporal.LOW_PASS")


def temporal_from(args: argparse.Namespace) -> TemporalWarpSettings:
    """The temporal settings the options ask for: a preset (or the defaults) with the
    options given."""
    base = TemporalWarpSettings()
    for name, preset in PRESETS.items():
        if getattr(args, name):
            base = preset
    given = {
        "steps": args.steps,
        "band": args.band,
        "time_constant_s": args.time_constant,
        "window_s": args.window,
        "full_grid": args.full_grid,
        "turn_ratio": args.turn_ratio,
        "turn_window_s": args.turn_window,
        "residual_gain": args.residual_gain,
    }
    return replace(base, **{k: v for k, v in given.items() if v is not None})


def main() -> None:
    apply_thread_policy(1)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--motions", default="right,stops,fast,turns")
    add_temporal_args(ap)
    args = ap.parse_args()
    temporal = temporal_from(args)
    plan = replace(clips.DEVICE_PLAN, temporal=temporal)
    motions = clips.MOTIONS
    surface = simulate_surface(clips.SURFACE)
    print(f"{temporal}")
    for name in args.motions.split(","):
        device = clips.planner(plan)
        cf = device.content_free(surface, clips.SIZE, clips.SETTINGS)
        maps = TemporalContentMap(clips.SIZE, SaliencyModel())
        p = clips.Played(cf, [], [], [])
        for i in range(clips.FRAMES):
            image, mask = motions[name](i)
            cmap = maps.update(image)
            p.masks.append(mask)
            p.shown.append(device.refine(surface, cmap, clips.SETTINGS, cf, frame_dt=1 / clips.FPS))
            p.independent.append(compute_warp(surface, clips.SIZE, cmap, clips.SETTINGS))
        full, free = clips.size_ratios(p)
        ours, indep = clips.acceleration(p.shown), clips.acceleration(p.independent)
        steps = "".join(str(w.meta.get("iterations", "-")) for w in p.shown)
        print(
            f"{name}: size / independent full solve: mean {full.mean():.2f}, worst "
            f"{full.max():.2f} (frame {int(full.argmax())}); / content-free: worst "
            f"{free.max():.2f}; acceleration {ours:.3f} vs {indep:.3f} px/frame^2 "
            f"({indep / ours:.1f}x lower); steps {steps}"
        )
        print(f"  per frame / independent: {np.round(full, 2).tolist()}", flush=True)


if __name__ == "__main__":
    main()
