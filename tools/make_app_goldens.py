#!/usr/bin/env python3
"""Regenerate the device runtime's golden replay outputs (tests/fixtures/app/).

    .venv/bin/python tools/make_app_goldens.py            # goldens of every session
    .venv/bin/python tools/make_app_goldens.py --session  # first the fault session

The fault session (``faults.mcap``) is a simulated cylinder session with faults put
in: depth dropouts, a hole, a camera that stops sending for 0.6 s, a surface out of
range, and (in its metadata, raised by the replay) IMU read errors. Everything is
seeded, so the same command gives the same files. The tests never write these.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import FAULTS_KEY, ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.geometry.calibration import Calibration  # noqa: E402
from adaproj_edge.hal.depth import DepthFrame  # noqa: E402
from adaproj_edge.session import schemas  # noqa: E402
from adaproj_edge.session.simulator import T0_NS, Scene, SimulationSettings, simulate  # noqa: E402
from adaproj_edge.session.writer import SessionWriter  # noqa: E402
from tests.app.golden import FAULTS_SESSION, GOLDEN, golden_view, session_paths  # noqa: E402

# (kind, start s, end s) from the start of the session
DEPTH_FAULTS = [
    ("dropout", 1.5, 1.8),
    ("hole", 1.8, 2.1),
    ("disconnect", 2.4, 3.0),
    ("range", 3.4, 3.7),
]
IMU_ERRORS = [{"kind": "imu", "start_s": 4.0, "end_s": 4.4}]


def _faulty(frame: DepthFrame) -> DepthFrame | None:
    t = (frame.sensor_ns - T0_NS) / 1e9
    for kind, a, b in DEPTH_FAULTS:
        if not a <= t < b:
            continue
        d = frame.depth_mm.copy()
        if kind == "dropout":
            d[:] = 0
        elif kind == "hole":
            d[120:260, 240:420] = 0
        elif kind == "disconnect":
            return None
        elif kind == "range":
            d[d > 0] = 9000
        return replace(frame, depth_mm=d)
    return frame


def make_fault_session() -> None:
    scene = Scene.load("cylinder-convex")
    cal = Calibration.default()
    settings = SimulationSettings(seconds=5.0, depth_fps=5.0, seed=21, presses=(0.2,))
    recs = simulate(scene, cal, settings)
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        "depth_faults": json.dumps(DEPTH_FAULTS),
        FAULTS_KEY: json.dumps(IMU_ERRORS),
    }
    FAULTS_SESSION.parent.mkdir(parents=True, exist_ok=True)
    tmp = FAULTS_SESSION.with_name(FAULTS_SESSION.name + ".part")
    with SessionWriter(tmp, cal, meta, T0_NS) as w:
        w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, scene.spec, T0_NS)
        for r in recs:
            if isinstance(r, DepthFrame):
                r2 = _faulty(r)
                if r2 is None:
                    continue
                r = r2
            w.write(r)
    os.replace(tmp, FAULTS_SESSION)
    print(f"wrote {FAULTS_SESSION} ({FAULTS_SESSION.stat().st_size} bytes)")


def make_goldens() -> None:
    out = {}
    for name, path in session_paths().items():
        s = replay_session(path, None, ReplayOptions(score=False))
        out[name] = golden_view(s)
        print(f"{name}: {s['counters']}")
    GOLDEN.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {GOLDEN}")


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--session", action="store_true", help="regenerate faults.mcap first")
    args = ap.parse_args()
    np.seterr(all="ignore")
    if args.session or not FAULTS_SESSION.exists():
        make_fault_session()
    make_goldens()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
