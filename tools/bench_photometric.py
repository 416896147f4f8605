#!/usr/bin/env python3
"""The geometric photometry's figures: flat mid-grey content on a wall corner and on
concave domes, as a viewer off to the side sees it, plain and compensated; and what
the gain costs, per pose and per displayed frame, at 1280x800 on one core.

For each surface (``--surfaces``; the built-in ``corner``, a 90-degree wall corner, and
the concave dome ``sphere-concave`` and dish ``bowl``): the content warped as on the
device (``--mode``), the gain map made from the surface the projector measures, and
what the viewer at ``--viewer`` (default 0.8 m to the right of the projector) sees,
from the test's own ray cast of the analytic surface
(``tests/render/photometry_oracle.py``, the figures ``tests/render/test_photometry.py``
asserts at 640x400): max/min of the brightness over the picture (goal <= 1.10), mean
after / before (goal >= 0.7) and the largest change of brightness per degree of the
viewer's visual angle over a 1-degree baseline (goal: under the cited 2 %), before and
after. Beside them the module's own prediction and the gain's own largest change per
degree (it jumps at a crease on purpose: the brightness does not).

The cost: CPU time (``time.process_time``) of making the gain map (once per pose) and
of applying it to a 1280x800 BGR frame (every displayed frame), median and 95th
percentile of ``--frames`` runs.

    .venv/bin/python tools/bench_photometric.py [--surfaces corner,sphere-concave,bowl]
        [--scale 2] [--frames 300]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _gain_gradient(light: object, deg_per_px: float) -> float:
    """The gain's own largest relative change per degree (forward differences)."""
    import numpy as np

    lg = np.log(np.asarray(light, dtype=np.float64))
    g = np.hypot(np.diff(lg, axis=1)[:-1, :], np.diff(lg, axis=0)[:, :-1])
    return math.expm1(float(g.max()) / deg_per_px)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--surfaces", default="corner,sphere-concave,bowl")
    p.add_argument("--mode", default="content", choices=("content", "conformal"))
    p.add_argument(
        "--scale", type=int, default=None, help="the gain map's 1/scale (default: the module's)"
    )
    p.add_argument("--viewer", default="0.8,-0.15,0.1", help="X,Y,Z metres, projector frame")
    p.add_argument("--frames", type=int, default=300)
    args = p.parse_args()

    from adaproj_edge.threads import apply_thread_policy

    apply_thread_policy()

    import numpy as np

    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.geometry.projector import Projector
    from adaproj_edge.render.photometry import (
        PhotometrySettings,
        apply_gain,
        degrees_per_pixel,
        gain_map,
    )
    from tests.render.photometry_oracle import grey_case

    settings = PhotometrySettings() if args.scale is None else PhotometrySettings(scale=args.scale)
    eye = tuple(float(x) for x in args.viewer.split(","))
    assert len(eye) == 3
    projector = Projector.default()
    print(
        f"{projector.width}x{projector.height}, viewer at {eye} m, gain at 1/{settings.scale}, "
        f"mode {args.mode}, gradient bound {settings.gradient_per_deg:.0%}/deg "
        f"(projector angles), evenness {settings.evenness}, budget {settings.budget}"
    )
    head = (
        f"{'surface':16} {'max/min before':>14} {'after':>7} {'mean after/before':>17} "
        f"{'grad/deg before':>15} {'after':>7} | {'predicted':>9} {'gain grad/deg':>13}"
    )
    print(head)
    for name in args.surfaces.split(","):
        case = grey_case(name, projector, eye, settings, mode=args.mode)
        b, a, gm = case.before, case.after, case.gain
        deg = degrees_per_pixel(projector) * projector.width / gm.light.shape[1]
        print(
            f"{name:16} {b.ratio():14.3f} {a.ratio():7.3f} {a.mean() / b.mean():17.3f} "
            f"{b.gradient_per_deg():15.4f} {a.gradient_per_deg():7.4f} | "
            f"{gm.ratio_after:9.3f} {_gain_gradient(gm.light, deg):13.3f}"
            + (f"  ({gm.reason})" if gm.reason else "")
        )

    surface = simulate_surface("corner", projector)
    made = []
    for _ in range(5):
        t = time.process_time()
        gm = gain_map(surface, None, settings)
        gm.pixels(3)
        made.append(time.process_time() - t)
    frame = np.full((projector.height, projector.width, 3), 128, np.uint8)
    out = np.empty_like(frame)
    apply_gain(frame, gm, out)
    times = []
    for _ in range(args.frames):
        t = time.process_time()
        apply_gain(frame, gm, out)
        times.append(time.process_time() - t)
    ms = np.array(times) * 1e3
    print(
        f"cost: gain map per pose median {np.median(made) * 1e3:.0f} ms (corner, 5 runs); "
        f"per displayed frame median {np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms "
        f"({args.frames} frames, 1280x800 BGR, one core)"
    )


if __name__ == "__main__":
    main()
