"""The committed calibration session replays to its golden outputs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from adaproj_edge.procam.report import judge
from adaproj_edge.procam.result import CalibrationResult
from adaproj_edge.session.reader import read_session
from tests.procam.golden import FIXTURE, GOLDEN


def test_the_fixture_is_small_and_complete() -> None:
    assert FIXTURE.stat().st_size < 5_000_000
    s = read_session(FIXTURE)
    assert not s.truncated and len(s.depth) == 9 and s.depth[0].depth_mm.shape == (200, 320)
    assert s.metadata["session"]["kind"] == "calibration"
    assert {"truth-calibration.json", "camera.json", "capture.json"} <= set(s.attachments)


def test_replay_matches_the_golden(fixture_result: tuple[CalibrationResult, list[str]]) -> None:
    result, transcript = fixture_result
    golden = json.loads(GOLDEN.read_text())
    # decisions: exactly
    assert transcript == golden["transcript"]
    assert judge(result).level == golden["verdict"]
    assert [[p.decoded.cell_x, p.decoded.cell_y] for p in result.run.poses] == golden["cells"]
    assert [len(p.normals) for p in result.run.poses] == golden["planes"]
    assert result.imu.measured == golden["imu_measured"]
    # numbers: within what another CPU's rounding can move them
    got_pairs = [len(p.pairs) for p in result.run.poses]
    assert got_pairs == pytest.approx(golden["pairs_per_pose"], abs=3)
    assert int(result.projector.inliers.sum()) == pytest.approx(golden["inliers"], abs=5)
    assert result.projector.rms_px == pytest.approx(golden["rms_px"], abs=0.01)
    cal = result.calibration
    assert np.allclose(cal.projector.K, golden["K"], atol=0.3)
    T = np.asarray(golden["T_P_D"])
    assert np.linalg.norm(cal.T_P_D[:3, 3] - T[:3, 3]) < 2e-4
    dR = Rotation.from_matrix(cal.T_P_D[:3, :3] @ T[:3, :3].T).magnitude()
    dI = Rotation.from_matrix(cal.R_P_I @ np.asarray(golden["R_P_I"]).T).magnitude()
    assert np.degrees(dR) < 0.01 and np.degrees(dI) < 0.05
