"""The structured-light camera's host-side pieces, on real DepthAI objects; its replay;
the board's [calibrate] section and the choice of calibration file."""

from __future__ import annotations

import datetime
from pathlib import Path

import depthai as dai
import numpy as np
import pytest

from adaproj_edge.errors import DeviceError, InputError
from adaproj_edge.hal.board import Board, calibration_in_use
from adaproj_edge.hal.camera import (
    CameraFrame,
    CameraSettings,
    ReplayCamera,
    camera_control,
    camera_frame_from_img,
    camera_intrinsics,
)
from adaproj_edge.hal.clock import VirtualClock
from tests.hal.test_board import write_board
from tests.hal.test_depth_hal import calibration_handler


def test_camera_control_holds_the_manual_exposure() -> None:
    ctrl = camera_control(CameraSettings(exposure_us=5000, iso=800))
    assert isinstance(ctrl, dai.CameraControl)
    assert ctrl.getExposureTime() == datetime.timedelta(microseconds=5000)
    assert ctrl.getSensitivity() == 800


def _img(kind: dai.ImgFrame.Type, pixels: np.ndarray, w: int, h: int) -> dai.ImgFrame:
    img = dai.ImgFrame()
    img.setType(kind)
    img.setWidth(w)
    img.setHeight(h)
    img.setData(pixels.ravel())
    img.setTimestamp(datetime.timedelta(seconds=3, microseconds=250))
    img.setSequenceNum(11)
    return img


def test_frame_from_a_grey_img() -> None:
    grey = (np.arange(12, dtype=np.uint8) * 20).reshape(3, 4)
    f = camera_frame_from_img(_img(dai.ImgFrame.Type.GRAY8, grey, 4, 3), 77)
    # no exposure set on the host object: the start of exposure is the timestamp
    assert (f.sensor_ns, f.receive_ns, f.sequence) == (3_000_250_000, 77, 11)
    assert np.array_equal(f.image, grey) and f.image.dtype == np.uint8


def test_frame_from_nv12_keeps_the_luma() -> None:
    luma = np.arange(16, dtype=np.uint8).reshape(4, 4)
    chroma = np.full(8, 128, np.uint8)
    f = camera_frame_from_img(_img(dai.ImgFrame.Type.NV12, np.r_[luma.ravel(), chroma], 4, 4), 0)
    assert np.array_equal(f.image, luma)


def test_frame_of_another_type_is_refused() -> None:
    rgb = np.zeros(4 * 3 * 3, np.uint8)
    with pytest.raises(DeviceError, match="not grey"):
        camera_frame_from_img(_img(dai.ImgFrame.Type.BGR888i, rgb, 4, 3), 0)


def test_intrinsics_from_the_device_calibration() -> None:
    K = camera_intrinsics(calibration_handler(), CameraSettings(width=640, height=400))
    # the handler holds f = 1000 at 1280x800: half of it at half the size
    assert K[0, 0] == pytest.approx(500.0) and K[1, 1] == pytest.approx(500.0)
    with pytest.raises(DeviceError, match="lacks"):
        camera_intrinsics(dai.CalibrationHandler(), CameraSettings())


@pytest.mark.parametrize(
    "bad",
    [{"socket": "CAM_X"}, {"width": 8}, {"exposure_us": 0}, {"iso": 5000}, {"fps": 0.0},
     {"display_latency_ms": -1.0}],
)  # fmt: skip
def test_bad_camera_settings(bad: dict[str, object]) -> None:
    with pytest.raises(InputError):
        CameraSettings(**bad)  # type: ignore[arg-type]


def test_replay_camera() -> None:
    clock = VirtualClock()
    frames = [CameraFrame(5, 9, 0, np.zeros((2, 3), np.uint8), 8000, 400)]
    cam = ReplayCamera(np.eye(3), (3, 2), frames, clock)
    assert cam.size == (3, 2) and np.array_equal(cam.intrinsics, np.eye(3))
    assert cam.read() == frames[0] and clock.now_ns() == 9
    assert cam.read() is None
    cam.close()


def test_board_calibrate_section(tmp_path: Path) -> None:
    b = Board.load("rpi5-oakd")
    assert b.camera.socket == b.depth.align_to == "CAM_A"
    assert b.camera.display_latency_ns == 100_000_000
    p = write_board(tmp_path, "[calibrate]\nwidth = 320\nheight = 200\nexposure_us = 4000\n")
    assert Board.load(p).camera == CameraSettings(width=320, height=200, exposure_us=4000)
    assert Board.load(write_board(tmp_path, "")).camera == CameraSettings()
    with pytest.raises(InputError, match="unknown keys"):
        Board.load(write_board(tmp_path, "[calibrate]\nshutter = 3\n"))


def test_calibration_in_use(tmp_path: Path) -> None:
    board = Board.load("rpi5-oakd")
    device_file = tmp_path / "calibration.toml"
    assert calibration_in_use(board, None, device_file) == board.calibration_path
    device_file.write_text("x")
    assert calibration_in_use(board, None, device_file) == device_file
    assert calibration_in_use(board, tmp_path / "mine.toml", device_file) == tmp_path / "mine.toml"
    assert board.with_calibration(device_file).calibration_path == device_file
