"""The figures of issue 11, end to end: calibration sessions simulated on true rigs
off the nominal one (``tests/procam/rigs.py``), solved by ``adaproj calibrate --replay``,
compared with the truth. The bad input: ``tests/procam/test_bad_captures.py``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from adaproj_edge.cli import main
from adaproj_edge.geometry.calibration import Calibration
from tests.procam.rigs import simulate


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
