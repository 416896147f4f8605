"""A simulated device for ``adaproj calibrate``: projector, camera, depth and IMU of a
*true* rig in front of a surface, and a user who moves it between poses.

The devices implement the ``hal`` protocols on a virtual clock, so the calibration
procedure (:func:`~adaproj_edge.procam.procedure.capture_poses`) drives them exactly
as it drives the OAK-D, the framebuffer and the LSM6DSOX:

- :class:`SimDisplay` keeps what was shown when; the light reaches the wall
  ``display_latency_ms`` later (the rig's own latency, which the board's setting
  may overstate);
- :class:`SimCamera` renders what the depth-aligned camera sees
  (:mod:`~adaproj_edge.session.scene_render`) at 30 fps, a DepthAI-like queue of 4
  frames, time-stamped at the start of the exposure;
- :class:`SimDepth` gives depth frames through the stereo error model
  (:func:`~adaproj_edge.session.stereo.stereo_depth`), 15 fps;
- :class:`SimImu` gives LSM6DSOX-like samples (noise, biases, quantisation) of the
  device's motion, rotated into the true rig's IMU frame.

:class:`SimUser` listens to what the procedure says: told to move, it moves the
device (a minimum-jerk move, 1.5 s) to the next of its ``stops`` and holds it there
(resting: no tremor). Faults for the bad-input tests: a projector that shows
nothing, a user who shakes the device during a capture, a camera exposed too long.

:func:`simulate_calibration` runs the procedure on them and records the session
(every record the procedure keeps), with the *nominal* calibration as the session's
calibration and the true rig as ground truth (``truth-calibration.json``).
Everything follows from the seed.

This file is about 540 lines on purpose: the simulated devices share one world
(:class:`SimWorld`: the true rig's pose on the virtual clock, the scene, the light)
and only make sense together; the rendering of a camera image is in
:mod:`~adaproj_edge.session.scene_render`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.geometry.mesh_surface import MeshSurface
from adaproj_edge.hal.camera import CameraFrame, CameraSettings, FixedCamera
from adaproj_edge.hal.clock import VirtualClock
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.display import DEFAULT_REFRESH_HZ, RefreshTimer
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.lsm6dsox import Lsm6dsoxConfig
from adaproj_edge.session import schemas
from adaproj_edge.session.codec import Record
from adaproj_edge.session.hand import HandMotion, _min_jerk
from adaproj_edge.session.scene_render import (
    CameraOptics,
    LitView,
    Paint,
    clean_capture,
    expose,
    lit_view,
    noise_sigma,
)
from adaproj_edge.session.simulator import (
    MESH_ATTACHMENT,
    T0_NS,
    ImuNoise,
    Scene,
    _pose,
    _quantise,
)
from adaproj_edge.session.stereo import StereoNoise, stereo_depth
from adaproj_edge.session.writer import SessionWriter

MOVE_S = 1.5
REACTION_S = 0.6
IMU_AHEAD_S = 0.25  # below REACTION_S: the path is settled that far ahead

# Stops for a scene in front of the device at 1.3-2 m: (tx, ty, tz, rx, ry, rz),
# metres and rotation vector (radians) in W. Distances vary by ~1.6x; the turns from
# one stop to the next are left/right and up/down in turn (and a little roll).
STOPS = np.array(
    [
        [0.00, 0.00, 0.00, 0.00, 0.00, 0.00],
        [0.12, 0.04, 0.45, 0.04, -0.22, 0.03],
        [-0.18, -0.05, -0.35, 0.24, -0.18, -0.04],
        [0.08, 0.10, 0.30, 0.10, 0.16, 0.05],
        [-0.10, -0.10, -0.15, -0.16, 0.10, -0.03],
        [0.02, 0.05, 0.60, -0.05, -0.12, 0.06],
        [0.15, -0.04, 0.15, 0.18, 0.06, 0.00],
        [-0.05, 0.08, -0.25, -0.10, 0.24, -0.05],
    ]
)


@dataclass(frozen=True)
class StopPath(HandMotion):
    """A device resting at a stop until told to move, then moving to the next one.

    ``stops`` (n, 6) holds translation and rotation vector of each stop; ``moves``
    (a list the user appends to) holds ``(t_start_s, from_state, to_state)`` of each
    move, in order. The path holds still between moves (no tremor: the device rests).
    """

    stops: FloatArray = field(default_factory=lambda: STOPS[:1].copy())
    moves: list[tuple[float, FloatArray, FloatArray]] = field(default_factory=list)
    move_s: float = MOVE_S

    def state(self, t: FloatArray) -> FloatArray:
        """Translation and rotation vector (N, 6) at times ``t`` (N,) seconds: the first stop,
        then each move's minimum-jerk path from its start."""
        t = np.asarray(t, dtype=np.float64)
        x = np.broadcast_to(self.stops[0], (len(t), 6)).copy()
        for t0, a, b in self.moves:
            s = _min_jerk((t - t0) / self.move_s)[:, None]
            after = (t >= t0)[:, None]
            x = np.where(after, a + s * (b - a), x)
        return x

    def current(self) -> FloatArray:
        """The state the device rests at (or moves to) after the last move."""
        return self.moves[-1][2] if self.moves else self.stops[0]


@dataclass(frozen=True)
class SimFaults:
    """Bad input: the projector shows nothing (``projector_off``); the user shakes the
    device during the first capture of pose ``shake_pose`` (0-based); the camera is
    exposed ``exposure_scale`` times longer than set."""

    projector_off: bool = False
    shake_pose: int | None = None
    exposure_scale: float = 1.0


@dataclass(frozen=True)
class CalibrationSimSettings:
    """What to simulate."""

    poses: int = 5
    seed: int = 0
    camera: CameraSettings = field(default_factory=lambda: CameraSettings(width=640, height=400))
    display_latency_ms: float = 70.0
    optics: CameraOptics = field(default_factory=lambda: CameraOptics(supersample=2))
    stereo: StereoNoise = field(default_factory=StereoNoise)
    imu: Lsm6dsoxConfig = field(default_factory=Lsm6dsoxConfig)
    imu_noise: ImuNoise = field(default_factory=ImuNoise)
    depth_fps: float = 15.0
    faults: SimFaults = field(default_factory=SimFaults)
    stops: FloatArray | None = None
    photometric: bool = False
    albedo: NDArray[np.float32] | None = None
    """The surface's colour (H, W, 3, blue-green-red reflectance in [0, 1]) as the true
    projector sees it from the first stop (a :class:`~adaproj_edge.session.scene_render.Paint`);
    None: the procedural grey texture of ``optics``."""


class SimWorld:
    """The true rig, the scene, the path, the clock and what the display shows."""

    def __init__(
        self, scene: Scene, rig: Calibration, settings: CalibrationSimSettings, stops: FloatArray
    ) -> None:
        self.scene, self.rig, self.settings = scene, rig, settings
        self.clock = VirtualClock(T0_NS)
        self.rng = np.random.default_rng(settings.seed)
        self.path = StopPath(seconds=0.0, seed=settings.seed, stops=np.asarray(stops, float))
        self.shown: list[tuple[int, int, Image]] = []  # (time on the wall, id, frame)
        self.paint: Paint | None = None
        if settings.albedo is not None:
            size = (rig.projector.height, rig.projector.width, 3)
            if settings.albedo.shape != size:
                raise InputError(f"the albedo is {settings.albedo.shape}, not the frame's {size}")
            R0, t0 = self.pose(T0_NS)
            self.paint = Paint(settings.albedo, R0, t0, rig.projector.K, rig.distortion)

    def pose(self, t_ns: int) -> tuple[FloatArray, FloatArray]:
        """``R_W_P`` (3, 3), ``t_W_P`` (3,) at ``t_ns``."""
        R, p = self.path.pose(np.array([(t_ns - T0_NS) * 1e-9]))
        return R[0], p[0]

    def on_wall(self, t_ns: int) -> tuple[int, Image | None]:
        """The frame lighting the wall at ``t_ns`` (id -1 and None: nothing yet)."""
        out: tuple[int, Image | None] = (-1, None)
        for t, i, f in self.shown:
            if t > t_ns:
                break
            out = (i, f)
        return out


def pose_key(R: FloatArray, t: FloatArray) -> bytes:
    """A key (bytes) equal for equal poses (``R`` (3, 3), ``t`` (3,), rounded to 1e-9):
    what is rendered at a pose is kept while the device rests there."""
    return np.round(np.r_[R.ravel(), t], 9).tobytes()


class SimDisplay:
    """The projector: shows frames, which reach the wall after the rig's latency."""

    def __init__(self, world: SimWorld, width: int, height: int) -> None:
        self.world, self._size = world, (width, height)
        self._timer = RefreshTimer(world.clock, DEFAULT_REFRESH_HZ)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self._size

    @property
    def refresh_hz(self) -> float:
        """The refresh rate, Hz."""
        return self._timer.refresh_hz

    def wait_refresh(self) -> int:
        """Wait for the next refresh (virtual); its time, ns."""
        return self._timer.wait()

    def show(self, frame: Image) -> None:
        """Queue a (height, width, 3) BGR frame to reach the wall after the display
        latency (grey when its channels are equal; the camera weighs a colour frame's
        primaries after the projector's gamma)."""
        w = self.world
        lat = int(w.settings.display_latency_ms * 1e6)
        if frame.ndim == 3 and frame.strides[2] == 0:  # one grey value per pixel
            kept: Image = np.array(frame[..., 0])
        elif frame.ndim == 3 and not (
            np.array_equal(frame[..., 0], frame[..., 1])
            and np.array_equal(frame[..., 1], frame[..., 2])
        ):
            kept = np.array(frame)
        else:
            kept = np.asarray(cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_BGR2GRAY))
        w.shown.append((w.clock.now_ns() + lat, len(w.shown), kept))

    def close(self) -> None:
        """Nothing to release."""
        pass


class _Queue:
    """DepthAI-like output queue of frames at ``fps`` (newest 4 kept, blocking get)."""

    def __init__(self, world: SimWorld, fps: float, phase_s: float, latency_ns: int) -> None:
        self.world, self.period = world, round(1e9 / fps)
        self.t0 = T0_NS + int(phase_s * 1e9)
        self.latency = latency_ns
        self.next = 0

    def take(self) -> tuple[int, int, int]:
        """(sequence, sensor_ns, receive_ns) of the next frame; waits for it."""
        now = self.world.clock.now_ns()
        newest = (now - self.latency - self.t0) // self.period
        k = max(self.next, newest - 3)
        sensor = self.t0 + k * self.period
        receive = sensor + self.latency
        self.world.clock.advance_to(receive)
        self.next = k + 1
        return int(k), int(sensor), int(receive)


class SimCamera(FixedCamera):
    """The depth-aligned camera: renders the scene lit by what the display shows."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        cam = world.settings.camera
        super().__init__(
            world.rig.depth.intrinsics_at(cam.width, cam.height), (cam.width, cam.height)
        )
        latency = int(cam.camera_latency_ms * 1e6) + int(cam.exposure_us * 1e3)
        self._queue = _Queue(world, cam.fps, 0.0123, latency)
        self._view: tuple[bytes, LitView] | None = None
        # per frame shown, in the current view: the clean image and its noise
        self._clean: dict[int, tuple[NDArray[np.float32], NDArray[np.float32]]] = {}

    def _lit(self, t_ns: int) -> tuple[bytes, LitView]:
        w = self.world
        R, p = w.pose(t_ns)
        key = pose_key(R, p)
        if self._view is None or self._view[0] != key:
            self._clean.clear()
            view = lit_view(w.scene, w.rig, R, p, self._K, self._size, w.settings.optics,
                            w.rig.distortion, w.paint)  # fmt: skip
            self._view = (key, view)
        return self._view

    def read(self) -> CameraFrame | None:
        """The next frame: the scene lit by what is on the wall at mid-exposure, with sensor
        noise (the projector dark when ``projector_off``)."""
        w = self.world
        cam = w.settings.camera
        seq, sensor, receive = self._queue.take()
        exposure_ns = int(cam.exposure_us * 1e3)
        _, view = self._lit(sensor + exposure_ns // 2)
        fid, frame = w.on_wall(sensor + exposure_ns // 2)
        if w.settings.faults.projector_off:
            fid, frame = -1, None
        optics = w.settings.optics
        if fid not in self._clean:
            exposure = int(cam.exposure_us * w.settings.faults.exposure_scale)
            clean = clean_capture(view, frame, optics, exposure, cam.iso)
            self._clean[fid] = (clean, noise_sigma(clean, optics))
        clean, sigma = self._clean[fid]
        image = expose(clean, optics, w.rng, sigma)
        return CameraFrame(sensor, receive, seq, image, cam.exposure_us, cam.iso)


class SimDepth:
    """The OAK-D's stereo depth of the scene, through the stereo error model."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self._queue = _Queue(world, world.settings.depth_fps, 0.031, 35_000_000)
        self._points: tuple[bytes, FloatArray] | None = None  # of the last pose

    @property
    def model(self) -> DepthCameraModel:
        """The true rig's depth camera model."""
        return self.world.rig.depth

    def read(self) -> DepthFrame | None:
        """The next depth frame: the scene seen from the pose at its sensor time, through the
        stereo error model."""
        w = self.world
        seq, sensor, receive = self._queue.take()
        R, p = w.pose(sensor)
        T, d = w.rig.T_P_D, w.rig.depth
        key = pose_key(R, p)
        if self._points is None or self._points[0] != key:  # the device rests between moves
            pts = w.scene.points_seen(d.K, d.width, d.height, R @ T[:3, :3], R @ T[:3, 3] + p)
            self._points = (key, pts)
        depth = stereo_depth(self._points[1], d, w.settings.stereo, w.rng)
        return DepthFrame(sensor, receive, seq, depth)

    def close(self) -> None:
        """Nothing to release."""
        pass


class SimImu:
    """LSM6DSOX-like samples of the device's motion in the true rig's IMU frame.

    Samples are made in blocks reaching :data:`IMU_AHEAD_S` past the clock's time and
    handed out when due: the path is settled that far ahead (a move the user is told
    to make starts :data:`REACTION_S` after it is heard, a shake later still)."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        s = world.settings
        self.dt_ns = round(1e9 / s.imu.rate_hz)
        n = s.imu_noise
        rng = np.random.default_rng(s.seed + 1)
        self.accel_bias = rng.normal(scale=n.accel_bias_sigma, size=3)
        self.gyro_bias = rng.normal(scale=n.gyro_bias_sigma, size=3)
        self.k = 0
        self._ready: list[ImuSample] = []  # made; those from ``_next`` on not yet read
        self._next = 0

    def _make(self, k1: int) -> None:
        """Samples ``self.k`` to ``k1 - 1``."""
        w = self.world
        s = w.settings
        ks = np.arange(self.k, k1)
        t = T0_NS + ks * self.dt_ns
        f_p, w_p = w.path.imu_truth(((t - T0_NS) * 1e-9).astype(np.float64))
        R_I_P = w.rig.R_P_I.T
        accel_sigma, gyro_sigma = s.imu_noise.sigmas(s.imu.rate_hz)
        acc = f_p @ R_I_P.T + self.accel_bias + w.rng.normal(scale=accel_sigma, size=f_p.shape)
        gyr = w_p @ R_I_P.T + self.gyro_bias + w.rng.normal(scale=gyro_sigma, size=w_p.shape)
        acc = _quantise(acc, s.imu.accel_scale)
        gyr = _quantise(gyr, s.imu.gyro_scale)
        for i, ti in enumerate(t):
            a, g = acc[i], gyr[i]
            self._ready.append(
                ImuSample(
                    int(ti),
                    int(ti) + 400_000,
                    (float(a[0]), float(a[1]), float(a[2])),
                    (float(g[0]), float(g[1]), float(g[2])),
                    30.0,
                )
            )
        self.k = k1

    def read(self) -> ImuSample | None:
        """The oldest sample not yet read, if it is due by the clock's time; None when none
        is."""
        now = self.world.clock.now_ns()
        if self._next >= len(self._ready):
            due = (now - 400_000 - T0_NS) // self.dt_ns + 1
            if due <= self.k:
                return None
            self._ready, self._next = [], 0
            self._make(int(due) + round(IMU_AHEAD_S * 1e9) // self.dt_ns)
        sample = self._ready[self._next]
        if sample.receive_ns > now:
            return None
        self._next += 1
        return sample

    def close(self) -> None:
        """Nothing to release."""
        pass


class SimUser:
    """Hears the procedure and moves the device; forwards records to ``sink``."""

    def __init__(
        self,
        world: SimWorld,
        sink: Callable[[Record], None],
        tell: Callable[[str, str], None] | None = None,
    ) -> None:
        self.world, self.sink, self.tell = world, sink, tell
        self.stop = 0
        self.captures = 0
        self.shaken = False

    def say(self, event: str, message: str) -> None:
        """Hear the procedure's ``event``: on "move" start moving to the next stop, on
        "capture" record the true pose (and shake once when the faults say so)."""
        w = self.world
        if self.tell is not None:
            self.tell(event, message)
        now_s = (w.clock.now_ns() - T0_NS) * 1e-9
        if event == "move":
            self.stop += 1
            target = w.path.stops[self.stop % len(w.path.stops)]
            w.path.moves.append((now_s + REACTION_S, w.path.current().copy(), target.copy()))
        elif event == "capture":
            R, p = w.pose(w.clock.now_ns())
            self.sink(_pose(w.clock.now_ns(), R, p))
            if w.settings.faults.shake_pose == self.stop and not self.shaken:
                self.shaken = True  # a nudge 1 s into the capture, and back
                here = w.path.current().copy()
                nudge = here + np.r_[0.0, 0.0, 0.0, 0.0, 0.03, 0.0]
                w.path.moves.append((now_s + 1.0, here, nudge))
                w.path.moves.append((now_s + 1.0 + MOVE_S, nudge, here))

    def record(self, rec: Record) -> None:
        """Forward ``rec`` to the sink."""
        self.sink(rec)


def default_stops(scene: Scene, n: int, seed: int) -> FloatArray:
    """``n`` stops for ``scene``: the table :data:`STOPS` (cycled) with a little
    seeded jitter, after the scene's own start pose (``spec["start"]``, if any)."""
    rng = np.random.default_rng(seed + 2)
    base = np.asarray(scene.spec.get("start", np.zeros(6)), float)
    stops = np.array([STOPS[k % len(STOPS)] for k in range(max(n, 1))])
    stops[1:] *= 1 + 0.15 * rng.uniform(-1, 1, size=stops[1:].shape)
    return stops + base  # type: ignore[no-any-return]


@dataclass
class SimRig:
    """The simulated devices and their world."""

    world: SimWorld
    display: SimDisplay
    camera: SimCamera
    depth: SimDepth
    imu: SimImu


def sim_rig(scene: Scene, rig: Calibration, settings: CalibrationSimSettings) -> SimRig:
    """The simulated devices of ``rig`` (the truth) in front of ``scene``."""
    if settings.poses < 1 or settings.poses > 20:
        raise InputError(f"--poses must be 1..20, got {settings.poses}")
    stops = (
        settings.stops
        if settings.stops is not None
        else default_stops(scene, settings.poses + 1, settings.seed)
    )
    world = SimWorld(scene, rig, settings, stops)
    p = rig.projector
    return SimRig(world, SimDisplay(world, p.width, p.height), SimCamera(world), SimDepth(world),
                  SimImu(world))  # fmt: skip


def session_metadata(scene: Scene, settings: CalibrationSimSettings) -> dict[str, str]:
    """The session's ``metadata`` record: source, kind, surface spec, seed and poses."""
    return {
        "source": "simulator",
        "kind": "calibration",
        "surface": json.dumps({k: v for k, v in scene.spec.items() if k != "start"}),
        "seed": str(settings.seed),
        "poses": str(settings.poses),
    }


def camera_attachment(K: FloatArray, size: tuple[int, int]) -> dict[str, Any]:
    """The camera attachment: intrinsics ``K`` (3, 3) and frame size (width, height)."""
    return {"K": np.asarray(K).tolist(), "width": size[0], "height": size[1]}


def write_truth(w: SessionWriter, scene: Scene, truth: Calibration) -> None:
    """The ground truth attachments: the scene and the true rig."""
    w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, scene.spec, T0_NS)
    if isinstance(scene.surface, MeshSurface):
        from adaproj_edge.geometry.mesh_surface import ply_bytes

        w.attach(MESH_ATTACHMENT, "application/octet-stream", ply_bytes(scene.surface), T0_NS)
    w.attach(schemas.TRUTH_RIG_ATTACHMENT, "application/json", truth.to_json().encode(), T0_NS)


def simulate_calibration(
    scene: Scene,
    truth: Calibration,
    nominal: Calibration,
    out: str | os.PathLike[str],
    settings: CalibrationSimSettings | None = None,
    tell: Callable[[str, str], None] | None = None,
) -> int:
    """Run the calibration procedure on the simulated ``truth`` rig and record the
    session to ``out`` (written to a temporary name, renamed when complete); returns
    the number of records. The procedure's own refusals (projector off, saturated
    images, ...) end the recording where they happen; it is still written."""
    from adaproj_edge.errors import CalibrationError
    from adaproj_edge.procam.plan import PlanSettings
    from adaproj_edge.procam.procedure import Devices, LiveShow, ProcedureSettings, capture_poses

    s = settings or CalibrationSimSettings()
    sim = sim_rig(scene, truth, s)
    tmp = Path(out).with_name(Path(out).name + ".part")
    with SessionWriter(tmp, nominal, session_metadata(scene, s), T0_NS) as w:
        write_truth(w, scene, truth)
        w.attach_json(
            schemas.CAMERA_ATTACHMENT,
            camera_attachment(sim.camera.intrinsics, sim.camera.size),
            T0_NS,
        )
        w.attach_json(
            schemas.CAPTURE_ATTACHMENT, capture_settings(s.camera, s.poses, s.poses), T0_NS
        )
        user = SimUser(sim.world, w.write, tell)
        devices = Devices(
            LiveShow(sim.display, sim.world.clock, user), sim.camera, sim.depth, sim.imu,
            sim.world.clock,
        )  # fmt: skip
        procedure = ProcedureSettings(
            max_poses=s.poses, plan=PlanSettings(min_poses=s.poses), photometric=s.photometric
        )
        p = nominal.projector
        try:
            capture_poses(devices, s.camera, user, procedure, (p.width, p.height), nominal.R_P_I)
        except CalibrationError as e:
            if tell is not None:
                tell("error", str(e))
        n = w.count
    os.replace(tmp, out)
    return n


def capture_settings(camera: CameraSettings, max_poses: int, min_poses: int) -> dict[str, Any]:
    """The ``capture.json`` attachment of a calibration session: the board's camera
    settings and the pose counts the procedure ran with (a replay runs with them)."""
    from dataclasses import asdict

    return {"camera": asdict(camera), "max_poses": max_poses, "min_poses": min_poses}


def perturbed_rig(
    nominal: Calibration,
    focal: float = 0.03,
    principal_px: tuple[float, float] = (15.0, 300.0),
    T_P_D_deg: float = 2.0,
    T_P_D_mm: float = 15.0,
    R_P_I_deg: float = 5.0,
    seed: int = 0,
) -> Calibration:
    """A true rig off ``nominal`` by the given amounts: focal lengths times
    ``1 + focal``, the principal point moved by ``principal_px``, ``T_P_D`` turned by
    ``T_P_D_deg`` and moved by ``T_P_D_mm`` and ``R_P_I`` turned by ``R_P_I_deg``, about
    and along directions drawn from ``seed``."""
    from adaproj_edge.geometry.projector import Projector
    from adaproj_edge.geometry.rotations import rotation_matrix

    rng = np.random.default_rng(seed)

    def unit() -> FloatArray:
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    K = nominal.projector.K.copy()
    K[0, 0] *= 1 + focal
    K[1, 1] *= 1 + focal
    K[0, 2] += principal_px[0]
    K[1, 2] += principal_px[1]
    T = nominal.T_P_D.copy()
    T[:3, :3] = rotation_matrix(unit() * np.radians(T_P_D_deg)) @ T[:3, :3]
    T[:3, 3] += unit() * T_P_D_mm / 1000
    R = rotation_matrix(unit() * np.radians(R_P_I_deg)) @ nominal.R_P_I
    p = nominal.projector
    return Calibration(Projector(K, p.width, p.height), nominal.depth, T, R)
