"""The replay outputs of the committed calibration session, compared field by field
with ``tests/fixtures/calibration/golden.json`` (written only by
``tools/make_calibration_fixture.py``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from adaproj_edge.procam.report import judge
from adaproj_edge.procam.result import CalibrationResult, solve_capture
from adaproj_edge.procam.session_devices import recorded_capture, run_recorded
from adaproj_edge.session.codec import Record

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "calibration" / "corner.mcap"
GOLDEN = FIXTURE.with_name("golden.json")


class Transcript:
    """What the procedure says, in order (its decisions)."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def say(self, event: str, message: str) -> None:
        self.lines.append(f"{event}: {message}")

    def record(self, rec: Record) -> None:
        pass


def replay(path: Path = FIXTURE) -> tuple[CalibrationResult, list[str]]:
    """``adaproj calibrate --replay`` of ``path``, without writing: result, transcript."""
    rc = recorded_capture(path)
    talk = Transcript()
    run = run_recorded(rc, talk)
    return solve_capture(run, rc.nominal), talk.lines


def replay_outputs(path: Path = FIXTURE) -> dict[str, Any]:
    """The decisions (exactly) and the numbers (with tolerances) of a replay."""
    result, lines = replay(path)
    cal = result.calibration
    sol = result.projector
    return {
        "transcript": lines,
        "verdict": judge(result).level,
        "pairs_per_pose": [len(p.pairs) for p in result.run.poses],
        "cells": [[p.decoded.cell_x, p.decoded.cell_y] for p in result.run.poses],
        "planes": [len(p.normals) for p in result.run.poses],
        "inliers": int(sol.inliers.sum()),
        "rms_px": sol.rms_px,
        "K": cal.projector.K.tolist(),
        "T_P_D": cal.T_P_D.tolist(),
        "R_P_I": cal.R_P_I.tolist(),
        "imu_measured": result.imu.measured,
    }
