"""The session simulator: a virtual device, held in a hand, in front of a surface.

The surface is a built-in analytic one (``adaproj_edge.geometry.analytic.SURFACES``)
or any triangle mesh (``.obj``/``.ply``, metres, in the projector frame at t = 0).
The simulator writes a normal session (depth frames, IMU samples, button presses)
plus the ground truth on channels of its own: ``/truth/pose`` (T_W_P at every IMU
sample and depth frame) and the ``truth-surface.json`` attachment (with the mesh file
for meshes), so tests can score what the device estimates. Everything follows from
the seed: the same arguments give the same file.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from adaproj_edge.arrays import FloatArray
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
from adaproj_edge.session import schemas
from adaproj_edge.session.codec import Record
from adaproj_edge.session.hand import HandMotion
from adaproj_edge.session.records import TruthPose
from adaproj_edge.session.stereo import StereoNoise, stereo_depth
from adaproj_edge.session.writer import SessionWriter

T0_NS = 1_000_000_000
KEY_CODE = 28
MESH_ATTACHMENT = "truth-mesh.ply"


@dataclass(frozen=True)
class ImuNoise:
    """LSM6DSOX-like noise at 208 Hz (DS12814 table 2: noise density, zero offsets)."""

    accel_sigma: float = 0.008  # m/s^2 per sample (~80 ug/sqrt(Hz) over ~100 Hz)
    gyro_sigma: float = 0.0007  # rad/s per sample (~3.8 mdps/sqrt(Hz))
    accel_bias_sigma: float = 0.1  # m/s^2 (~10 mg)
    gyro_bias_sigma: float = 0.005  # rad/s (~0.3 dps)


@dataclass(frozen=True)
class SimulationSettings:
    """What to simulate; ``presses`` are times (s) of button presses (None: two)."""

    seconds: float = 3.0
    depth_fps: float = 15.0
    seed: int = 0
    presses: tuple[float, ...] | None = None
    imu: Lsm6dsoxConfig = field(default_factory=Lsm6dsoxConfig)
    imu_noise: ImuNoise = field(default_factory=ImuNoise)
    stereo: StereoNoise = field(default_factory=StereoNoise)
    motion: HandMotion | None = None

    def hand(self) -> HandMotion:
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
        if Path(name_or_path).suffix.lower() in (".obj", ".ply"):
            mesh = load_mesh(name_or_path)
            return cls(mesh, {"kind": "mesh", "name": mesh.name, "file": MESH_ATTACHMENT})
        raise InputError(
            f"unknown surface {name_or_path!r}: give a mesh file (.obj, .ply) or one of "
            + ", ".join(SURFACES)
        )

    def points_seen(
        self, K: FloatArray, width: int, height: int, R_W_C: FloatArray, t_W_C: FloatArray
    ) -> FloatArray:
        """Points (height, width, 3) in the camera frame where its pixel rays meet the
        surface (NaN: nothing) for a camera with intrinsics ``K`` at pose (R_W_C, t_W_C).

        A mesh is cast in one call through its BVH (built once per scene); the rays
        have z = 1 in the camera frame, so the hit's ray parameter is its depth.
        """
        rays = Projector(K, width, height).rays(Projector(K, width, height).pixel_grid())
        if isinstance(self.surface, MeshSurface):
            z = self.surface.intersect(np.asarray(t_W_C, dtype=np.float64), rays @ R_W_C.T)
            return rays * z[..., None]
        hits = ray_cast(self.surface, t_W_C, rays @ R_W_C.T)
        return (hits - t_W_C) @ R_W_C


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
    dt = 1.0 / settings.imu.rate_hz
    t_imu = np.arange(0.0, settings.seconds, dt)
    f_p, w_p = hand.imu_truth(t_imu)
    R_I_P = calibration.R_P_I.T
    n = settings.imu_noise
    acc = f_p @ R_I_P.T + rng.normal(scale=n.accel_bias_sigma, size=3)
    acc += rng.normal(scale=n.accel_sigma, size=acc.shape)
    gyr = w_p @ R_I_P.T + rng.normal(scale=n.gyro_bias_sigma, size=3)
    gyr += rng.normal(scale=n.gyro_sigma, size=gyr.shape)
    acc = _quantise(acc, settings.imu.accel_scale)
    gyr = _quantise(gyr, settings.imu.gyro_scale)
    R_all, p_all = hand.pose(t_imu)
    for i, t in enumerate(t_imu):
        ts = T0_NS + round(t * 1e9)
        rx = ts + 300_000 + int(rng.integers(0, 200_000))
        a = (float(acc[i, 0]), float(acc[i, 1]), float(acc[i, 2]))
        g = (float(gyr[i, 0]), float(gyr[i, 1]), float(gyr[i, 2]))
        recs.append((rx, 1, ImuSample(ts, rx, a, g, 30.0)))
        recs.append((ts, 3, _pose(ts, R_all[i], p_all[i])))
    # --- depth frames
    d = calibration.depth
    T = calibration.T_P_D
    t_depth = np.arange(0.0, settings.seconds, 1.0 / settings.depth_fps) + 0.5 / settings.depth_fps
    R_d, p_d = hand.pose(t_depth)
    for k, t in enumerate(t_depth):
        R_W_D = R_d[k] @ T[:3, :3]
        t_W_D = R_d[k] @ T[:3, 3] + p_d[k]
        pts = scene.points_seen(d.K, d.width, d.height, R_W_D, t_W_D)
        depth = stereo_depth(pts, d, settings.stereo, rng)
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
) -> int:
    """Simulate and write a session file; returns the number of records."""
    calibration = calibration or Calibration.default()
    settings = settings or SimulationSettings()
    if settings.seconds <= 0 or settings.seconds > 600:
        raise InputError(f"--seconds must be in (0, 600], got {settings.seconds}")
    if not 0 < settings.depth_fps <= 60:
        raise InputError(f"the depth frame rate must be in (0, 60], got {settings.depth_fps}")
    recs = simulate(scene, calibration, settings)
    meta = {
        "source": "simulator",
        "surface": json.dumps(scene.spec),
        "seed": str(settings.seed),
        "seconds": str(settings.seconds),
        "depth_fps": str(settings.depth_fps),
        "imu_rate_hz": str(settings.imu.rate_hz),
    }
    tmp = Path(out).with_name(Path(out).name + ".part")
    with SessionWriter(tmp, calibration, meta, T0_NS) as w:
        w.attach_json(schemas.TRUTH_SURFACE_ATTACHMENT, scene.spec, T0_NS)
        if isinstance(scene.surface, MeshSurface):
            w.attach(MESH_ATTACHMENT, "application/octet-stream", ply_bytes(scene.surface), T0_NS)
        for r in recs:
            w.write(r)
    os.replace(tmp, out)
    return len(recs)


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
