"""Calibration sessions simulated on true rigs off the nominal one, made here
independently of the simulator's helpers: shared by the accuracy and bad-capture tests."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.hal.board import Board
from adaproj_edge.session.calibration_sim import CalibrationSimSettings, simulate_calibration
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


def simulate(
    tmp: Path, scene: str, poses: int, sign: float, seed: int, **kw: object
) -> tuple[Path, Calibration]:
    nominal = Board.load("rpi5-oakd").calibration()
    truth = true_rig(nominal, sign, seed)
    path = tmp / f"{scene}.mcap"
    settings = replace(CalibrationSimSettings(poses=poses, seed=seed), **kw)  # type: ignore[arg-type]
    simulate_calibration(Scene.load(scene), truth, nominal, path, settings)
    return path, truth


def small(**kw: object) -> dict[str, object]:
    return {"camera": replace(Board.load("rpi5-oakd").camera, width=256, height=160), **kw}
