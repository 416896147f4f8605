"""The figures of issue 11, end to end: calibration sessions simulated on true rigs
off the nominal one (made here, independently of the simulator's helpers), solved by
``adaproj calibrate --replay``, compared with the truth; and the bad input."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from adaproj_edge.cli import main
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.board import Board
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.session.calibration_sim import (
    CalibrationSimSettings,
    SimFaults,
    simulate_calibration,
)
from adaproj_edge.session.reader import read_session
from adaproj_edge.session.simulator import Scene


def true_rig(nominal: Calibration, sign: float, seed: int) -> Calibration:
    """Focal +-3 %, principal point (+-15, +300) px, T_P_D 2 deg and 15 mm, R_P_I 5 deg."""
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(3, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    K = nominal.projector.K.copy()
    K[0, 0] *= 1 + 0.03 * sign
    K[1, 1] *= 1 + 0.03 * sign
    K[0, 2] += 15 * sign
    K[1, 2] += 300
    T = nominal.T_P_D.copy()
    T[:3, :3] = Rotation.from_rotvec(axes[0] * np.radians(2)).as_matrix() @ T[:3, :3]
    T[:3, 3] += axes[1] * 0.015
    R = Rotation.from_rotvec(axes[2] * np.radians(5)).as_matrix() @ nominal.R_P_I
    return Calibration(Projector(K, 1280, 800), nominal.depth, T, R)


def errors(got: Calibration, truth: Calibration) -> dict[str, float]:
    Kg, Kt = got.projector.K, truth.projector.K
    return {
        "focal": max(abs(Kg[0, 0] / Kt[0, 0] - 1), abs(Kg[1, 1] / Kt[1, 1] - 1)),
        "principal": float(np.hypot(Kg[0, 2] - Kt[0, 2], Kg[1, 2] - Kt[1, 2])),
        "rotation": np.degrees(
            Rotation.from_matrix(got.T_P_D[:3, :3] @ truth.T_P_D[:3, :3].T).magnitude()
        ),
        "translation": 1000 * float(np.linalg.norm(got.T_P_D[:3, 3] - truth.T_P_D[:3, 3])),
        "imu": np.degrees(Rotation.from_matrix(got.R_P_I @ truth.R_P_I.T).magnitude()),
    }


def simulate(
    tmp: Path, scene: str, poses: int, sign: float, seed: int, **kw: object
) -> tuple[Path, Calibration]:
    nominal = Board.load("rpi5-oakd").calibration()
    truth = true_rig(nominal, sign, seed)
    path = tmp / f"{scene}.mcap"
    settings = replace(CalibrationSimSettings(poses=poses, seed=seed), **kw)  # type: ignore[arg-type]
    simulate_calibration(Scene.load(scene), truth, nominal, path, settings)
    return path, truth


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scene", "poses", "sign", "seed"),
    [("corner", 4, +1, 1), ("corner", 6, -1, 2), ("wall-floor", 5, +1, 4)],
)
def test_recovers_the_true_rig(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    scene: str,
    poses: int,
    sign: float,
    seed: int,
) -> None:
    session, truth = simulate(tmp_path, scene, poses, sign, seed)
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "good: reprojection RMS" in printed and f"wrote {out}" in printed
    e = errors(Calibration.load(out), truth)
    assert e["focal"] < 0.003 and e["principal"] < 2.0
    assert e["rotation"] < 0.1 and e["translation"] < 2.0 and e["imu"] < 0.5
    report = json.loads(out.with_name("unit.report.json").read_text())
    assert report["rms_px"] < 0.5 and report["verdict"] == "good"


@pytest.mark.slow
def test_a_single_flat_wall_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cam = replace(Board.load("rpi5-oakd").camera, width=320, height=200)
    session, _ = simulate(tmp_path, "plane", 4, +1, 5, camera=cam)
    out = tmp_path / "unit.toml"
    assert main(["calibrate", "--replay", str(session), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "one plane only" in err[0] and "wall corner" in err[0]
    assert not out.exists() and out.with_name("unit.report.json").exists()


def small(**kw: object) -> dict[str, object]:
    return {"camera": replace(Board.load("rpi5-oakd").camera, width=256, height=160), **kw}


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
