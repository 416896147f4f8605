#!/usr/bin/env python3
"""Regenerate the committed calibration session (tests/fixtures/calibration/).

    .venv/bin/python tools/make_calibration_fixture.py                 # session + golden
    .venv/bin/python tools/make_calibration_fixture.py --golden-only   # golden only

A small rig keeps the file small: a 256x160 camera, 320x200 depth, 3 poses in front
of a wall corner; the true rig is off the nominal one as in the issue (focal +3 %,
principal point (+15, +300) px, T_P_D 2 deg and 15 mm, R_P_I 5 deg). Fixed seed:
running this again gives the same file. Regenerating is a deliberate act: the tests
never write these files.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.geometry.calibration import DepthCameraModel  # noqa: E402
from adaproj_edge.hal.board import Board  # noqa: E402
from adaproj_edge.session.calibration_sim import (  # noqa: E402
    CalibrationSimSettings,
    perturbed_rig,
    simulate_calibration,
)
from adaproj_edge.session.simulator import Scene  # noqa: E402

OUT = ROOT / "tests" / "fixtures" / "calibration"
SESSION = OUT / "corner.mcap"
GOLDEN = OUT / "golden.json"
SEED = 31


def make_session() -> None:
    board = Board.load("rpi5-oakd")
    nominal = board.calibration()
    d = nominal.depth
    small = DepthCameraModel(d.intrinsics_at(320, 200), 320, 200, d.baseline_m)
    nominal = nominal.with_depth(small)
    truth = perturbed_rig(nominal, seed=SEED)
    settings = CalibrationSimSettings(
        poses=3, seed=SEED, camera=replace(board.camera, width=256, height=160)
    )
    OUT.mkdir(parents=True, exist_ok=True)
    n = simulate_calibration(Scene.load("corner"), truth, nominal, SESSION, settings)
    print(f"{SESSION.name}: {n} records, {SESSION.stat().st_size / 1e6:.2f} MB")


def make_golden() -> None:
    from tests.procam.golden import replay_outputs

    GOLDEN.write_text(json.dumps(replay_outputs(SESSION), indent=1) + "\n")
    print(f"wrote {GOLDEN}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--golden-only",
        action="store_true",
        help="keep the session, rewrite its golden outputs (after a deliberate change)",
    )
    if not ap.parse_args().golden_only:
        make_session()
    make_golden()
    return 0


if __name__ == "__main__":
    sys.exit(main())
