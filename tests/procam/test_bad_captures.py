"""Calibration captures that cannot work, end to end (sessions simulated on true rigs,
``tests/procam/rigs.py``, replayed by ``adaproj calibrate --replay``): a single flat
wall, a dark or saturated capture, a pose where the device moved."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.board import Board
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.session.calibration_sim import SimFaults
from adaproj_edge.session.reader import read_session
from tests.procam.rigs import simulate, small


@pytest.mark.slow
def test_a_single_flat_wall_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cam = replace(Board.load("rpi5-oakd").camera, width=320, height=200)
    session, _ = simulate(tmp_path, "plane", 4, +1, 5, camera=cam)
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "one plane only" in err[0] and "wall corner" in err[0]
    assert not out.exists() and out.with_name("unit.report.json").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("fault", "message"),
    [
        (SimFaults(projector_off=True), "nothing decodes"),
        (SimFaults(exposure_scale=6.0), "saturated"),
    ],
)
def test_captures_that_cannot_work_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fault: SimFaults, message: str
) -> None:
    session, _ = simulate(tmp_path, "corner", 3, +1, 6, **small(faults=fault))
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "pose 1" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_a_pose_where_the_device_moved_is_retaken(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    faults = SimFaults(shake_pose=1)
    session, _ = simulate(tmp_path, "corner", 3, +1, 7, **small(faults=faults, photometric=True))
    s = read_session(session)
    pose2 = [p for p in s.records if getattr(p, "pose", None) == 1 and getattr(p, "index", 1) == 0]
    assert len(pose2) == 2  # pose 2's patterns began twice
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "pose 2: the device moved during the capture; hold it still" in printed
    assert out.exists()
    # the surface's colour measured after pose 1 (the replay measures as the session
    # did), kept with the distance to that wall (the corner, 1.2-2.2 m away): it holds
    # on that surface, not on one 10 % nearer
    assert "pose 1: the surface's colour and the room's light measured" in printed
    measured = Measured.load(out.with_name("unit.photometric.npz"))
    white = measured.response.white()[measured.response.valid]
    assert white.size > 100 and np.all(white > 0)
    dist = measured.distance_m
    assert 1.2 < np.nanmin(dist) and np.nanmax(dist) < 2.2
    projector = Projector(Calibration.load(out).projector.K, 1280, 800)
    h, w = dist.shape
    v, u = np.mgrid[0:h, 0:w]
    rays = projector.rays(np.stack([u * 1279 / (w - 1), v * 799 / (h - 1)], -1))
    unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    assert measured.holds_on(Surface(unit * dist[..., None], projector)) is None
    nearer = measured.holds_on(Surface(0.9 * unit * dist[..., None], projector))
    assert nearer is not None and "moved" in nearer
