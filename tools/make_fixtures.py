#!/usr/bin/env python3
"""Regenerate the committed session fixtures (tests/fixtures/sessions/) and the
built-in recording ``adaproj replay`` plays (``adaproj_edge/data/cylinder.mcap``, a
copy of the cylinder fixture).

    .venv/bin/python tools/make_fixtures.py            # sessions
    .venv/bin/python tools/make_fixtures.py --golden   # and the golden replay outputs

The depth frames are drawn from the OAK-D's noise model (the simulator's default:
depth steps, flying pixels, holes, occlusion bands), as a real sensor gives them.
Every fixture has a fixed seed, so running this again gives the same files.
Regenerating is a deliberate act: the tests never write them.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.mesh_surface import ply_bytes, uv_sphere
from adaproj_edge.resources import default_session
from adaproj_edge.session.digest import tracking_digest
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session
from adaproj_edge.threads import apply_thread_policy

ROOT = Path(__file__).resolve().parents[1]

OUT = ROOT / "tests" / "fixtures" / "sessions"
SECONDS = 3.0
DEPTH_FPS = 5.0
# name -> (surface, seed)
FIXTURES = {
    "corner": ("corner", 11),
    "cylinder": ("cylinder-convex", 12),
    "sphere": ("sphere-convex", 13),
    "mesh-sphere": ("mesh-sphere.ply", 14),
}
BUILT_IN = "cylinder"  # the fixture adaproj replay plays by default
GOLDEN = OUT / "golden.json"
GRID = (21, 21)


def make_sessions() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    mesh = uv_sphere((0.05, 0.0, 1.9), 0.5, n_lat=16, n_lon=32)
    (OUT / "mesh-sphere.ply").write_bytes(ply_bytes(mesh))
    for name, (surface, seed) in FIXTURES.items():
        spec = str(OUT / surface) if surface.endswith(".ply") else surface
        settings = SimulationSettings(seconds=SECONDS, depth_fps=DEPTH_FPS, seed=seed)
        n = simulate_session(
            Scene.load(spec), OUT / f"{name}.mcap", Calibration.default(), settings
        )
        size = (OUT / f"{name}.mcap").stat().st_size
        print(f"{name}.mcap: {n} records, {size / 1e6:.2f} MB")
    built_in = default_session()
    tmp = built_in.with_name(built_in.name + ".part")
    shutil.copyfile(OUT / f"{BUILT_IN}.mcap", tmp)
    tmp.replace(built_in)
    print(f"{built_in.relative_to(ROOT)}: a copy of {BUILT_IN}.mcap")


def make_golden() -> None:
    golden = {name: tracking_digest(OUT / f"{name}.mcap", GRID) for name in FIXTURES}
    GOLDEN.write_text(json.dumps(golden, indent=1) + "\n")
    print(f"wrote {GOLDEN}")


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--golden", action="store_true", help="also rewrite the golden outputs")
    ap.add_argument("--golden-only", action="store_true", help="only rewrite the golden outputs")
    args = ap.parse_args()
    if not args.golden_only:
        make_sessions()
    if args.golden or args.golden_only:
        make_golden()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
