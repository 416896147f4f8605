"""The parts of the OAK-D driver that run without the device, on real DepthAI objects."""

from __future__ import annotations

import datetime

import depthai as dai
import numpy as np
import pytest

from adaproj_edge.errors import DeviceError, InputError
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import (
    DepthFrame,
    ReplayDepthCamera,
    StereoSettings,
    depth_model,
    frame_from_img,
    stereo_config,
    timedelta_ns,
)


def test_stereo_config_holds_the_settings() -> None:
    cfg = stereo_config(StereoSettings())
    assert isinstance(cfg, dai.StereoDepthConfig)
    assert cfg.getMedianFilter() == dai.filters.params.MedianFilter.KERNEL_7x7
    assert cfg.getSubpixel() and cfg.getLeftRightCheck()
    assert cfg.getSubpixelFractionalBits() == 3
    assert cfg.getConfidenceThreshold() == 55
    assert cfg.getDepthUnit() == dai.LengthUnit.MILLIMETER
    off = stereo_config(StereoSettings(median="MEDIAN_OFF", left_right_check=False))
    assert off.getMedianFilter() == dai.filters.params.MedianFilter.MEDIAN_OFF
    assert not off.getLeftRightCheck()


@pytest.mark.parametrize("bad", [{"median": "KERNEL_9x9"}, {"subpixel_fractional_bits": 2}])
def test_bad_settings(bad: dict[str, object]) -> None:
    with pytest.raises(InputError):
        StereoSettings(**bad)  # type: ignore[arg-type]


def calibration_handler() -> dai.CalibrationHandler:
    c = dai.CalibrationHandler()
    K = [[1000.0, 0.0, 640.0], [0.0, 1000.0, 400.0], [0.0, 0.0, 1.0]]
    for s in (
        dai.CameraBoardSocket.CAM_A,
        dai.CameraBoardSocket.CAM_B,
        dai.CameraBoardSocket.CAM_C,
    ):
        c.setCameraIntrinsics(s, K, 1280, 800)
    c.setCameraExtrinsics(
        dai.CameraBoardSocket.CAM_B, dai.CameraBoardSocket.CAM_C, np.eye(3).tolist(), [-7.5, 0, 0]
    )
    return c


def test_depth_model_from_the_camera_calibration() -> None:
    m = depth_model(calibration_handler(), StereoSettings())
    assert m.width == 640 and m.height == 400
    assert m.K[0, 0] == pytest.approx(500.0) and m.K[0, 2] == pytest.approx(320.0)
    assert m.baseline_m == pytest.approx(0.075)


def test_depth_model_from_an_empty_calibration() -> None:
    with pytest.raises(DeviceError, match="recalibrate"):
        depth_model(dai.CalibrationHandler(), StereoSettings())


def test_frame_from_img() -> None:
    depth = (np.arange(12, dtype=np.uint16) * 300).reshape(3, 4)
    img = dai.ImgFrame()
    img.setType(dai.ImgFrame.Type.RAW16)
    img.setWidth(4)
    img.setHeight(3)
    img.setData(depth.view(np.uint8).ravel())
    img.setTimestamp(datetime.timedelta(seconds=12, microseconds=345))
    img.setSequenceNum(7)
    f = frame_from_img(img, 99)
    assert f == DepthFrame(12_000_345_000, 99, 7, depth)
    z = f.metres()
    assert np.isnan(z[0, 0]) and z[2, 3] == pytest.approx(3.3)


def test_timedelta_ns_is_exact() -> None:
    assert timedelta_ns(datetime.timedelta(days=2, seconds=3, microseconds=4)) == (
        (2 * 86400 + 3) * 10**9 + 4000
    )


def test_replay_depth_camera() -> None:
    clock = VirtualClock()
    frames = [DepthFrame(1, 5, 0, np.zeros((2, 2), np.uint16))]
    cam = ReplayDepthCamera(DepthCameraModel.oak_d(), frames, clock)
    assert cam.model.width == 640
    assert cam.read() == frames[0] and clock.now_ns() == 5
    assert cam.read() is None
    cam.close()
