#!/usr/bin/env python3
"""Time of the display's fold guard (``render/folds.py``), against the guard of another
revision, same run, alternately, one core.

On the per-pixel maps of surfaces whose display folds at a curved crease (a cylinder on
a floor: ``tools/stress_warp.py`` seed 1 case 128, seed 2 case 39, conformal mode) and
of the named ``cylinder-floor`` at 20x20 (nothing folds): the folded pixels, the pixels
that took part of their value from the smoothing, and the best of ``--repeat`` times of
:func:`~adaproj_edge.render.folds.guard` for this tree and (``--baseline REV``) the
module as it is at git revision ``REV`` (loaded from ``git show``).

    .venv/bin/python tools/bench_fold_guard.py [--baseline bd7eab0] [--repeat 3]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.render import folds
from adaproj_edge.render.maps import PixelWeights
from adaproj_edge.threads import apply_thread_policy
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid
from tests.warp.random_surfaces import _warp, draw_case

ROOT = Path(__file__).resolve().parents[1]


def module_at(rev: str) -> ModuleType:
    """``adaproj_edge/render/folds.py`` as it is at git revision ``rev``."""
    text = subprocess.run(
        ["git", "show", f"{rev}:adaproj_edge/render/folds.py"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "folds_baseline.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("folds_baseline", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def maps() -> Iterator[tuple[str, Any, Any]]:
    """(label, surface-based map, perspective-correct map) of each input."""
    warps = []
    for seed, index in ((1, 128), (2, 39)):
        sim, warp, _ = _warp(draw_case(seed, index), "conformal", "ours", None)
        warps.append((f"seed {seed} case {index}", sim, warp))
    sim = simulate_surface("cylinder-floor")
    settings = WarpSettings(mode="conformal", grid=Grid(20, 20))
    warps.append(("cylinder-floor 20x20", sim, compute_warp(sim, (640, 360), None, settings)))
    for label, sim, warp in warps:
        w = PixelWeights.build(warp.grid_uv, warp.depth, warp.projector, sim)
        assert w.fallback is not None
        verts = np.asarray(warp.image_xy, np.float32).reshape(-1, 2)
        yield (
            label,
            w._gather(verts, w.corners, w.weights),
            w._gather(verts, w.corners[:3], w.fallback),
        )


def main() -> None:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--baseline", default="", help="git revision to compare with")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    mods = [("this", folds)] + (
        [(args.baseline, module_at(args.baseline))] if args.baseline else []
    )
    for label, raw, plain in maps():
        best: dict[str, float] = {}
        count = 0
        for _ in range(args.repeat):
            for name, mod in mods:
                t0 = time.perf_counter()
                _, n = mod.guard(raw, plain)
                dt = time.perf_counter() - t0
                best[name] = min(best.get(name, np.inf), dt)
                count = n if mod is folds else count
        times = "  ".join(f"{name} {1000 * t:6.0f} ms" for name, t in best.items())
        folded = int(folds.fold_mask(raw).sum())
        print(f"{label:22s} folded {folded:5d} px, smoothed {count:7d} px  {times}", flush=True)


if __name__ == "__main__":
    main()
