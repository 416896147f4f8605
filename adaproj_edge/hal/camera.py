"""The camera depth is aligned to, for structured light: DepthAI v3 on the OAK-D, and
its replay.

``adaproj calibrate`` shows Gray-code patterns with the projector and captures each
with the OAK-D camera that the depth frames are aligned to (``CAM_A``, frame D of the
calibration), so a decoded camera pixel has its depth at the same place. The camera
runs at a fixed exposure and ISO (no auto exposure: every pattern must be captured
alike) and, on a camera with a focus motor, at the lens position of the OAK-D's own
calibration. Frames are grey (``GRAY8``) and time-stamped at the *start* of their
exposure on the device clock DepthAI syncs to the host's steady clock, the clock
depth frames use too; a capture waits until a frame began after the pattern was on
the wall (:class:`CameraSettings`: display latency, from the board's
``[calibration]`` section).

One DepthAI pipeline runs both the camera and the stereo depth (:class:`OakRig`).
The pieces around the device — the ``CameraControl`` made from the settings, the
intrinsics read from a ``CalibrationHandler``, the conversion of an ``ImgFrame`` into
a :class:`CameraFrame` — run on the host and are tested there.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from adaproj_edge import checks
from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import DeviceError, DeviceNotFoundError, InputError
from adaproj_edge.hal.clock import Clock, VirtualClock
from adaproj_edge.hal.depth import (
    SOCKETS,
    OakDepthCamera,
    StereoSettings,
    _dai,
    add_stereo,
    timedelta_ns,
)
from adaproj_edge.hal.recorded import ReplayStream

_CHECK = "the OAK-D USB cable (USB3 port), its power, and the udev rule for vendor 03e7"


@dataclass(frozen=True)
class CameraSettings:
    """The structured-light camera and timing of a board (``[calibration]`` section).

    Parameters
    ----------
    socket : str
        The DepthAI camera socket; must be the one depth is aligned to.
    width, height : int
        Frame size in pixels (same aspect ratio as the depth frames).
    fps : float
        Frame rate.
    exposure_us, iso : int
        Fixed exposure time (microseconds) and sensitivity.
    display_latency_ms : float
        From ``Display.show`` until the frame is on the wall (framebuffer scan-out
        plus the projector's own processing); a capture uses the first camera frame
        whose exposure starts after it.
    camera_latency_ms : float
        From the end of an exposure until the frame reaches the host (how long a
        capture waits before it calls the camera silent).
    """

    socket: str = "CAM_A"
    width: int = 1280
    height: int = 800
    fps: float = 30.0
    exposure_us: int = 8000
    iso: int = 400
    display_latency_ms: float = 100.0
    camera_latency_ms: float = 60.0

    def __post_init__(self) -> None:
        checks.text(self.socket, "socket", SOCKETS)
        checks.integer(self.width, "width", 16, 8192)
        checks.integer(self.height, "height", 16, 8192)
        checks.number(self.fps, "fps", 0.0, 240.0, above=True)
        checks.integer(self.exposure_us, "exposure_us", 1, 33_000)
        checks.integer(self.iso, "iso", 100, 1600)
        checks.number(self.display_latency_ms, "display_latency_ms", 0.0, 10_000.0)
        checks.number(self.camera_latency_ms, "camera_latency_ms", 0.0, 10_000.0)

    @property
    def display_latency_ns(self) -> int:
        """:attr:`display_latency_ms` in nanoseconds."""
        return round(self.display_latency_ms * 1e6)

    @property
    def frame_ns(self) -> int:
        """Frame period in nanoseconds."""
        return round(1e9 / self.fps)


@dataclass(frozen=True)
class CameraFrame:
    """One grey frame (height, width) uint8; ``sensor_ns`` is the start of its
    exposure on the device clock, ``receive_ns`` when the host got it."""

    sensor_ns: int
    receive_ns: int
    sequence: int
    image: NDArray[np.uint8]
    exposure_us: int
    iso: int

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraFrame):
            return NotImplemented
        return (
            (self.sensor_ns, self.receive_ns, self.sequence, self.exposure_us, self.iso)
            == (other.sensor_ns, other.receive_ns, other.sequence, other.exposure_us, other.iso)
            and self.image.shape == other.image.shape
            and bool(np.array_equal(self.image, other.image))
        )

    __hash__ = None  # type: ignore[assignment]


class Camera(Protocol):
    """A camera with known intrinsics, at a fixed exposure."""

    @property
    def intrinsics(self) -> FloatArray:
        """(3, 3) at the frames' size."""
        ...

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the frames."""
        ...

    def read(self) -> CameraFrame | None:
        """The next frame (waits for it), or None when the recording ended."""
        ...

    def close(self) -> None:
        """Release the camera."""
        ...


def camera_control(settings: CameraSettings, lens_position: float | None = None) -> Any:
    """A host-side ``dai.CameraControl``: manual exposure and ISO, and the focus at
    ``lens_position`` (0..1, from the device calibration) when given."""
    dai = _dai()
    ctrl = dai.CameraControl()
    ctrl.setManualExposure(int(settings.exposure_us), int(settings.iso))
    if lens_position is not None:
        ctrl.setManualFocus(round(255 * min(max(lens_position, 0.0), 1.0)))
    return ctrl


def camera_intrinsics(calibration: Any, settings: CameraSettings) -> FloatArray:
    """The camera's intrinsics (3, 3) at the frame size, from the OAK-D's own
    ``dai.CalibrationHandler``."""
    dai = _dai()
    sock = getattr(dai.CameraBoardSocket, settings.socket)
    try:
        K = np.asarray(calibration.getCameraIntrinsics(sock, settings.width, settings.height))
    except RuntimeError as e:
        raise DeviceError(f"the OAK-D calibration lacks {settings.socket} ({e})") from None
    return K.astype(np.float64)


def camera_frame_from_img(img: Any, receive_ns: int) -> CameraFrame:
    """A :class:`CameraFrame` from a DepthAI ``ImgFrame`` (``GRAY8``, or the luma plane
    of ``NV12``), time-stamped at the start of its exposure."""
    dai = _dai()
    kind = img.getType()
    w, h = int(img.getWidth()), int(img.getHeight())
    data = np.asarray(img.getData(), dtype=np.uint8)
    if kind not in (dai.ImgFrame.Type.GRAY8, dai.ImgFrame.Type.NV12) or data.size < w * h:
        raise DeviceError(f"the OAK-D camera sent a {kind} {w}x{h} frame, not grey")
    image = data[: w * h].reshape(h, w).copy()
    start = timedelta_ns(img.getTimestamp(dai.CameraExposureOffset.START))
    exposure = timedelta_ns(img.getExposureTime()) // 1000
    return CameraFrame(
        start,
        receive_ns,
        int(img.getSequenceNum()),
        image,
        int(exposure),
        int(img.getSensitivity()),
    )


class FixedCamera:
    """The part every :class:`Camera` shares: intrinsics (3, 3) at a frame size
    (width, height) that do not change; nothing to close."""

    def __init__(self, intrinsics: FloatArray, size: tuple[int, int]) -> None:
        self._K = np.asarray(intrinsics, np.float64)
        self._size = (int(size[0]), int(size[1]))

    @property
    def intrinsics(self) -> FloatArray:
        """(3, 3) at the frames' size."""
        return self._K

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the frames."""
        return self._size

    def close(self) -> None:
        """Nothing to release."""
        pass


class _OakCamera(FixedCamera):
    """The camera half of an :class:`OakRig`."""

    def __init__(self, queue: Any, K: FloatArray, size: tuple[int, int], clock: Clock) -> None:
        super().__init__(K, size)
        self._queue, self._clock = queue, clock

    def read(self) -> CameraFrame | None:
        try:
            img = self._queue.get()
        except RuntimeError as e:
            raise DeviceError(f"the OAK-D camera stopped ({e}); check {_CHECK}") from None
        return None if img is None else camera_frame_from_img(img, self._clock.now_ns())


class OakRig:
    """The OAK-D running stereo depth and the structured-light camera in one pipeline
    (board only): ``camera`` (a :class:`Camera`) and ``depth`` (a ``DepthCamera``)."""

    def __init__(self, stereo: StereoSettings, settings: CameraSettings, clock: Clock) -> None:
        if settings.socket != stereo.align_to:
            raise InputError(
                f"the calibration camera {settings.socket} is not the camera depth is aligned "
                f"to ({stereo.align_to})"
            )
        dai = _dai()
        try:
            pipeline = dai.Pipeline()
            depth_queue = add_stereo(pipeline, stereo)
            calibration = pipeline.getDefaultDevice().readCalibration()
            sock = getattr(dai.CameraBoardSocket, settings.socket)
            cam = pipeline.create(dai.node.Camera).build(sock)
            try:
                lens = float(calibration.getLensPosition(sock)) / 255.0
            except RuntimeError:
                lens = None
            cam.initialControl.setManualExposure(int(settings.exposure_us), int(settings.iso))
            if lens is not None and lens > 0:
                cam.initialControl.setManualFocus(round(255 * lens))
            out = cam.requestOutput(
                (settings.width, settings.height), type=dai.ImgFrame.Type.GRAY8, fps=settings.fps
            )
            camera_queue = out.createOutputQueue(maxSize=4, blocking=False)
            pipeline.start()
        except RuntimeError as e:
            raise DeviceNotFoundError(f"cannot start the OAK-D ({e}); check {_CHECK}") from None
        self._pipeline = pipeline
        self.depth = OakDepthCamera(stereo, clock, (pipeline, depth_queue, calibration))
        K = camera_intrinsics(calibration, settings)
        self.camera = _OakCamera(camera_queue, K, (settings.width, settings.height), clock)

    def close(self) -> None:
        """Stop the pipeline (both the camera and depth)."""
        self._pipeline.stop()


class ReplayCamera(FixedCamera):
    """Camera frames from a recording, on a virtual clock."""

    def __init__(
        self,
        intrinsics: FloatArray,
        size: tuple[int, int],
        frames: Iterable[CameraFrame],
        clock: VirtualClock,
    ) -> None:
        super().__init__(intrinsics, size)
        self._stream = ReplayStream(frames, clock)

    def read(self) -> CameraFrame | None:
        """The next recorded frame, or None at the end of the recording."""
        return self._stream.next()
