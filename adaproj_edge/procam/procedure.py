"""The calibration procedure: poses captured through the ``hal`` protocols.

For each pose (:func:`capture_poses`):

1. the user is told to hold the device still (the first pose) or to move it to a
   new pose and hold it there; the IMU says when it has moved (after the first
   pose) and then stood still for ``still_s``;
2. ``depth_frames`` depth frames taken from then on are averaged (median);
3. each pattern of the :class:`~adaproj_edge.procam.graycode.PatternSet` is shown,
   and the first camera frame whose exposure starts ``display_latency_ms`` after
   the display call is kept (:class:`~adaproj_edge.hal.camera.CameraSettings`);
4. the IMU samples of the capture are checked: a device that turned or shook while
   the patterns ran is told so and the pose is taken again (at most
   ``max_retakes`` times in a row);
5. the captures are decoded and checked — nothing decoded (projector off, lens cap
   on, camera looking elsewhere) ends the procedure; saturated images or ambient
   light drowning the patterns make the pose be taken again, with what to change
   (and end it after ``max_retakes``), each with a message that says what to do —
   and made into point pairs;
6. with ``photometric`` on, after the first good pose the projector shows its three
   primaries too, and the surface's colour and the room's light are measured from
   them and the pose's black and white (:mod:`adaproj_edge.procam.photometric`);
   captures it refuses are said, and the calibration goes on without;
7. :func:`~adaproj_edge.procam.plan.assess` says how many poses are still needed
   and what to change; the procedure stops when it says enough (and
   ``min_poses`` are done) or at ``max_poses``.

Every decision depends on the records' own time stamps (and on the display's time
of each pattern), never on when the code happened to run, so a recorded session
replayed through :class:`ReplayShow` and the replay devices takes the very same
decisions (``adaproj calibrate --replay``). The :class:`Listener` hears what to tell
the user (``say``) and every record to keep (``record``: the IMU samples read, the
depth and camera frames used, the patterns shown).

``adaproj calibrate`` and the runtime's "hold the button 5 s" gesture call
:func:`capture_poses`, then :func:`~adaproj_edge.procam.result.solve_capture`.

This file is about 460 lines on purpose: the pose loop and the checks it makes
between captures (stillness, turns during a capture, dark or saturated captures)
share the IMU log, the settings and the listener; apart, each would reach into the
other's state.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.geometry.rotations import rotation_vector
from adaproj_edge.hal.camera import Camera, CameraFrame, CameraSettings
from adaproj_edge.hal.clock import Clock, VirtualClock
from adaproj_edge.hal.depth import DepthCamera, DepthFrame
from adaproj_edge.hal.display import Display
from adaproj_edge.hal.imu import Imu, ImuSample
from adaproj_edge.motion.tracker import is_still
from adaproj_edge.procam.graycode import Decoded, DecodeSettings, PatternSet, decode
from adaproj_edge.procam.imu import integrate_gyro, scene_planes
from adaproj_edge.procam.pairs import Pairs, PairSettings, pose_pairs
from adaproj_edge.procam.photometric import PRIMARY_FRAMES, measure_pose, primary_frame
from adaproj_edge.procam.plan import Plan, PlanSettings, PoseSummary, assess
from adaproj_edge.render.reflectance import Response
from adaproj_edge.session.codec import Record
from adaproj_edge.session.records import PatternShown


@dataclass(frozen=True)
class ProcedureSettings:
    """How the procedure runs (seconds, degrees, counts)."""

    max_poses: int = 8
    still_s: float = 0.5
    settle_timeout_s: float = 90.0
    depth_frames: int = 3
    max_retakes: int = 3
    max_capture_turn_deg: float = 0.1
    min_lit_fraction: float = 0.005
    max_saturated: float = 0.2
    max_ambient_ratio: float = 0.7
    min_signal: float = 15.0
    decode: DecodeSettings = field(default_factory=DecodeSettings)
    pairs: PairSettings = field(default_factory=PairSettings)
    plan: PlanSettings = field(default_factory=PlanSettings)
    photometric: bool = False


class Listener(Protocol):
    """Who hears the procedure: the user (``say``) and the recorder (``record``)."""

    def say(self, event: str, message: str) -> None:
        """``event``: ``"hold"``, ``"move"``, ``"retake"``, ``"captured"``, ``"done"``."""
        ...

    def record(self, rec: Record) -> None:
        """Record ``rec`` (a pattern shown, a capture, a depth frame, an IMU sample)."""
        ...


class Silent:
    """A listener that tells nobody and records nothing (tools, tests)."""

    def say(self, event: str, message: str) -> None:
        """Say nothing."""
        pass

    def record(self, rec: Record) -> None:
        """Record nothing."""
        pass


class ShowLog(Protocol):
    """Puts a pattern on the display and says when (ns)."""

    def show(self, pose: int, index: int, name: str, frame: Image) -> int:
        """Show ``frame``, pattern ``index`` (``name``) of pose ``pose``; its time in ns."""
        ...


class LiveShow:
    """The display itself: the time of a pattern is the clock's at the display call;
    each pattern shown is recorded."""

    def __init__(self, display: Display, clock: Clock, listener: Listener) -> None:
        self.display, self.clock, self.listener = display, clock, listener

    def show(self, pose: int, index: int, name: str, frame: Image) -> int:
        """Show ``frame`` and record it; the clock's time at the display call, in ns."""
        self.display.show(frame)
        t = self.clock.now_ns()
        self.listener.record(PatternShown(t, pose, index, name))
        return t


class ReplayShow:
    """The patterns of a recording: each display call takes the next recorded one
    (which must be the same pattern) and its time, moving the virtual clock there."""

    def __init__(
        self, shown: Iterator[PatternShown], clock: VirtualClock, display: Display | None = None
    ) -> None:
        self._it, self.clock, self.display = shown, clock, display

    def show(self, pose: int, index: int, name: str, frame: Image) -> int:
        """Show ``frame`` (if there is a display) and return the recorded time of the same
        pattern, in ns; a :class:`CalibrationError` if the recording shows another."""
        if self.display is not None:
            self.display.show(frame)
        rec = next(self._it, None)
        if rec is None:
            raise CalibrationError(f"the recording ends before pattern {name} of pose {pose + 1}")
        if (rec.pose, rec.index) != (pose, index):
            raise CalibrationError(
                f"the replay differs from the recording: it shows pattern {name} of pose "
                f"{pose + 1}, the recording {rec.name} of pose {rec.pose + 1}"
            )
        self.clock.advance_to(rec.t_ns)
        return rec.t_ns


@dataclass
class Devices:
    """What the procedure drives."""

    show: ShowLog
    camera: Camera
    depth: DepthCamera
    imu: Imu
    clock: Clock


class ImuLog:
    """Every IMU sample read, in order; reads on until a sample passes a time."""

    def __init__(self, imu: Imu, clock: Clock, listener: Listener, poll_ns: int) -> None:
        self.imu, self.clock, self.listener, self.poll_ns = imu, clock, listener, poll_ns
        self.samples: list[ImuSample] = []
        self._silent_since: int | None = None

    def next(self) -> ImuSample:
        """The next sample (waits for it); a silent IMU ends the procedure."""
        while True:
            s = self.imu.read()
            if s is not None:
                self._silent_since = None
                self.samples.append(s)
                self.listener.record(s)
                return s
            now = self.clock.now_ns()
            if self._silent_since is None:
                self._silent_since = now
            elif now - self._silent_since > 2_000_000_000:
                raise CalibrationError("the IMU sends nothing (or the recording ended)")
            self.clock.sleep_until(now + self.poll_ns)

    def until(self, t_ns: int) -> None:
        """Read until a sample at or after ``t_ns`` has come."""
        while not self.samples or self.samples[-1].sensor_ns < t_ns:
            self.next()

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Sensor times (n,) ns, gyro (n, 3) and accel (n, 3) of every sample."""
        t = np.array([s.sensor_ns for s in self.samples], np.float64)
        g = np.array([s.gyro for s in self.samples], np.float64).reshape(-1, 3)
        a = np.array([s.accel for s in self.samples], np.float64).reshape(-1, 3)
        return t, g, a

    def window(self, t0: int, t1: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Sensor times (n,) ns, gyro (n, 3) and accel (n, 3) of the samples in
        ``[t0, t1]`` ns."""
        t, g, a = self.arrays()
        k = (t >= t0) & (t <= t1)
        return t[k], g[k], a[k]


@dataclass(frozen=True)
class PoseCapture:
    """One pose: its pairs, depth, decode (without the per-bit differences), and the
    IMU at rest."""

    index: int
    pairs: Pairs
    depth_m: FloatArray
    decoded: Decoded
    normals: FloatArray
    gyro_bias: FloatArray
    accel: FloatArray
    start_ns: int
    end_ns: int
    turn: FloatArray


@dataclass
class CaptureRun:
    """Everything captured: the poses, the IMU, the camera's intrinsics, the plan."""

    poses: list[PoseCapture]
    imu_t: FloatArray
    imu_gyro: FloatArray
    camera_K: FloatArray
    camera_size: tuple[int, int]
    plan: Plan | None
    retakes: int = 0
    response: Response | None = None
    photometric_note: str = ""


def _summary(p: PoseCapture) -> PoseSummary:
    return PoseSummary(p.pairs.projector_uv, p.pairs.points, p.normals, p.turn)


def _wait_still(log: ImuLog, s: ProcedureSettings, need_motion: bool) -> int:
    """Read the IMU until the device has moved (if ``need_motion``) and then stood
    still for ``still_s``; the sensor time of the last sample."""
    start: int | None = None
    moved = not need_motion
    window_ns = int(s.still_s * 1e9)
    recent: list[ImuSample] = []
    while True:
        smp = log.next()
        if start is None:
            start = smp.sensor_ns
        if smp.sensor_ns - start > s.settle_timeout_s * 1e9:
            what = "hold still" if moved else "move to a new pose and hold it"
            raise CalibrationError(
                f"the device did not {what} within {s.settle_timeout_s:.0f} s: rest it on "
                "something steady for each pose"
            )
        recent.append(smp)
        recent = [r for r in recent if r.sensor_ns >= smp.sensor_ns - window_ns]
        short = [r for r in recent if r.sensor_ns >= smp.sensor_ns - 200_000_000]
        if len(short) >= 8 and not _still(short):
            moved = True
            recent = short
            continue
        if moved and recent[-1].sensor_ns - recent[0].sensor_ns >= 0.95 * window_ns:
            if _still(recent):
                return smp.sensor_ns


def _still(samples: list[ImuSample]) -> bool:
    return is_still(np.array([x.gyro for x in samples]), np.array([x.accel for x in samples]))


def _average_depth(frames: list[DepthFrame]) -> FloatArray:
    """Per-pixel median of the valid depths (metres, NaN where most frames had none)."""
    z = np.sort(np.stack([f.metres() for f in frames]), axis=0)  # NaN sorts last
    n = np.sum(np.isfinite(z), axis=0)
    lo = np.take_along_axis(z, np.maximum((n - 1) // 2, 0)[None], 0)[0]
    hi = np.take_along_axis(z, np.maximum(n // 2, 0)[None], 0)[0]
    return np.where(n * 2 > len(frames), (lo + hi) / 2, np.nan)


def _capture_turn_deg(log: ImuLog, t0: int, t1: int) -> float:
    """How far the device turned away during a capture (degrees): the largest angle of
    the gyro integrated from the start, its bias taken as its mean over the capture
    (a turn and back shows, a still device's noise does not); infinite when a short
    window was not still."""
    t, g, a = log.window(t0, t1)
    if len(t) < 8:
        return 0.0
    for k in range(0, len(t), 20):
        sel = (t >= t[k]) & (t < t[k] + 200_000_000)
        if sel.sum() >= 8 and not is_still(g[sel], a[sel]):
            return float("inf")
    dt = np.diff(t, prepend=t[0]) * 1e-9
    angle = np.cumsum((g - g.mean(axis=0)) * dt[:, None], axis=0)  # small angles
    return float(np.degrees(np.linalg.norm(angle, axis=1).max()))


def _check(dec: Decoded, s: ProcedureSettings, pose: int) -> str:
    """What makes captures useless ("" when nothing does): nothing decoded ends the
    procedure at once; saturation and ambient light may pass at another pose (the
    user is told what to change)."""
    if dec.lit_fraction < s.min_lit_fraction or dec.signal < s.min_signal / 2:
        raise CalibrationError(
            f"pose {pose + 1}: nothing decodes — the camera sees no projected patterns. Is the "
            "projector on and its lens cap off, and does the camera look at the projected "
            "image?"
        )
    if dec.saturated_fraction > s.max_saturated:
        return (
            f"pose {pose + 1}: the captures are saturated ({100 * dec.saturated_fraction:.0f} % "
            "of the lit pixels are pure white): move further from the wall, or lower "
            "exposure_us or iso in the board's [calibrate] section"
        )
    if dec.ambient_ratio > s.max_ambient_ratio or dec.signal < s.min_signal:
        return (
            f"pose {pose + 1}: too much ambient light (the dark pattern is "
            f"{100 * dec.ambient_ratio:.0f} % as bright as the lit one, contrast "
            f"{dec.signal:.0f} grey levels): dim the room or raise exposure_us"
        )
    return ""


def _capture_one(
    dev: Devices,
    log: ImuLog,
    patterns: PatternSet,
    cam: CameraSettings,
    s: ProcedureSettings,
    listener: Listener,
    pose: int,
    t_start: int,
) -> tuple[list[CameraFrame], list[DepthFrame]]:
    """The depth frames and one camera frame per pattern, from ``t_start`` on."""
    depth: list[DepthFrame] = []
    while len(depth) < s.depth_frames:
        f = dev.depth.read()
        if f is None:
            raise CalibrationError("the depth camera sends nothing (or the recording ended)")
        if f.sensor_ns >= t_start:
            depth.append(f)
            listener.record(f)
    frames = [
        capture_frame(dev, cam, listener, pose, p.index, p.name, patterns.frame(p.index))
        for p in patterns.patterns
    ]
    return frames, depth


def capture_frame(
    dev: Devices, cam: CameraSettings, listener: Listener, pose: int, index: int, name: str,
    frame: Image,
) -> CameraFrame:  # fmt: skip
    """Show ``frame`` and take the first camera frame exposed after it is on the wall."""
    wait_ns = cam.display_latency_ns + int(cam.camera_latency_ms * 1e6) + 10 * cam.frame_ns
    t_show = dev.show.show(pose, index, name, frame)
    while True:
        fr = dev.camera.read()
        if fr is None or dev.clock.now_ns() - t_show > max(wait_ns, 2_000_000_000):
            raise CalibrationError("the camera sends no frames (or the recording ended)")
        if fr.sensor_ns >= t_show + cam.display_latency_ns:
            listener.record(fr)
            return fr


def _photometric(
    dev: Devices,
    cam: CameraSettings,
    listener: Listener,
    pose: int,
    first: int,
    frames: list[CameraFrame],
    dec: Decoded,
    size: tuple[int, int],
) -> tuple[Response | None, str]:
    """The three primaries captured after pose ``pose``'s patterns (indices from
    ``first``) and the surface's response measured with its black and white; None and
    the reason when the captures are refused (the calibration goes on without)."""
    prim = [
        capture_frame(dev, cam, listener, pose, first + j, name, primary_frame(j, size)).image
        for j, (name, _) in enumerate(PRIMARY_FRAMES)
    ]
    try:
        response = measure_pose(frames[0].image, frames[1].image, prim, dec, size)
    except CalibrationError as e:
        said = f"the surface's colour was not measured: {e}"
        listener.say("photometric", said)
        return None, said
    listener.say(
        "photometric", f"pose {pose + 1}: the surface's colour and the room's light measured"
    )
    return response, ""


def capture_poses(
    dev: Devices,
    cam: CameraSettings,
    listener: Listener,
    settings: ProcedureSettings | None = None,
    projector_size: tuple[int, int] = (1280, 800),
    R_P_I: FloatArray | None = None,
) -> CaptureRun:
    """Run the procedure; the poses captured (see the module's description).

    ``R_P_I`` (the nominal one) only serves to tell turns up/down from left/right.

    Raises
    ------
    CalibrationError
        Captures that cannot work, a device that never holds still, a silent sensor.
    """
    s = settings or ProcedureSettings()
    patterns = PatternSet(*projector_size)
    K = np.asarray(dev.camera.intrinsics, np.float64)
    log = ImuLog(dev.imu, dev.clock, listener, 2_000_000)
    poses: list[PoseCapture] = []
    plan: Plan | None = None
    retakes = total_retakes = 0
    response: Response | None = None
    note, measured = "", False
    while len(poses) < s.max_poses:
        k = len(poses)
        if k == 0:
            listener.say(
                "hold", "pose 1: aim at a wall corner (or a wall and the floor), hold still"
            )
        elif retakes == 0:
            assert plan is not None
            listener.say("move", f"pose {k + 1}: {plan.advice}; then hold still")
        t_start = _wait_still(log, s, need_motion=k > 0 and retakes == 0)
        listener.say("capture", f"pose {k + 1}: capturing, keep still")
        frames, depth = _capture_one(dev, log, patterns, cam, s, listener, k, t_start)
        t_end = frames[-1].sensor_ns + frames[-1].exposure_us * 1000
        log.until(t_end)
        moved_deg = _capture_turn_deg(log, t_start, t_end)
        if moved_deg > s.max_capture_turn_deg:
            retakes += 1
            total_retakes += 1
            if retakes > s.max_retakes:
                raise CalibrationError(
                    f"pose {k + 1}: the device moved during the capture {retakes} times: rest "
                    "it on something steady"
                )
            listener.say(
                "retake", f"pose {k + 1}: the device moved during the capture; hold it still"
            )
            continue
        dec = decode([f.image for f in frames], patterns, s.decode)
        problem = _check(dec, s, k)
        if problem:
            retakes += 1
            total_retakes += 1
            if retakes > s.max_retakes:
                raise CalibrationError(problem)
            listener.say("retake", f"{problem}; taking pose {k + 1} again")
            continue
        retakes = 0
        z = _average_depth(depth)
        pairs = pose_pairs(dec, z, K, k, s.pairs)
        _, gw, aw = log.window(t_start, t_end)
        bias: FloatArray = np.mean(gw, axis=0)  # the mean: noise dithers the quantisation
        turn: FloatArray = np.zeros(3)
        if poses:
            a = poses[-1]
            t, g, _ = log.arrays()
            Rt = integrate_gyro(
                t, g, (a.start_ns + a.end_ns) // 2, (t_start + t_end) // 2, a.gyro_bias, bias
            )
            turn = (np.eye(3) if R_P_I is None else R_P_I) @ rotation_vector(Rt)
        poses.append(
            PoseCapture(
                k,
                pairs,
                z,
                replace(dec, diff_x=dec.diff_x[:0], diff_y=dec.diff_y[:0]),  # (megabytes)
                scene_planes(z, _depth_K(K, dev.camera.size, z.shape)),
                bias,
                np.mean(aw, axis=0),
                t_start,
                t_end,
                turn,
            )
        )
        if s.photometric and not measured:
            measured = True
            response, note = _photometric(
                dev, cam, listener, k, len(patterns), frames, dec, projector_size
            )
        plan = assess([_summary(p) for p in poses], projector_size, s.plan)
        listener.say("captured", f"pose {k + 1}: {len(pairs)} point pairs; {plan.status}")
        if plan.done:
            break
    t, g, _ = log.arrays()
    listener.say("done", f"{len(poses)} poses captured; solving")
    return CaptureRun(poses, t, g, K, dev.camera.size, plan, total_retakes, response, note)


def _depth_K(
    K_camera: FloatArray, camera_size: tuple[int, int], depth_shape: tuple[int, ...]
) -> FloatArray:
    """The depth image's intrinsics (same field of view as the camera)."""
    w, h = camera_size
    return DepthCameraModel(K_camera, w, h).intrinsics_at(depth_shape[1], depth_shape[0])
