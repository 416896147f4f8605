"""The depth camera: DepthAI v3 stereo depth on a Luxonis OAK-D, and its replay.

The configuration is plain data (:class:`StereoSettings`); the device pipeline is
built in one function, :func:`build_pipeline`, which needs a camera attached. The
pieces around it run anywhere and are tested on the host: the ``StereoDepthConfig``
made from the settings, the depth model read from a ``CalibrationHandler``, and the
conversion of ``ImgFrame`` s into :class:`DepthFrame` records.

Depth frames are uint16 millimetres, 0 where the stereo matcher found no valid
disparity (left-right check, confidence, edges), aligned to the colour camera
(``CAM_A``), which is the depth frame D of the calibration.
"""

from __future__ import annotations

import datetime
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge import checks
from adaproj_edge.errors import DeviceError, DeviceNotFoundError
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.hal.clock import Clock, VirtualClock
from adaproj_edge.hal.recorded import ReplayStream

_CHECK = "the OAK-D USB cable (USB3 port), its power, and the udev rule for vendor 03e7"


@dataclass(frozen=True)
class DepthFrame:
    """One depth image (height, width) uint16 in millimetres, 0 = invalid.

    ``sensor_ns`` is the exposure time on the device's monotonic clock (DepthAI syncs
    it to the host's steady clock), ``receive_ns`` when the host got it.
    """

    sensor_ns: int
    receive_ns: int
    sequence: int
    depth_mm: NDArray[np.uint16]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DepthFrame):
            return NotImplemented
        return (
            (self.sensor_ns, self.receive_ns, self.sequence)
            == (other.sensor_ns, other.receive_ns, other.sequence)
            and self.depth_mm.shape == other.depth_mm.shape
            and bool(np.array_equal(self.depth_mm, other.depth_mm))
        )

    __hash__ = None  # type: ignore[assignment]

    def metres(self) -> NDArray[np.float64]:
        """Depth (height, width) in metres, NaN where invalid."""
        z = self.depth_mm.astype(np.float64) * 1e-3
        z[self.depth_mm == 0] = np.nan
        return z


class DepthCamera(Protocol):
    """A depth camera with a known model."""

    @property
    def model(self) -> DepthCameraModel:
        """The depth camera model of the frames (intrinsics, size, baseline)."""
        ...

    def read(self) -> DepthFrame | None:
        """The next frame, or None when none came (or the recording ended)."""
        ...

    def close(self) -> None:
        """Release the camera."""
        ...


@dataclass(frozen=True)
class StereoSettings:
    """How the OAK-D computes depth; plain data, kept in board files and sessions."""

    width: int = 640
    height: int = 400
    fps: float = 15.0
    preset: str = "DEFAULT"
    subpixel: bool = True
    subpixel_fractional_bits: int = 3
    left_right_check: bool = True
    left_right_threshold: int = 10
    median: str = "KERNEL_7x7"
    confidence_threshold: int = 55
    extended_disparity: bool = False
    align_to: str = "CAM_A"

    def __post_init__(self) -> None:
        checks.integer(self.width, "width", 16, 4096)
        checks.integer(self.height, "height", 16, 4096)
        checks.number(self.fps, "fps", 0.0, 120.0, above=True)
        checks.text(self.preset, "preset", PRESETS)
        checks.flag(self.subpixel, "subpixel")
        checks.integer(self.subpixel_fractional_bits, "subpixel_fractional_bits", 3, 5)
        checks.flag(self.left_right_check, "left_right_check")
        checks.integer(self.left_right_threshold, "left_right_threshold", 0, 128)
        checks.text(self.median, "median", MEDIANS)
        checks.integer(self.confidence_threshold, "confidence_threshold", 0, 255)
        checks.flag(self.extended_disparity, "extended_disparity")
        checks.text(self.align_to, "align_to", SOCKETS)


PRESETS = (
    "ACCURACY",
    "DEFAULT",
    "DENSITY",
    "FACE",
    "FAST_ACCURACY",
    "FAST_DENSITY",
    "HIGH_DETAIL",
    "ROBOTICS",
)
"""DepthAI's stereo presets (``dai.node.StereoDepth.PresetMode``)."""
MEDIANS = ("MEDIAN_OFF", "KERNEL_3x3", "KERNEL_5x5", "KERNEL_7x7")
"""DepthAI's median filters."""
SOCKETS = ("CAM_A", "CAM_B", "CAM_C", "CAM_D")
"""Camera sockets of an OAK board."""


def _dai() -> Any:
    import depthai

    return depthai


def stereo_config(settings: StereoSettings) -> Any:
    """A host-side ``dai.StereoDepthConfig`` holding ``settings`` (depth in mm)."""
    dai = _dai()
    cfg = dai.StereoDepthConfig()
    cfg.setMedianFilter(getattr(dai.filters.params.MedianFilter, settings.median))
    cfg.setLeftRightCheck(settings.left_right_check)
    cfg.setLeftRightCheckThreshold(settings.left_right_threshold)
    cfg.setSubpixel(settings.subpixel)
    cfg.setSubpixelFractionalBits(settings.subpixel_fractional_bits)
    cfg.setConfidenceThreshold(settings.confidence_threshold)
    cfg.setExtendedDisparity(settings.extended_disparity)
    cfg.setDepthUnit(dai.LengthUnit.MILLIMETER)
    return cfg


def depth_model(calibration: Any, settings: StereoSettings) -> DepthCameraModel:
    """The depth camera model from the OAK-D's own ``dai.CalibrationHandler``.

    Intrinsics of the camera depth is aligned to, scaled to the output size; the stereo
    baseline between the two mono cameras (``CAM_B``, ``CAM_C``).
    """
    dai = _dai()
    sock = getattr(dai.CameraBoardSocket, settings.align_to)
    try:
        K = np.asarray(calibration.getCameraIntrinsics(sock, settings.width, settings.height))
        baseline_cm = calibration.getBaselineDistance(
            dai.CameraBoardSocket.CAM_C, dai.CameraBoardSocket.CAM_B, False
        )
    except RuntimeError as e:
        raise DeviceError(
            f"the OAK-D calibration lacks data for depth ({e}); recalibrate it"
        ) from None
    return DepthCameraModel(K, settings.width, settings.height, abs(float(baseline_cm)) / 100.0)


def timedelta_ns(td: datetime.timedelta) -> int:
    """Exact integer nanoseconds of a ``timedelta``."""
    return (td.days * 86_400 + td.seconds) * 1_000_000_000 + td.microseconds * 1000


def frame_from_img(img: Any, receive_ns: int) -> DepthFrame:
    """A :class:`DepthFrame` from a DepthAI ``ImgFrame`` of uint16 depth."""
    depth = np.asarray(img.getFrame())
    if depth.dtype != np.uint16 or depth.ndim != 2:
        raise DeviceError(f"the OAK-D sent a {depth.dtype} {depth.shape} frame, not uint16 depth")
    return DepthFrame(
        timedelta_ns(img.getTimestamp()), receive_ns, int(img.getSequenceNum()), depth.copy()
    )


def add_stereo(pipeline: Any, settings: StereoSettings) -> Any:
    """Add the stereo depth of ``settings`` to a DepthAI ``pipeline`` (both mono
    cameras and the ``StereoDepth`` node); returns its depth output queue."""
    dai = _dai()
    size = (settings.width, settings.height)
    left = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
    right = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_C)
    stereo = pipeline.create(dai.node.StereoDepth)
    stereo.setDefaultProfilePreset(getattr(dai.node.StereoDepth.PresetMode, settings.preset))
    left.requestOutput(size, fps=settings.fps).link(stereo.left)
    right.requestOutput(size, fps=settings.fps).link(stereo.right)
    stereo.setLeftRightCheck(settings.left_right_check)
    stereo.setSubpixel(settings.subpixel)
    stereo.setSubpixelFractionalBits(settings.subpixel_fractional_bits)
    stereo.setExtendedDisparity(settings.extended_disparity)
    stereo.setDepthAlign(getattr(dai.CameraBoardSocket, settings.align_to))
    stereo.setOutputSize(settings.width, settings.height)
    cfg = stereo_config(settings)
    stereo.initialConfig.setMedianFilter(cfg.getMedianFilter())
    stereo.initialConfig.setConfidenceThreshold(settings.confidence_threshold)
    stereo.initialConfig.setLeftRightCheckThreshold(settings.left_right_threshold)
    stereo.initialConfig.setDepthUnit(dai.LengthUnit.MILLIMETER)
    return stereo.depth.createOutputQueue(maxSize=4, blocking=False)


def build_pipeline(settings: StereoSettings) -> tuple[Any, Any, Any]:
    """Build and start the stereo pipeline on the attached OAK-D (board only).

    Returns
    -------
    pipeline, depth queue, calibration handler
    """
    dai = _dai()
    try:
        pipeline = dai.Pipeline()
        queue = add_stereo(pipeline, settings)
        calibration = pipeline.getDefaultDevice().readCalibration()
        pipeline.start()
    except RuntimeError as e:
        raise DeviceNotFoundError(f"cannot start the OAK-D ({e}); check {_CHECK}") from None
    return pipeline, queue, calibration


def find_oak_devices() -> list[str]:
    """The ids of the OAK devices DepthAI sees on USB (none opened).

    Raises ``ModuleNotFoundError`` without DepthAI (the ``device`` extra)."""
    dai = _dai()
    return [str(info.getDeviceId()) for info in dai.Device.getAllAvailableDevices()]


def read_oak_calibration(settings: StereoSettings) -> DepthCameraModel:
    """Open the first OAK-D, read its own calibration and close it: the depth camera
    model it gives (board only; raises a named DeviceError)."""
    dai = _dai()
    try:
        with dai.Device() as device:
            calibration = device.readCalibration()
    except RuntimeError as e:
        raise DeviceNotFoundError(f"cannot open the OAK-D ({e}); check {_CHECK}") from None
    return depth_model(calibration, settings)


class OakDepthCamera:
    """The real depth camera (an OAK-D through DepthAI v3).

    ``started`` (pipeline, depth queue, calibration handler) makes it read a pipeline
    built elsewhere (:class:`adaproj_edge.hal.camera.OakRig`), which then stops it.
    """

    def __init__(
        self, settings: StereoSettings, clock: Clock, started: tuple[Any, Any, Any] | None = None
    ) -> None:
        self.settings = settings
        self._clock = clock
        self._owner = started is None
        self._pipeline, self._queue, calibration = started or build_pipeline(settings)
        self._model = depth_model(calibration, settings)

    @property
    def model(self) -> DepthCameraModel:
        """The depth camera model read from the device's calibration."""
        return self._model

    def read(self) -> DepthFrame | None:
        """The next depth frame from the device queue (waits for it), stamped on arrival."""
        try:
            img = self._queue.get()
        except RuntimeError as e:
            raise DeviceError(f"the OAK-D stopped sending depth ({e}); check {_CHECK}") from None
        return None if img is None else frame_from_img(img, self._clock.now_ns())

    def close(self) -> None:
        """Stop the pipeline if this camera started it."""
        if self._owner:
            self._pipeline.stop()


class ReplayDepthCamera:
    """Depth frames from a recording, on a virtual clock."""

    def __init__(
        self, model: DepthCameraModel, frames: Iterable[DepthFrame], clock: VirtualClock
    ) -> None:
        self._model = model
        self._stream = ReplayStream(frames, clock)

    @property
    def model(self) -> DepthCameraModel:
        """The recorded depth camera model."""
        return self._model

    def read(self) -> DepthFrame | None:
        """The next recorded frame, or None at the end of the recording."""
        return self._stream.next()

    def close(self) -> None:
        """Nothing to release."""
        pass
