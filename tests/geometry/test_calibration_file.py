"""The calibration file format: old files load as before, distortion and [quality]
round-trip through TOML and JSON, and the depth model scales to other sizes."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.hal.board import Board


def test_nominal_files_load_and_write_as_before() -> None:
    cal = Board.load("rpi5-oakd").calibration()
    assert np.array_equal(cal.distortion, np.zeros(5)) and cal.quality is None
    d = cal.to_dict()
    # session attachments of nominal calibrations keep their old fields only
    assert set(d) == {"format", "projector", "depth", "extrinsics"}
    assert set(d["projector"]) == {"width", "height", "K"}


@given(
    st.lists(st.floats(-0.5, 0.5), min_size=5, max_size=5),
    st.floats(0.01, 5.0),
    st.sampled_from(["good", "acceptable"]),
    st.booleans(),
)
def test_distortion_and_quality_round_trip(
    dist: list[float], rms: float, verdict: str, flag: bool
) -> None:
    base = Calibration.default()
    quality = {"verdict": verdict, "rms_px": rms, "poses": 5, "imu_measured": flag}
    cal = Calibration(base.projector, base.depth, base.T_P_D, base.R_P_I, np.array(dist), quality)
    for back in (
        Calibration.from_dict(tomllib.loads(cal.to_toml("a comment\nover two lines"))),
        Calibration.from_json(cal.to_json()),
    ):
        assert np.array_equal(back.distortion, cal.distortion) and back.quality == quality
        assert np.array_equal(back.projector.K, cal.projector.K)
        assert np.array_equal(back.T_P_D, cal.T_P_D) and np.array_equal(back.R_P_I, cal.R_P_I)


def test_bad_distortion_and_quality() -> None:
    d = Calibration.default().to_dict()
    d["projector"]["distortion"] = [0.1] * 6
    with pytest.raises(InputError, match="distortion"):
        Calibration.from_dict(d)
    d["projector"]["distortion"] = [0.1, float("nan")]
    with pytest.raises(InputError, match="distortion"):
        Calibration.from_dict(d)
    d["projector"]["distortion"] = [0.1, 0.0]  # fewer coefficients: the rest are zero
    assert np.array_equal(Calibration.from_dict(d).distortion, [0.1, 0, 0, 0, 0])
    d["quality"] = "good"
    with pytest.raises(InputError, match="quality"):
        Calibration.from_json(json.dumps(d))


def test_unwritable_values_are_refused() -> None:
    base = Calibration.default()
    cal = Calibration(base.projector, base.depth, base.T_P_D, base.R_P_I, quality={"x": {"y": 1}})
    with pytest.raises(InputError, match="cannot write dict"):
        cal.to_toml()


def test_intrinsics_at_another_size() -> None:
    m = DepthCameraModel.oak_d()
    K = m.intrinsics_at(1280, 800)
    assert K[0, 0] == pytest.approx(2 * m.K[0, 0]) and K[0, 2] == pytest.approx(639.5)
    # pixel centres line up: depth pixel 0 covers camera pixels 0 and 1
    assert m.intrinsics_at(m.width, m.height) == pytest.approx(m.K)
