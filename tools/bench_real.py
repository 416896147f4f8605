#!/usr/bin/env python3
"""Real depth frames through the device path: what a user's first rooms would show.

Every frame of ``tests/fixtures/real/`` (recorded by others with real structured-light
sensors; provenance in the README there) with the projector aimed at each of its
regions goes through the device (the runtime on a virtual clock: ``SurfaceSource`` ->
``WarpSource.pose`` -> ``content_aware``, default settings, the built-in poster, "up"
from gravity estimated on the frame's floor), and ``adaproj warp`` runs on the same
surface. The figures are
computed from the raw points alone (``tests/realframes.py`` says how): valid depth in
the region, the share of the frame shown, upright error, angle distortion and size
inconsistency on the region's plane and the plane fit's spread there (what the angle
figure reads between two robust fits to halves of the region's raw points: below it
the figure cannot tell the picture's distortion from the fit's), content shown across a
depth jump (bridging a silhouette / where no object is).

Prints a table, then one line per region against the aims (nothing projected with
>= 30 % valid depth; upright within 2 deg on walls, 5 deg on floors; planar regions
angle <= 0.02 and size <= 0.02, and the line the measure can verify: angle <= 0.02 +
the region's spread, size <= 0.02; <= 1 % shown across a jump; ``adaproj warp`` and the
runtime agree), then a summary. ``up_spr`` is the upright figure's own spread (degrees:
how far it moves when read on planes fitted to halves of the same raw points); an
upright figure within it of the line cannot be told from the fit's error. Always exits
0: it measures, the tests assert.

    .venv/bin/python tools/bench_real.py [--frame NAME] [--no-render]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.threads import apply_thread_policy
from tests.realframes import FIXTURES, Figures, Region, figures, load_frames

MIN_VALID_PCT = 30.0
UPRIGHT_DEG = {"wall": 2.0, "floor": 5.0}
MAX_ANGLE = 0.02
MAX_SIZE = 0.02
MAX_JUMP_PCT = 1.0


def verdicts(region: Region, fig: Figures) -> list[tuple[str, bool | None]]:
    """Each aim of the region: (what, met); None where it does not apply."""
    needs_picture = fig.valid_pct >= MIN_VALID_PCT
    out: list[tuple[str, bool | None]] = [
        ("projected", fig.projected if needs_picture else None),
        ("no WarpError shown", not fig.warp_failed),
    ]
    measured = fig.projected and not math.isnan(fig.upright_deg)
    limit = UPRIGHT_DEG.get(fig.upright_rule, 2.0)
    out.append((f"upright<={limit:g}deg", fig.upright_deg <= limit if measured else None))
    out.append(("not upside down", fig.upright_deg < 90.0 if measured else None))
    planar = region.planar and measured
    out.append((f"angle<={MAX_ANGLE:g}", fig.angle <= MAX_ANGLE if planar else None))
    out.append((f"size<={MAX_SIZE:g}", fig.size <= MAX_SIZE if planar else None))
    out.append(
        (f"angle<={MAX_ANGLE:g}+spread", fig.angle <= MAX_ANGLE + fig.spread if planar else None)
    )
    jump = fig.projected and not math.isnan(fig.jump_pct)
    out.append((f"jump<={MAX_JUMP_PCT:g}%", fig.jump_pct <= MAX_JUMP_PCT if jump else None))
    out.append(("warp agrees", bool(fig.warp_ok) == fig.projected and fig.projected))
    return out


def _f(x: float, fmt: str) -> str:
    return "-" if math.isnan(x) else format(x, fmt)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frame", action="append", help="only these frames (by name)")
    ap.add_argument(
        "--no-render",
        action="store_true",
        help="adaproj warp without drawing its frame (as the tests run it; faster)",
    )
    args = ap.parse_args(argv)
    apply_thread_policy()
    frames = [f for f in load_frames(FIXTURES) if not args.frame or f.name in args.frame]
    head = (
        f"{'frame':15} {'region':16} {'kind':12} {'valid%':>6} {'shown%':>6} {'up_deg':>6} "
        f"{'up_spr':>6} "
        f"{'angle':>6} {'size':>6} {'spread':>6} {'bridge%':>7} {'noobj%':>6} {'warp':>5}  device"
    )
    print(head)
    print("-" * len(head))
    rows = []
    for frame in frames:
        for region in frame.regions:
            fig, _ = figures(frame, region, render=not args.no_render, spreads=True)
            rows.append((frame, region, fig))
            device = f"shows {fig.kind}" if fig.projected else f"NOTHING: {fig.error}"
            print(
                f"{frame.name:15} {region.name:16} {region.kind:12} {fig.valid_pct:6.1f} "
                f"{fig.shown_pct:6.1f} {_f(fig.upright_deg, '6.1f')} "
                f"{_f(fig.upright_spread, '6.1f')} {_f(fig.angle, '6.3f')} "
                f"{_f(fig.size, '6.3f')} {_f(fig.spread, '6.3f')} {_f(fig.bridging_pct, '7.2f')} "
                f"{_f(fig.no_object_pct, '6.2f')} {'ok' if fig.warp_ok else 'FAIL':>5}  {device}",
                flush=True,
            )
    print()
    failed: dict[str, int] = {}
    for frame, region, fig in rows:
        marks = []
        for what, met in verdicts(region, fig):
            if met is None:
                continue
            marks.append(("" if met else "FAIL ") + what)
            if not met:
                failed[what] = failed.get(what, 0) + 1
        rule = f", up measured on a {fig.upright_rule}" if fig.upright_rule else ""
        print(f"{frame.name}/{region.name} ({region.kind}{rule}): " + "; ".join(marks))
    print()
    n = len(rows)
    dark = sum(1 for _, _, f in rows if not f.projected and f.valid_pct >= MIN_VALID_PCT)
    disagree = sum(1 for _, _, f in rows if bool(f.warp_ok) != f.projected)
    print(
        f"{n} regions on {len(frames)} real frames: {dark} with nothing projected, "
        f"{disagree} where adaproj warp and the runtime disagree"
    )
    if failed:
        print("aims missed (regions): " + ", ".join(f"{k} {v}" for k, v in sorted(failed.items())))
    else:
        print("every aim met")
    return 0


if __name__ == "__main__":
    sys.exit(main())
