"""The verdict, the report and the files written (atomic, never over a better one)."""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.procam.outputs import existing_quality, is_worse, report_paths, write_outputs
from adaproj_edge.procam.report import Verdict, changes, judge, report_dict, report_picture
from adaproj_edge.procam.result import CalibrationResult
from adaproj_edge.session.reader import read_calibration
from adaproj_edge.session.simulator import truth_rig
from tests.procam.golden import FIXTURE

Fixture = tuple[CalibrationResult, list[str]]


def test_the_fixture_solves_close_to_its_true_rig(fixture_result: Fixture) -> None:
    """Even from 3 poses and a 256x160 camera (the figures of the issue come from
    tests/procam/test_accuracy.py)."""
    result, _ = fixture_result
    from adaproj_edge.session.reader import read_session

    truth = truth_rig(read_session(FIXTURE).attachments)
    assert truth is not None
    d = changes(result.calibration, truth)
    assert abs(d["focal_pct"]) < 0.3 and d["principal_px"] < 2.0
    assert d["T_P_D_deg"] < 0.1 and d["T_P_D_mm"] < 2.0
    # three small turns seen by a 320x200 depth image: R_P_I is loose, and says so
    assert result.imu.measured and d["R_P_I_deg"] < 3 * result.imu.sigma_deg


def test_report_and_picture(fixture_result: Fixture) -> None:
    result, _ = fixture_result
    v = judge(result)
    assert v.level == "acceptable" and v.line.startswith("acceptable: reprojection RMS 0.")
    assert "R_P_I measured to +-" in v.line
    rep = report_dict(result, v)
    json.dumps(rep)  # plain JSON
    assert rep["verdict"] == "acceptable" and len(rep["poses"]) == 3
    assert rep["change_from_nominal"]["principal_px"] > 250  # the rig's +300 px
    assert rep["imu"]["measured"] and rep["depth_range_m"][0] < rep["depth_range_m"][1]
    img = report_picture(result, v)
    # a title bar (the verdict and a legend) above the frame (400) and the depth strip (90)
    assert img.shape[1:] == (640, 3) and img.shape[0] > 400 + 90 and img.dtype == np.uint8
    assert img[-490:-90].std() > 5  # pairs and residuals drawn


def test_the_nominal_rig_is_refused_as_a_plane_when_every_pose_is_flat(
    fixture_result: Fixture,
) -> None:
    result, _ = fixture_result
    flat_poses = []
    for p in result.run.poses:
        pts = p.pairs.points.copy()
        pts[:, 2] = 1.5  # every point of the pose on one plane
        flat_poses.append(replace(p, pairs=replace(p.pairs, points=pts)))
    flat = replace(result, run=replace(result.run, poses=flat_poses))
    v = judge(flat)
    assert v.level == "refused" and "one plane only" in v.line and not v.writable


def test_write_outputs_and_the_no_worse_rule(fixture_result: Fixture, tmp_path: Path) -> None:
    result, _ = fixture_result
    v = judge(result)
    out = tmp_path / "cal" / "unit.toml"
    written = write_outputs(result, v, out)
    assert written == [out, *report_paths(out)] and all(p.exists() for p in written)
    assert not list(out.parent.glob(".*.tmp"))  # no temporary file left behind
    data = tomllib.loads(out.read_text())
    assert data["quality"]["verdict"] == "acceptable" and data["quality"]["poses"] == 3
    cal = Calibration.load(out)
    assert np.allclose(cal.projector.K, result.calibration.projector.K)
    # the depth model stays the session's, as recorded
    assert np.array_equal(cal.depth.K, read_calibration(FIXTURE).depth.K)
    assert existing_quality(out) == (v.level, pytest.approx(result.projector.rms_px, abs=1e-4))
    # a better calibration there: not replaced, unless forced
    better = data["quality"] | {"rms_px": 0.01}
    text = out.read_text().replace(f"rms_px = {data['quality']['rms_px']}", "rms_px = 0.01")
    out.write_text(text)
    assert existing_quality(out) == (v.level, 0.01) and better["rms_px"] == 0.01
    with pytest.raises(CalibrationError, match="holds a better calibration"):
        write_outputs(result, v, out)
    assert existing_quality(out) == (v.level, 0.01)
    write_outputs(result, v, out, force=True)
    assert existing_quality(out) == (v.level, pytest.approx(result.projector.rms_px, abs=1e-4))


def test_a_refused_calibration_is_not_written(fixture_result: Fixture, tmp_path: Path) -> None:
    result, _ = fixture_result
    out = tmp_path / "unit.toml"
    with pytest.raises(CalibrationError, match="no calibration written"):
        write_outputs(result, Verdict("poor", "poor: redo"), out)
    assert not out.exists() and report_paths(out)[0].exists()


def test_is_worse() -> None:
    good, ok = Verdict("good", ""), Verdict("acceptable", "")
    assert is_worse(ok, 0.3, ("good", 0.4)) and not is_worse(good, 0.4, ("acceptable", 0.3))
    assert is_worse(good, 0.4, ("good", 0.3)) and not is_worse(good, 0.3, ("good", 0.3))


def test_existing_quality_of_files_without_one(tmp_path: Path) -> None:
    nominal = tmp_path / "nominal.toml"
    nominal.write_text(Calibration.default().to_toml())
    assert existing_quality(nominal) is None
    assert existing_quality(tmp_path / "none.toml") is None
    (tmp_path / "bad.toml").write_text("[quality\n")
    assert existing_quality(tmp_path / "bad.toml") is None
