"""The session simulator: a virtual device, held in a hand, in front of a surface.

The surface is a built-in analytic one (``adaproj_edge.geometry.analytic.SURFACES``)
or any triangle mesh (``.obj``/``.ply``, metres, in the projector frame at t = 0).
The simulator writes a normal session (depth frames, IMU samples, button presses)
plus the ground truth on channels of its own: ``/truth/pose`` (T_W_P at every IMU
sample and depth frame: at 416 Hz, so the pose at any instant, e.g. when a displayed
frame is lit, is interpolated to well under a microradian), the ``truth-surface.json``
attachment (with the mesh file for meshes) and, in the session metadata, the hand's
intent (``hand``: still phases, tremor, sway, roll; :data:`HAND_KEY`), so tests can
score what the device estimates and shows. IMU samples arrive as the driver reads the
chip's FIFO: in batches every ``ImuTiming.read_period_s``. The recorded calibration
carries the accelerometer's offset as the device's own calibration would have measured
it (``SimulationSettings.accel_calibrated``, :func:`recorded_calibration`). Everything
follows from the seed: the same arguments give the same file.

Given a ``truth`` rig, the world follows it (depth seen through its ``T_P_D``, the
IMU turned by its ``R_P_I``, the true projector lighting the surface) while the
session records the ``calibration`` the device believes; the truth goes into the
``truth-calibration.json`` attachment, and :func:`scoring_projector` gives the
projector a ground-truth scorer must light the surface with.

Besides the analytic surfaces, ``wall-floor`` is a wall 2 m ahead and the floor
0.45 m below the device, seen from a device tilted 20 degrees down (``start``: its
first pose, for the calibration simulator), and the cluttered rooms of
:mod:`adaproj_edge.session.clutter` (objects in front of walls, a desk with a
partition).
"""

from __future__ import annotations

import functools
import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from adaproj_edge.arrays import FloatArray, IntArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import SURFACES, AnalyticSurface, get_surface, ray_cast
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.mesh_surface import MeshSurface, load_mesh, ply_bytes
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.rotations import quaternion, rotation_of
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.button import ButtonEvent
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.hal.imu import ImuSample
from adaproj_edge.hal.lsm6dsox import Lsm6dsoxConfig
from adaproj_edge.progress import Progress
from adaproj_edge.session import schemas
from adaproj_edge.session.accel_calibration import with_accel_offset
from adaproj_edge.session.clutter import CLUTTER
from adaproj_edge.session.codec import Record
from adaproj_edge.session.hand import GRAVITY_W, HandMotion
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.stereo import StereoNoise, default_noise, stereo_depth
from adaproj_edge.session.writer import SessionWriter

log = logging.getLogger(__name__)

T0_NS = 1_000_000_000
KEY_CODE = 28
MESH_ATTACHMENT = "truth-mesh.ply"
WALL_FLOOR = "wall-floor"


def wall_floor_mesh(wall_z: float = 2.0, floor_y: float = 0.45) -> MeshSurface:
    """A wall (``z = wall_z``) standing on a floor (``y = floor_y``, y is down), 6 m
    wide, metres in the frame of a level device at the origin."""
    v = np.array(
        [
            [-3.0, -2.5, wall_z], [3.0, -2.5, wall_z], [3.0, floor_y, wall_z],
            [-3.0, floor_y, wall_z], [-3.0, floor_y, 0.1], [3.0, floor_y, 0.1],
        ]
    )  # fmt: skip
    return MeshSurface(WALL_FLOOR, v, np.array([[0, 1, 2], [0, 2, 3], [3, 2, 5], [3, 5, 4]]))


SENSOR_KEY = "sensor"
"""Session metadata key of the depth noise model the frames were drawn from
(:attr:`StereoNoise.name`: ``oak-d``, ``kinect`` or ``smooth``)."""

HAND_KEY = "hand"
"""Session metadata key of the simulated hand's intent (JSON, :func:`hand_metadata`)."""


@dataclass(frozen=True)
class ImuNoise:
    """LSM6DSOX-like noise (DS12814 table 2: noise density, zero offsets).

    The per-sample noise is the density times the square root of half the rate (the
    bandwidth): 0.008 m/s^2 and 0.0007 rad/s at 208 Hz. The accelerometer's offset
    tilts the gravity estimate directly (0.1 m/s^2 is 0.6 degrees): a unit whose offset
    was calibrated keeps about 0.02 m/s^2 (2 mg), ``accel_offset_drift``
    (:mod:`~adaproj_edge.session.accel_calibration`).
    """

    accel_density: float = 7.8e-4  # m/s^2/sqrt(Hz) (~80 ug/sqrt(Hz))
    gyro_density: float = 6.9e-5  # rad/s/sqrt(Hz) (~3.8 mdps/sqrt(Hz))
    accel_bias_sigma: float = 0.1  # m/s^2 (~10 mg)
    gyro_bias_sigma: float = 0.005  # rad/s (~0.3 dps)
    accel_offset_drift: float = 0.02  # m/s^2: the offset's move since its calibration

    def sigmas(self, rate_hz: float) -> tuple[float, float]:
        """Per-sample accelerometer (m/s^2) and gyro (rad/s) noise at ``rate_hz``."""
        k = float(np.sqrt(rate_hz / 2))
        return self.accel_density * k, self.gyro_density * k


@dataclass(frozen=True)
class ImuTiming:
    """When IMU samples reach the host: the driver reads the chip's FIFO every
    ``read_period_s`` (a batch), each read taking ``read_s`` plus ``per_sample_s`` per
    sample on the bus."""

    read_period_s: float = 0.0025
    read_s: float = 0.0002
    per_sample_s: float = 0.00005


@dataclass(frozen=True)
class SimulationSettings:
    """What to simulate; ``presses`` are times (s) of button presses (None: two);
    ``stereo``: the depth sensor's noise model (by default an OAK-D's: depth steps,
    flying pixels, holes, occlusion bands; ``StereoNoise.named("smooth")`` for smooth
    noise only)."""

    seconds: float = 3.0
    depth_fps: float = 15.0
    seed: int = 0
    presses: tuple[float, ...] | None = None
    imu: Lsm6dsoxConfig = field(default_factory=Lsm6dsoxConfig)
    imu_noise: ImuNoise = field(default_factory=ImuNoise)
    imu_timing: ImuTiming = field(default_factory=ImuTiming)
    stereo: StereoNoise = field(default_factory=default_noise)
    motion: HandMotion | None = None
    accel_calibrated: bool = True  # the recorded calibration carries the accel offset

    def hand(self) -> HandMotion:
        """The hand motion to simulate: :attr:`motion`, or a hand path of ``seconds`` seeded
        with ``seed``."""
        return self.motion or HandMotion(self.seconds, self.seed)


@dataclass(frozen=True)
class Scene:
    """The surface in front of the device, and how to describe it in a session."""

    surface: AnalyticSurface | MeshSurface
    spec: dict[str, Any]

    @classmethod
    def load(cls, name_or_path: str) -> Scene:
        """A built-in surface by name, or a mesh file (``.obj``, ``.ply``)."""
        if name_or_path in SURFACES:
            return cls(get_surface(name_or_path), {"kind": "analytic", "name": name_or_path})
        if name_or_path == WALL_FLOOR:
            spec = {"kind": "mesh", "name": WALL_FLOOR, "file": MESH_ATTACHMENT}
            return cls(wall_floor_mesh(), {**spec, "start": [0.0, 0.0, 0.0, -0.35, 0.0, 0.0]})
        if name_or_path in CLUTTER:
            spec = {"kind": "mesh", "name": name_or_path, "file": MESH_ATTACHMENT}
            return cls(CLUTTER[name_or_path](), spec)
        if Path(name_or_path).suffix.lower() in (".obj", ".ply"):
            mesh = load_mesh(name_or_path)
            return cls(mesh, {"kind": "mesh", "name": mesh.name, "file": MESH_ATTACHMENT})
        raise InputError(
            f"unknown surface {name_or_path!r}: give a mesh file (.obj, .ply) or one of "
            + ", ".join([*SURFACES, WALL_FLOOR, *CLUTTER])
        )

    def points_seen(
        self, K: FloatArray, width: int, height: int, R_W_C: FloatArray, t_W_C: FloatArray
    ) -> FloatArray:
        """Points (height, width, 3) in the camera frame where its pixel rays meet the
        surface (NaN: nothing) for a camera with intrinsics ``K`` at pose (R_W_C, t_W_C).

        A mesh is cast in one call through its BVH (built once per scene); the rays
        have z = 1 in the camera frame, so the hit's ray parameter is its depth.
        """
        rays = pixel_rays(np.asarray(K, np.float64).tobytes(), int(width), int(height))
        return self._cast(rays, R_W_C, t_W_C)

    def depths_seen(
        self,
        K: FloatArray,
        width: int,
        height: int,
        R_W_C: FloatArray,
        t_W_C: FloatArray,
        pixels: IntArray,
    ) -> FloatArray:
        """Depths (N,) in the camera frame of the flat pixel indices ``pixels`` (N,)
        (``row * width + col``): the z of :meth:`points_seen` at those pixels (NaN:
        nothing), casting only their rays (a shadow map looked up at a few pixels)."""
        rays = pixel_rays(np.asarray(K, np.float64).tobytes(), int(width), int(height))
        z: FloatArray = self._cast(rays.reshape(-1, 3)[pixels], R_W_C, t_W_C)[:, 2]
        return z

    def _cast(self, rays: FloatArray, R_W_C: FloatArray, t_W_C: FloatArray) -> FloatArray:
        """Points (..., 3) in the camera frame where ``rays`` (..., 3, z = 1, camera
        frame) from a camera at pose (R_W_C, t_W_C) meet the surface (NaN: nothing)."""
        if isinstance(self.surface, MeshSurface):
            z = self.surface.intersect(np.asarray(t_W_C, dtype=np.float64), rays @ R_W_C.T)
            return rays * z[..., None]
        hits = ray_cast(self.surface, t_W_C, rays @ R_W_C.T)
        out: FloatArray = (hits - t_W_C) @ R_W_C
        return out


@functools.lru_cache(maxsize=4)
def pixel_rays(K: bytes, width: int, height: int) -> FloatArray:
    """The rays (height, width, 3), z = 1, of every pixel of a camera with intrinsics
    ``K`` (the bytes of its (3, 3) float64), read-only: kept for the next frame, as
    a session casts the same camera's pixels every frame."""
    p = Projector(np.frombuffer(K, np.float64).reshape(3, 3), width, height)
    rays = p.rays(p.pixel_grid())
    rays.flags.writeable = False
    return rays


def true_surface(
    scene: Scene, pose: TruthPose, projector: Projector, shape: tuple[int, int]
) -> Surface:
    """The exact Surface (lattice ``shape`` = (rows, cols)) seen from projector pose."""
    rows, cols = shape
    xs = np.linspace(0, projector.width - 1, cols)
    ys = np.linspace(0, projector.height - 1, rows)
    uv = np.stack(np.meshgrid(xs, ys), axis=-1)
    R = rotation_of(pose.quaternion)
    t = np.asarray(pose.position)
    dirs = projector.rays(uv) @ R.T
    tt = scene.surface.intersect(np.broadcast_to(t, dirs.shape), dirs)
    pts = (t + tt[..., None] * dirs - t) @ R
    return Surface(pts.astype(np.float32), projector, {"source": "truth", **scene.spec})


def _quantise(v: FloatArray, lsb: float) -> FloatArray:
    """What the chip reports: int16 counts of ``lsb``, saturating."""
    return np.clip(np.round(v / lsb), -32768, 32767) * lsb


def simulate(scene: Scene, calibration: Calibration, settings: SimulationSettings) -> list[Record]:
    """Every record of the simulated session, in receive order."""
    rng = np.random.default_rng(settings.seed)
    hand = settings.hand()
    recs: list[tuple[int, int, Record]] = []
    # --- IMU at its output data rate
    t_imu, acc, gyr = imu_readings(hand, calibration.R_P_I, settings, rng)
    R_all, p_all = hand.pose(t_imu)
    rx_all = _fifo_receive(t_imu, settings.imu_timing, rng)
    for i, t in enumerate(t_imu):
        ts = T0_NS + round(t * 1e9)
        rx = T0_NS + int(rx_all[i])
        a = (float(acc[i, 0]), float(acc[i, 1]), float(acc[i, 2]))
        g = (float(gyr[i, 0]), float(gyr[i, 1]), float(gyr[i, 2]))
        recs.append((rx, 1, ImuSample(ts, rx, a, g, 30.0)))
        recs.append((ts, 3, _pose(ts, R_all[i], p_all[i])))
    # --- depth frames
    d = calibration.depth
    T = calibration.T_P_D
    t_depth = np.arange(0.0, settings.seconds, 1.0 / settings.depth_fps) + 0.5 / settings.depth_fps
    R_d, p_d = hand.pose(t_depth)
    progress = Progress("depth frames simulated", len(t_depth), log)
    for k, t in enumerate(t_depth):
        progress.step(k)
        R_W_D = R_d[k] @ T[:3, :3]
        t_W_D = R_d[k] @ T[:3, 3] + p_d[k]
        pts = scene.points_seen(d.K, d.width, d.height, R_W_D, t_W_D)
        depth = stereo_depth(pts, d, settings.stereo, rng, pts @ R_W_D.T + t_W_D)
        ts = T0_NS + round(t * 1e9)
        rx = ts + 35_000_000 + int(rng.integers(0, 5_000_000))
        recs.append((rx, 0, DepthFrame(ts, rx, k, depth)))
        recs.append((ts, 3, _pose(ts, R_d[k], p_d[k])))
    # --- button presses (release 150 ms later)
    presses = settings.presses
    if presses is None:
        presses = (0.2, min(settings.seconds - 0.3, hand.still_s + hand.move_s + 0.2))
    for tp in presses:
        for dt_s, pressed in ((0.0, True), (0.15, False)):
            ts = T0_NS + round((tp + dt_s) * 1e9)
            rx = ts + 1_000_000
            recs.append((rx, 2, ButtonEvent(ts, rx, KEY_CODE, pressed)))
    recs.sort(key=lambda r: (r[0], r[1]))
    return [r for _, _, r in recs]


def recorded_calibration(calibration: Calibration, settings: SimulationSettings) -> Calibration:
    """The calibration a session of ``settings`` records: ``calibration`` with the
    accelerometer offset ``adaproj calibrate`` would have measured on the session's IMU
    (``settings.accel_calibrated``; :mod:`~adaproj_edge.session.accel_calibration`),
    else as it is."""
    if not settings.accel_calibrated:
        return calibration
    n = settings.imu_noise
    return with_accel_offset(
        calibration, settings.seed, n.accel_bias_sigma, n.sigmas(settings.imu.rate_hz)[0],
        settings.imu.accel_scale, n.accel_offset_drift, settings.imu.rate_hz,
    )  # fmt: skip


def imu_readings(
    hand: HandMotion, R_P_I: FloatArray, settings: SimulationSettings, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """What the IMU reports of ``hand``'s motion over ``settings.seconds``: sample times
    (N,) seconds, accelerometer (N, 3) m/s^2 and gyro (N, 3) rad/s in the IMU frame
    (noise, zero offsets drawn from ``rng`` and quantisation included; the
    accelerometer's offset is ``rng``'s first draw,
    :func:`~adaproj_edge.session.accel_calibration.session_accel_offset`)."""
    t_imu = np.arange(0.0, settings.seconds, 1.0 / settings.imu.rate_hz)
    f_p, w_p = hand.imu_truth(t_imu)
    R_I_P = np.asarray(R_P_I, dtype=np.float64).T
    n = settings.imu_noise
    accel_sigma, gyro_sigma = n.sigmas(settings.imu.rate_hz)
    acc = f_p @ R_I_P.T + rng.normal(scale=n.accel_bias_sigma, size=3)
    acc += rng.normal(scale=accel_sigma, size=acc.shape)
    gyr = w_p @ R_I_P.T + rng.normal(scale=n.gyro_bias_sigma, size=3)
    gyr += rng.normal(scale=gyro_sigma, size=gyr.shape)
    acc = _quantise(acc, settings.imu.accel_scale)
    gyr = _quantise(gyr, settings.imu.gyro_scale)
    return t_imu, acc, gyr


def _fifo_receive(t: FloatArray, timing: ImuTiming, rng: np.random.Generator) -> FloatArray:
    """Receive times (ns from the start) of samples taken at ``t`` (s): each batch is
    read at the first read after it, every sample of a batch arriving together."""
    period = timing.read_period_s
    phase = float(rng.uniform(0, period))
    reads = np.floor((t - phase) / period) + 1  # the read that takes each sample
    at = phase + reads * period
    batch = np.unique(reads, return_counts=True)[1]
    sizes = np.repeat(batch, batch)
    out: FloatArray = np.round((at + timing.read_s + timing.per_sample_s * sizes) * 1e9)
    return out


def hand_metadata(hand: HandMotion) -> dict[str, Any]:
    """What the session records of the hand (metadata ``hand``): its still phases
    (seconds from ``t0_ns``), tremor, sway and roll, and gravity in the world frame."""
    return {
        "still": [[round(a, 6), round(b, 6)] for a, b in hand.still_intervals()],
        "tremor_deg_rms": hand.tremor_deg,
        "sway_deg_rms": hand.sway_deg,
        "roll_deg": hand.roll_deg,
        "lever_m": hand.lever_m,
        "gravity_w": [float(x) for x in GRAVITY_W],
        "t0_ns": T0_NS,
    }


def _pose(t_ns: int, R: FloatArray, p: FloatArray) -> TruthPose:
    q = quaternion(R)
    return TruthPose(
        t_ns,
        (float(p[0]), float(p[1]), float(p[2])),
        (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
    )


def simulate_session(
    scene: Scene,
    out: str | os.PathLike[str],
    calibration: Calibration | None = None,
    settings: SimulationSettings | None = None,
    truth: Calibration | None = None,
) -> int:
    """Simulate and write a session file; returns the number of records.

    ``calibration`` is what the session records (the device's belief); the world
    follows ``truth`` when given (recorded as ``truth-calibration.json``)."""
    calibration = calibration or Calibration.default()
    settings = settings or SimulationSettings()
    if not 0 < settings.seconds <= 600:  # (NaN fails it too)
        raise InputError(f"--seconds must be in (0, 600], got {settings.seconds}")
    if not 0 < settings.depth_fps <= 60:
        raise InputError(f"the depth frame rate must be in (0, 60], got {settings.depth_fps}")
    recs = simulate(scene, truth or calibration, settings)
    calibration = recorded_calibration(calibration, settings)
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        "depth_fps": str(settings.depth_fps),
        "imu_rate_hz": str(settings.imu.rate_hz),
        SENSOR_KEY: settings.stereo.name,
        HAND_KEY: json.dumps(hand_metadata(settings.hand())),
    }
    tmp = Path(out).with_name(Path(out).name + ".part")
    with SessionWriter(tmp, calibration, meta, T0_NS) as w:
        w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, scene.spec, T0_NS)
        if isinstance(scene.surface, MeshSurface):
            w.attach(MESH_ATTACHMENT, "application/octet-stream", ply_bytes(scene.surface), T0_NS)
        if truth is not None:
            w.attach(schemas.TRUTH_RIG_ATTACHMENT, "application/json", truth.to_json().encode())
        for r in recs:
            w.write(r)
    os.replace(tmp, out)
    return len(recs)


def truth_rig(attachments: dict[str, bytes]) -> Calibration | None:
    """The true rig of a simulated session (``truth-calibration.json``), if any."""
    raw = attachments.get(schemas.TRUTH_RIG_ATTACHMENT)
    return None if raw is None else Calibration.from_json(raw, schemas.TRUTH_RIG_ATTACHMENT)


def scoring_projector(attachments: dict[str, bytes], recorded: Projector) -> Projector:
    """The projector that lights the true surface in a simulated session: the true
    rig's when the session has one, else the ``recorded`` calibration's."""
    rig = truth_rig(attachments)
    return recorded if rig is None else rig.projector


def scene_of_session(spec: dict[str, Any], attachments: dict[str, bytes]) -> Scene:
    """The Scene recorded in a simulated session (for scoring against the truth)."""
    if spec.get("kind") == "analytic":
        return Scene(get_surface(str(spec["name"])), spec)
    raw = attachments.get(str(spec.get("file")))
    if raw is None:
        raise InputError("the session has no truth mesh attachment")
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "truth.ply"
        p.write_bytes(raw)
        return Scene(load_mesh(p), spec)
