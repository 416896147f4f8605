"""Real depth frames (``tests/fixtures/real/``) through the device path, scored against
the raw points.

A frame is a uint16 millimetre depth PNG recorded by someone else's sensor and a JSON
file beside it: the depth camera's intrinsics, the sensor kind, a pixel box of floor
(gravity is estimated from it: none of these frames carries an accelerometer reading)
and the regions to aim at. For a region the rig is built like a device's: the depth
camera is the recording's, the projector sits 4 cm below it (the reference board's
offset) and is turned to aim at the region's pixel, keeping the camera's roll.

The device path is the runtime itself (:func:`run_runtime`: the
:class:`~adaproj_edge.app.runtime.Runtime` on a virtual clock, held still with the
accelerometer reading the frame's gravity, the button pressed, the frame delivered as
the capture's depth frames), default settings, the built-in poster: its
:class:`~adaproj_edge.app.surfaces.SurfaceSource` ->
:meth:`~adaproj_edge.app.warps.WarpSource.pose` ->
:meth:`~adaproj_edge.app.warps.WarpSource.content_aware` and whatever it does when those
fail. :func:`run_device` is that chain by hand (the same maps; the exception itself
where the runtime shows a fault). ``adaproj warp`` is run on the same surface.

The figures are computed from the raw points alone (nothing of the code under test):

- the real surface seen by the projector: every valid depth pixel back-projected,
  moved to frame P and z-buffered onto a sampling of the projector frame (every
  :func:`sample_step` pixels: 1.5 depth pixels, so that every sample gets a point);
- planes: RANSAC then least squares on the raw points of a pixel box;
- distortion (as ``tests/distortion.py``): per small triangle of the sampling, J is the
  Jacobian content -> plane (3x2), angle = sigma1 / sigma2 - 1, size = std of
  log sqrt(sigma1 sigma2); over the triangles whose three samples are shown and whose
  real points lie on the plane;
- upright: the content's up (-y) through the same Jacobians, against gravity projected
  on the plane (a wall: its normal more than 45 deg from gravity) or the projector's
  forward direction projected on it (a floor or a table: away from the device); on the
  region's plane for a planar region, else on the dominant plane (RANSAC) of the real
  points under the subject shown (the poster's salient content);
- the plane fit's spread (:func:`plane_spread`): the angle figure read between two
  robust fits to halves of the region's raw points, content laid exactly on one and
  read on the other (the larger of a left/right and a top/bottom split). A planar
  region's angle figure cannot be verified below it: seen grazing an error of the
  plane's normal of d radians reads as about tan(incidence) d of angle;
- across a depth jump: shown samples next to a shown sample (1 or 2 samples away) whose
  real point lies more than ``JUMP_M`` away nearly along the ray (within
  ``JUMP_RAY_DEG``: a curtain between a silhouette and what is behind it, not a slanted
  wall nor a quantisation step) and further apart in disparity than the frame's own
  noise explains (``JUMP_SIGMAS`` of a pair's, from the disparity noise measured on the
  frame's floor: :func:`disparity_noise`), bridging a silhouette; or with no real point
  within ``NO_OBJECT_RADIUS`` samples (where no object is); as a fraction of the shown
  samples. A sensor's depth error grows as depth squared: at 4-5 m two neighbouring
  points of one wall differ by more than 5 cm along the ray by noise alone.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.app.content import Item, builtin_item
from adaproj_edge.app.settings import AppSettings
from adaproj_edge.app.surfaces import SurfaceSource
from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.app.warps import WarpSource
from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.hal.depth import DepthFrame
from adaproj_edge.warp.engine import WarpSettings

FIXTURES = Path(__file__).parent / "fixtures" / "real"
MIN_STEP = 4  # projector pixels between the samples of the real surface, at least
JUMP_M = 0.05  # a jump: neighbouring samples' real points at least this far apart ...
JUMP_RAY_DEG = 4.0  # ... along a line within this angle of the ray (a silhouette's curtain)
JUMP_SIGMAS = 4.0  # ... and this many of the pair's disparity noise apart
MIN_DISPARITY_SIGMA_PX = 0.125 / np.sqrt(12.0)  # an 1/8-pixel step's own, at least
NO_OBJECT_RADIUS = 2  # samples: a shown sample this far from any real point lies on nothing
PROJECTOR_IN_D = np.array([-0.012, 0.04, -0.005])  # the projector's centre in frame D
PLANAR_KINDS = ("wall", "floor")

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Region:
    """Where the projector is aimed, and what is there.

    Attributes
    ----------
    name : str
    kind : str
        wall, floor, corner (a wall and its floor), wall-objects (a wall with objects
        in front), desk (a cluttered desk), corridor.
    aim : (u, v)
        The depth pixel the projector's axis goes through.
    plane_box : (u0, v0, u1, v1)
        Depth pixels whose raw points the region's plane is fitted to (the plane a
        planar region's figures are measured on).
    throw : float
        The projector's throw ratio (focal length / width): the device's 1.4 unless a
        narrower footprint is needed to keep a planar region planar.
    """

    name: str
    kind: str
    aim: tuple[int, int]
    plane_box: tuple[int, int, int, int]
    throw: float = 1.4

    @property
    def planar(self) -> bool:
        """Whether the whole region is one plane (distortion is asserted there)."""
        return self.kind in PLANAR_KINDS


@dataclass(frozen=True)
class RealFrame:
    """One recorded depth frame and its camera."""

    name: str
    depth_mm: NDArray[np.uint16]
    K: FloatArray
    sensor: str
    baseline_m: float
    floor_box: tuple[int, int, int, int]
    regions: tuple[Region, ...]
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def height(self) -> int:
        return int(self.depth_mm.shape[0])

    @property
    def width(self) -> int:
        return int(self.depth_mm.shape[1])

    def model(self) -> DepthCameraModel:
        return DepthCameraModel(self.K, self.width, self.height, self.baseline_m)

    def points(self) -> FloatArray:
        """Raw points (h, w, 3) in frame D, NaN where the sensor gave no depth."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        z = self.depth_mm.astype(np.float64) * 1e-3
        z[self.depth_mm == 0] = np.nan
        x = (u - self.K[0, 2]) / self.K[0, 0] * z
        y = (v - self.K[1, 2]) / self.K[1, 1] * z
        return np.stack([x, y, z], axis=-1)


def _box(values: list[int]) -> tuple[int, int, int, int]:
    u0, v0, u1, v1 = (int(x) for x in values)
    return u0, v0, u1, v1


def load_frames(directory: Path = FIXTURES) -> list[RealFrame]:
    """Every frame (``*.json`` with its depth PNG) in ``directory``, by name."""
    frames = []
    for meta_path in sorted(directory.glob("*.json")):
        meta = json.loads(meta_path.read_text())
        raw = cv2.imread(str(directory / meta["depth"]), cv2.IMREAD_UNCHANGED)
        if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
            raise ValueError(f"{meta['depth']}: not a 16-bit depth PNG")
        depth = np.asarray(raw, np.uint16)
        cam = meta["camera"]
        if (cam["width"], cam["height"]) != (depth.shape[1], depth.shape[0]):
            raise ValueError(f"{meta_path.name}: the camera's size is not the image's")
        K = np.array([[cam["fx"], 0.0, cam["cx"]], [0.0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
        regions = tuple(
            Region(
                r["name"],
                r["kind"],
                (int(r["aim"][0]), int(r["aim"][1])),
                _box(r["plane_box"]),
                float(r.get("throw", 1.4)),
            )
            for r in meta["regions"]
        )
        frames.append(
            RealFrame(
                meta_path.stem,
                depth,
                K,
                cam["sensor"],
                float(cam["baseline_m"]),
                _box(meta["floor_box"]),
                regions,
                meta,
            )
        )
    return frames


# ---------------------------------------------------------------------- planes
def fit_plane(
    points: FloatArray, tol: float, seed: int = 0
) -> tuple[FloatArray, float, FloatArray]:
    """A robust plane ``n . X = d`` through ``points`` (N, 3): RANSAC (inliers within
    ``tol`` metres), then least squares on the inliers. Returns (n, d, inlier mask)."""
    pts = points[np.isfinite(points).all(axis=1)]
    if len(pts) < 50:
        raise ValueError("too few points for a plane")
    rng = np.random.default_rng(seed)
    best = np.zeros(len(pts), bool)
    for _ in range(300):
        a, b, c = pts[rng.choice(len(pts), 3, replace=False)]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n)
        if norm < 1e-12:
            continue
        n /= norm
        inl = np.abs(pts @ n - n @ a) < tol
        if inl.sum() > best.sum():
            best = inl
    for _ in range(3):  # least squares on the inliers, inliers again
        q = pts[best]
        centre = q.mean(axis=0)
        n = np.linalg.svd(q - centre, full_matrices=False)[2][2]
        d = float(n @ centre)
        best = np.abs(pts @ n - d) < tol
    mask = np.zeros(len(points), bool)
    mask[np.flatnonzero(np.isfinite(points).all(axis=1))[best]] = True
    return n, d, mask


def plane_tol(frame: RealFrame, z: float) -> float:
    """Inlier band (m) of a plane at depth ``z``: 1.5 disparity steps of an 1/8-pixel
    triangulating sensor (a flat wall is a staircase of such steps), at least 1 cm."""
    step = z * z / (frame.K[0, 0] * frame.baseline_m) / 8.0
    return max(0.01, 1.5 * float(step))


def disparity_noise(frame: RealFrame) -> float:
    """The frame's disparity noise (px, one sigma, one pixel): the spread (1.4826 x the
    median absolute deviation) of the raw disparities ``f B / z`` about the plane fitted
    to the floor box, at least :data:`MIN_DISPARITY_SIGMA_PX` (a clean render's floor
    is exact to the millimetre). It holds the steps, the random error and the floor's
    slow error: measured on the frame itself, not taken from the device's model. Kept
    per frame (its depth, camera and floor box)."""
    key = hashlib.blake2b(frame.depth_mm.tobytes(), digest_size=16)
    key.update(np.asarray([*frame.K.ravel(), frame.baseline_m, *frame.floor_box]).tobytes())
    found = _NOISE.get(key.digest())
    if found is None:
        found = _NOISE[key.digest()] = _disparity_noise(frame)
    return found


_NOISE: dict[bytes, float] = {}  # disparity_noise's, per frame


def _disparity_noise(frame: RealFrame) -> float:
    """:func:`disparity_noise`, measured."""
    pts = box_points(frame, frame.floor_box)
    n, d, _ = fit_plane(pts, plane_tol(frame, float(np.nanmedian(pts[:, 2]))))
    pts = pts[np.isfinite(pts).all(axis=1)]
    with np.errstate(divide="ignore", invalid="ignore"):
        z_plane = d / (pts / pts[:, 2:3] @ n)
    fb = frame.K[0, 0] * frame.baseline_m
    r = fb / pts[:, 2] - fb / z_plane
    r = r[np.isfinite(r)]
    mad = float(np.median(np.abs(r - np.median(r))))
    return max(MIN_DISPARITY_SIGMA_PX, 1.4826 * mad)


def box_points(frame: RealFrame, box: tuple[int, int, int, int]) -> FloatArray:
    u0, v0, u1, v1 = box
    return frame.points()[v0:v1, u0:u1].reshape(-1, 3)


def gravity_up(frame: RealFrame) -> FloatArray:
    """ "Up" in frame D: the normal of the floor (fitted in ``floor_box``) towards the
    camera."""
    pts = box_points(frame, frame.floor_box)
    n, d, _ = fit_plane(pts, plane_tol(frame, float(np.nanmedian(pts[:, 2]))))
    return -n if d > 0 else n  # towards the camera (the origin): the side n . X < d when d > 0


# ---------------------------------------------------------------------- the rig
def rig(frame: RealFrame, region: Region, width: int = 1280, height: int = 800) -> Calibration:
    """The device's calibration: the recording's camera, the projector beside it aimed
    at ``region.aim`` (its roll the camera's)."""
    u, v = region.aim
    pts = frame.points()
    win = pts[max(v - 7, 0) : v + 8, max(u - 7, 0) : u + 8].reshape(-1, 3)
    win = win[np.isfinite(win).all(axis=1)]
    if len(win):
        target = np.median(win, axis=0)
    else:  # nothing measured there: the frame's median depth along the aimed ray
        z = float(np.nanmedian(pts[..., 2]))
        target = (
            np.array(
                [(u - frame.K[0, 2]) / frame.K[0, 0], (v - frame.K[1, 2]) / frame.K[1, 1], 1.0]
            )
            * z
        )
    zc = target - PROJECTOR_IN_D
    zc /= np.linalg.norm(zc)
    xc = np.array([1.0, 0.0, 0.0]) - zc[0] * zc
    xc /= np.linalg.norm(xc)
    yc = np.cross(zc, xc)
    R = np.stack([xc, yc, zc])  # rows: P's axes in D
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ PROJECTOR_IN_D
    f = region.throw * width
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    return Calibration(Projector(K, width, height), frame.model(), T, np.eye(3))


def to_p(cal: Calibration, X: FloatArray) -> FloatArray:
    return X @ cal.T_P_D[:3, :3].T + cal.T_P_D[:3, 3]


# ---------------------------------------------------------------------- device path
@dataclass
class DeviceRun:
    """What the device path made of one region."""

    calibration: Calibration
    up_p: FloatArray
    surface: Surface | None = None
    map_xy: NDArray[np.float32] | None = None  # what the display draws (H, W, 2)
    error: str | None = None  # why nothing was projected
    kind: str = ""  # what was shown: content-aware, content-free, ...
    telemetry: Telemetry | None = None  # the runtime's (run_runtime): stage times, updates

    @property
    def projected(self) -> bool:
        return self.map_xy is not None


def run_device(
    frame: RealFrame, region: Region, item: Item | None = None, settings: AppSettings | None = None
) -> DeviceRun:
    """The runtime's path for ``frame`` with the projector aimed at ``region``."""
    item = item or builtin_item()
    s = settings or AppSettings()
    cal = rig(frame, region)
    up_p = cal.T_P_D[:3, :3] @ gravity_up(frame)
    run = DeviceRun(cal, up_p)
    telemetry = Telemetry(100)
    surfaces = SurfaceSource(cal, s, telemetry.times)
    warps = WarpSource(cal.projector, s, telemetry, sensor=surfaces.estimator.sensor)
    depth = DepthFrame(0, 0, 0, frame.depth_mm)
    try:
        cur = None
        for i in range(s.capture_frames):
            est = surfaces.estimate(depth)
            if est.coverage < s.min_coverage:
                run.error = "DepthFault: " + surfaces.depth_problem(depth, est.coverage)[1]
                return run
            cur = surfaces.filter.update(est, still=i > 0)
        assert cur is not None
        surface = run.surface = surfaces.prepared(cur)
        ws = WarpSettings(
            mode="content",
            grid=s.grid,
            threshold=item.settings.threshold,
            max_iterations=s.refine_iterations,
            up=(float(up_p[0]), float(up_p[1]), float(up_p[2])),
        )
        min_frames = min(cur.frames, s.settle_frames)
        entry, _ = warps.pose(surface, cur.frames, min_frames, np.zeros(3), item.size, ws)
        assert item.content_map is not None
        warp, _ = warps.content_aware(surface, item.content_map, ws, entry)
        run.map_xy = warps.float_map(warp)
        run.kind = "content-aware"
    except AdaprojError as e:
        run.error = f"{type(e).__name__}: {e}"
    return run


def run_runtime(
    frame: RealFrame,
    region: Region,
    item: Item | None = None,
    settings: AppSettings | None = None,
    depth_frames: int | None = None,
    stage_clock: Callable[[], float] | None = None,
) -> DeviceRun:
    """The device itself (:class:`~adaproj_edge.app.runtime.Runtime`, on a virtual clock)
    aimed at ``region``: booted, held still (the accelerometer reads gravity, the
    frame's "up"), the button pressed, then ``depth_frames`` copies of ``frame`` at
    10 Hz (the capture's, by default); ``stage_clock`` times its stages (its telemetry's
    default: wall-clock). What it projects for this surface is the warp it
    shows after the capture (the plain picture of the boot is "nothing"); its warp and
    depth faults are the error."""
    from adaproj_edge.app.content import mask_content_map
    from adaproj_edge.app.runtime import Runtime
    from adaproj_edge.hal.button import ButtonEvent
    from adaproj_edge.hal.clock import VirtualClock
    from adaproj_edge.hal.display import MemoryDisplay
    from adaproj_edge.hal.imu import ImuSample

    item = item or builtin_item()
    s = settings or AppSettings()
    n_depth = s.capture_frames if depth_frames is None else depth_frames
    cal = rig(frame, region)
    up_p = cal.T_P_D[:3, :3] @ gravity_up(frame)
    run = DeviceRun(cal, up_p)
    ms = 1_000_000
    clock = VirtualClock(1_000 * ms)
    p = cal.projector
    rt = Runtime(cal, MemoryDisplay(p.width, p.height), clock, [item], s, mask_content_map)
    run.telemetry = rt.telemetry
    if stage_clock is not None:
        rt.telemetry.times.clock = stage_clock
    rt.boot()
    g = 9.81 * up_p  # the IMU is frame P here (R_P_I = I)
    accel = (float(g[0]), float(g[1]), float(g[2]))
    events: list[tuple[int, object]] = []
    t_end = 2_600 + 100 * n_depth
    events += [
        (t, ImuSample(t * ms, t * ms, accel, (0.0, 0.0, 0.0))) for t in range(1_000, t_end, 5)
    ]
    events += [(t, ButtonEvent(t * ms, t * ms, 28, t == 2_000)) for t in (2_000, 2_100)]
    events += [
        (t, DepthFrame(t * ms, t * ms, k, frame.depth_mm))
        for k, t in enumerate(range(2_550, t_end, 100))
    ]
    for t, ev in sorted(events, key=lambda e: e[0]):
        clock.advance_to(t * ms)
        rt.tick()
        if isinstance(ev, ImuSample):
            rt.on_imu(ev)
        elif isinstance(ev, ButtonEvent):
            rt.on_button(ev)
        elif isinstance(ev, DepthFrame):
            rt.on_depth(ev)
    faults = {k: v for k, v in rt.faults.active.items() if k in ("warp", "depth", "range")}
    if faults:
        run.error = "; ".join(f"{k} fault: {v}" for k, v in sorted(faults.items()))
    warp = rt.shown_warp
    if rt.telemetry.updates and warp is not None and rt.surface is not None:
        run.surface = rt.surface
        run.map_xy = rt.warps.float_map(warp)
        run.kind = str(rt.telemetry.updates[-1]["kind"])
    elif rt.surface is None and rt.surfaces.filter.current is not None:
        run.surface = rt.surfaces.prepared(rt.surfaces.filter.current)
    return run


def adaproj_warp(
    surface: Surface, item: Item | None = None, render: bool = True
) -> tuple[bool, str]:
    """``adaproj warp`` on ``surface`` (saved and read back as the command reads it) with
    the poster and its mask as content map: (succeeded, its error line).

    ``render=False`` runs only the command's warp (the same settings and
    :func:`~adaproj_edge.warp.planner.compute_warp` call, without drawing the projector
    frame at full resolution: what the tests can afford)."""
    from adaproj_edge.cli import main
    from adaproj_edge.commands._inputs import load_surface
    from adaproj_edge.fileio import write_image
    from adaproj_edge.warp.planner import compute_warp

    item = item or builtin_item()
    assert item.content_map is not None
    with tempfile.TemporaryDirectory(prefix="adaproj-real-") as tmp:
        d = Path(tmp)
        surface.save(d / "surface.npz")
        if not render:
            try:
                compute_warp(
                    load_surface(str(d / "surface.npz")),
                    item.size,
                    item.content_map,
                    WarpSettings(),
                )
            except AdaprojError as e:
                return False, f"adaproj warp: error: {e}"
            return True, ""
        write_image(d / "poster.png", item.image)
        cmap = np.clip(item.content_map.full_size() * 255, 0, 255).astype(np.uint8)
        write_image(d / "map.png", cmap)
        out, err = io.StringIO(), io.StringIO()
        argv = ["warp", "--surface", str(d / "surface.npz"), "--image", str(d / "poster.png")]
        argv += ["--content-map", str(d / "map.png"), "--out", str(d / "warp.npz")]
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(argv)
    return rc == 0, err.getvalue().strip()


# ---------------------------------------------------------------------- figures
@dataclass
class Figures:
    """One region's figures (NaN where not measurable)."""

    projected: bool
    error: str | None
    valid_pct: float
    shown_pct: float = 0.0  # of the projector's frame
    upright_deg: float = float("nan")
    angle: float = float("nan")
    size: float = float("nan")
    folds: int = 0
    bridging_pct: float = float("nan")
    no_object_pct: float = float("nan")
    plane_triangles: int = 0
    spread: float = float("nan")  # the angle measure between two fits of the region's plane
    upright_spread: float = float("nan")  # deg: the upright read on fits to halves (see figures)
    upright_rule: str = ""  # the plane the upright figure is measured on: wall or floor
    kind: str = ""  # what the device showed: content-aware, content-free, ...
    warp_ok: bool | None = None
    warp_error: str = ""

    @property
    def warp_failed(self) -> bool:
        """Whether the warp failed for this surface (a warp fault on the display, or the
        WarpError itself on the chain by hand)."""
        error = self.error or ""
        return "warp fault" in error or "WarpError" in error

    @property
    def jump_pct(self) -> float:
        return self.bridging_pct + self.no_object_pct


def sample_step(frame: RealFrame, cal: Calibration) -> int:
    """Projector pixels between the samples of the real surface: 1.5 depth pixels (at
    least ``MIN_STEP``)."""
    ratio = cal.projector.K[0, 0] / frame.K[0, 0]
    return max(MIN_STEP, int(np.ceil(1.5 * ratio)))


def real_samples(frame: RealFrame, cal: Calibration) -> tuple[FloatArray, FloatArray]:
    """The real surface at the projector's samples: the sample pixels (r, c, 2) and the
    nearest raw point (r, c, 3) in frame P z-buffered onto them (NaN: none)."""
    p = cal.projector
    step = sample_step(frame, cal)
    ys, xs = np.arange(0, p.height, step), np.arange(0, p.width, step)
    gx, gy = np.meshgrid(xs, ys)
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    X = to_p(cal, frame.points().reshape(-1, 3))
    X = X[np.isfinite(X).all(axis=1) & (X[:, 2] > 0.05)]
    q = X @ p.K.T
    c = np.rint(q[:, 0] / q[:, 2] / step).astype(np.int64)
    r = np.rint(q[:, 1] / q[:, 2] / step).astype(np.int64)
    ok = (r >= 0) & (r < len(ys)) & (c >= 0) & (c < len(xs))
    r, c, X = r[ok], c[ok], X[ok]
    order = np.argsort(-X[:, 2])  # far first: the nearest point is written last
    out = np.full((len(ys), len(xs), 3), np.nan)
    out[r[order], c[order]] = X[order]
    return uv, out


def valid_fraction(frame: RealFrame, cal: Calibration) -> float:
    """Fraction of the depth pixels in the projector's footprint with valid depth (an
    invalid pixel placed at the frame's median depth)."""
    pts = frame.points()
    z = np.where(np.isfinite(pts[..., 2]), pts[..., 2], np.nanmedian(pts[..., 2]))
    v, u = np.mgrid[0 : frame.height, 0 : frame.width].astype(np.float64)
    X = np.stack(
        [(u - frame.K[0, 2]) / frame.K[0, 0] * z, (v - frame.K[1, 2]) / frame.K[1, 1] * z, z], -1
    )
    q = to_p(cal, X.reshape(-1, 3)) @ cal.projector.K.T
    pu, pv = q[:, 0] / q[:, 2], q[:, 1] / q[:, 2]
    p = cal.projector
    inside = (
        (q[:, 2] > 0) & (pu >= -0.5) & (pu < p.width - 0.5) & (pv >= -0.5) & (pv < p.height - 0.5)
    )
    if not inside.any():
        return 0.0
    return float(np.mean(frame.depth_mm.reshape(-1)[inside] > 0))


def jump_figures(
    shown: NDArray[np.bool_],
    real: FloatArray,
    disparity: FloatArray | None = None,
    noise_px: float = 0.0,
) -> tuple[float, float]:
    """(bridging, no object) in % of the shown samples ``shown`` (r, c), whose real
    points are ``real`` (r, c, 3) (NaN: none). With ``disparity`` (r, c), the sensor's
    disparity (px) of each real point, a jump must also be more than ``JUMP_SIGMAS``
    pair's noise apart there (``sqrt(2) noise_px``): what one frame's noise makes of
    one surface is not a silhouette."""
    n = int(shown.sum())
    if n == 0:
        return 0.0, 0.0
    has = np.asarray(np.isfinite(real).all(axis=-1), bool)
    bridge = np.zeros_like(shown)
    sin_max = np.sin(np.radians(JUMP_RAY_DEG))
    for dr, dc in ((0, 1), (1, 0), (0, 2), (2, 0)):
        a = (slice(0, real.shape[0] - dr), slice(0, real.shape[1] - dc))
        b = (slice(dr, None), slice(dc, None))
        both = shown[a] & shown[b] & has[a] & has[b]
        xa, xb = np.where(both[..., None], real[a], 1.0), np.where(both[..., None], real[b], 2.0)
        seg = xb - xa
        length = np.linalg.norm(seg, axis=-1)
        ray = xa / np.linalg.norm(xa, axis=-1, keepdims=True)
        sin = np.linalg.norm(np.cross(seg, ray), axis=-1) / np.maximum(length, 1e-12)
        jump = both & (length > JUMP_M) & (sin < sin_max)
        if disparity is not None:
            with np.errstate(invalid="ignore"):
                apart = np.abs(disparity[a] - disparity[b]) > JUMP_SIGMAS * np.sqrt(2) * noise_px
            jump &= apart
        bridge[a] |= jump
        bridge[b] |= jump
    k = 2 * NO_OBJECT_RADIUS + 1
    near = np.asarray(cv2.dilate(has.astype(np.uint8), np.ones((k, k), np.uint8))) > 0
    nothing = shown & ~near
    return 100.0 * float(bridge.sum()) / n, 100.0 * float(nothing.sum()) / n


def plane_hits(n: FloatArray, d: float, uv: FloatArray, K: FloatArray) -> FloatArray:
    """Where the rays of projector pixels ``uv`` (r, c, 2) meet the plane ``n . X = d``
    (r, c, 3), NaN behind the projector."""
    x = (uv[..., 0] - K[0, 2]) / K[0, 0]
    y = (uv[..., 1] - K[1, 2]) / K[1, 1]
    rays = np.stack([x, y, np.ones_like(x)], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d / (rays @ n)
    return rays * np.where(t > 0, t, np.nan)[..., None]


def jacobians(
    X: FloatArray, keep: NDArray[np.bool_], shown_xy: FloatArray
) -> tuple[FloatArray, int]:
    """Per small triangle of the sampling whose three samples are kept: J (n, 3, 2),
    the Jacobian content -> surface; and the number of folded triangles."""
    Js = []
    folds = 0
    h, w = keep.shape
    for (a0, a1), (b0, b1), (c0, c1) in (((0, 0), (0, 1), (1, 1)), ((0, 0), (1, 1), (1, 0))):
        s0, s1, s2 = (
            (slice(o0, o0 + h - 1), slice(o1, o1 + w - 1))
            for o0, o1 in ((a0, a1), (b0, b1), (c0, c1))
        )
        ok = (keep[s0] & keep[s1] & keep[s2]).ravel()
        cc = [shown_xy[s].reshape(-1, 2)[ok] for s in (s0, s1, s2)]
        xx = [X[s].reshape(-1, 3)[ok] for s in (s0, s1, s2)]
        dc = np.stack([cc[1] - cc[0], cc[2] - cc[0]], axis=2)
        dX = np.stack([xx[1] - xx[0], xx[2] - xx[0]], axis=2)
        det = dc[:, 0, 0] * dc[:, 1, 1] - dc[:, 0, 1] * dc[:, 1, 0]
        folds += int(np.sum(det <= 0))
        good = det > 1e-12
        Js.append(dX[good] @ np.linalg.inv(dc[good]))
    return np.concatenate(Js), folds


def upright_error(J: FloatArray, n: FloatArray, rule: str, up_p: FloatArray) -> float:
    """Degrees between the content's up (its -y through ``J``, averaged) and the rule's
    up on the plane of normal ``n``: gravity (wall) or the projector's forward direction
    (floor or table: away from the device)."""
    up_content = -J[:, :, 1]
    up_content = up_content / np.linalg.norm(up_content, axis=1, keepdims=True)
    shown_up = up_content.mean(axis=0)
    ref = up_p if rule == "wall" else np.array([0.0, 0.0, 1.0])
    ref = ref - (ref @ n) * n
    shown_up = shown_up - (shown_up @ n) * n
    cos = float(ref @ shown_up / (np.linalg.norm(ref) * np.linalg.norm(shown_up)))
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def plane_rule(n: FloatArray, up_p: FloatArray) -> str:
    """ "wall" for a plane whose normal is more than 45 deg from gravity, else "floor"
    (a floor or a table)."""
    return "floor" if abs(float(n @ up_p)) > np.cos(np.radians(45.0)) else "wall"


def salient(xy: FloatArray, item: Item | None = None) -> NDArray[np.bool_]:
    """Whether content points ``xy`` (..., 2) (NaN: none) lie on the poster's salient
    content (its content map at or above the threshold)."""
    item = item or builtin_item()
    assert item.content_map is not None
    cmap = item.content_map.full_size()
    h, w = cmap.shape
    ok = np.isfinite(xy).all(axis=-1)
    x = np.clip(np.rint(np.where(ok, xy[..., 0], 0)).astype(int), 0, w - 1)
    y = np.clip(np.rint(np.where(ok, xy[..., 1], 0)).astype(int), 0, h - 1)
    return np.asarray(ok & (cmap[y, x] >= item.content_map.threshold), bool)


def angle_size(J: FloatArray) -> tuple[float, float]:
    """(mean angle distortion sigma1 / sigma2 - 1, size inconsistency: std of
    log sqrt(sigma1 sigma2)) of Jacobians ``J`` (n, 3, 2)."""
    sv = np.linalg.svd(J, compute_uv=False)
    return float(np.mean(sv[:, 0] / sv[:, 1] - 1.0)), float(
        np.std(0.5 * np.log(sv[:, 0] * sv[:, 1]))
    )


def plane_spread(frame: RealFrame, region: Region) -> tuple[float, float, float]:
    """(angle, size, degrees between the fits) the measure reads between two robust plane
    fits of the raw points of ``region.plane_box``: its left and right halves, then its top
    and bottom halves (the pair with the larger angle), over the projector's samples on
    the region's plane (the rig of :func:`rig`). Content laid exactly on one fit, read on
    the other: what the planar figure cannot resolve."""
    cal = rig(frame, region)
    K = cal.projector.K
    uv, real = real_samples(frame, cal)
    u0, v0, u1, v1 = region.plane_box
    pts = to_p(cal, box_points(frame, region.plane_box))
    tol = plane_tol(frame, float(np.nanmedian(pts[:, 2])))
    n, d, inl = fit_plane(pts, tol)
    with np.errstate(invalid="ignore"):
        on = np.abs(real @ n - d) < tol
    v, u = np.mgrid[v0:v1, u0:u1]
    u, v = u.reshape(-1), v.reshape(-1)
    e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    worst = (0.0, 0.0, 0.0)
    for coord in (u, v):
        half = coord < np.median(coord[inl])
        na, da, _ = fit_plane(pts[inl & half], tol)
        nb, db, _ = fit_plane(pts[inl & ~half], tol)
        xa, xb = plane_hits(na, da, uv, K), plane_hits(nb, db, uv, K)
        keep = on & np.isfinite(xa).all(axis=-1) & np.isfinite(xb).all(axis=-1)
        flat = np.stack([xa @ e1, xa @ e2], axis=-1)  # content: the first fit, unrolled
        J = max((jacobians(xb, keep, flat * s)[0] for s in ([1, 1], [1, -1])), key=len)
        a, sz = angle_size(J)
        deg = float(np.degrees(np.arccos(min(1.0, abs(float(na @ nb))))))
        if a > worst[0]:
            worst = (a, sz, deg)
    return worst


def figures(
    frame: RealFrame,
    region: Region,
    render: bool = True,
    runtime: bool = True,
    spreads: bool = False,
) -> tuple[Figures, DeviceRun]:
    """Run ``region`` of ``frame`` through the device (:func:`run_runtime`; with
    ``runtime`` off, the runtime's chain by hand: :func:`run_device`) and score it;
    ``render``: ``adaproj warp`` draws its frame too (see :func:`adaproj_warp`).

    Distortion is measured on the plane fitted in the region's ``plane_box`` (planar
    regions); the upright error on that plane for planar regions, else on the dominant
    plane of the real points under the subject shown (the salient content; all the
    content when too little of it is shown), with the rule of its kind. With
    ``spreads``, also the upright figure's own spread (``Figures.upright_spread``): the
    largest change of the figure read on planes fitted to halves of the same points
    (left and right, top and bottom), what the figure cannot resolve there (a small
    patch of clutter, or a far wall whose raw points the sensor's slow error tilts)."""
    run = run_runtime(frame, region) if runtime else run_device(frame, region)
    fig = Figures(run.projected, run.error, 100.0 * valid_fraction(frame, run.calibration))
    fig.kind = run.kind
    if run.surface is not None:
        fig.warp_ok, fig.warp_error = adaproj_warp(run.surface, render=render)
    if run.map_xy is None:
        return fig, run
    cal = run.calibration
    K = cal.projector.K
    uv, real = real_samples(frame, cal)
    m = run.map_xy
    shown_xy = m[uv[..., 1].astype(int), uv[..., 0].astype(int)].astype(np.float64)
    shown = np.isfinite(shown_xy).all(axis=-1)
    fig.shown_pct = 100.0 * float(shown.mean())
    z_d = (real - cal.T_P_D[:3, 3]) @ cal.T_P_D[:3, :3][:, 2]  # depth in frame D
    fb = frame.K[0, 0] * frame.baseline_m
    with np.errstate(divide="ignore", invalid="ignore"):
        disparity = fb / z_d
    fig.bridging_pct, fig.no_object_pct = jump_figures(
        shown, real, disparity, disparity_noise(frame)
    )
    if region.planar:
        pts = to_p(cal, box_points(frame, region.plane_box))
    else:  # the plane where the subject (the salient content) is shown
        subject = shown & salient(shown_xy) & np.isfinite(real).all(axis=-1)
        if subject.sum() < 50:
            subject = shown & np.isfinite(real).all(axis=-1)
        pts = real[subject]
    if np.isfinite(pts).all(axis=1).sum() < 50:
        return fig, run
    tol = plane_tol(frame, float(np.nanmedian(pts[:, 2])))

    def on_plane(n: FloatArray, d: float) -> tuple[FloatArray, int]:
        """The Jacobians on the plane ``n . X = d`` where the real surface is it."""
        X = plane_hits(n, d, uv, K)
        with np.errstate(invalid="ignore"):
            on = np.abs(real @ n - d) < tol  # the real surface there is the plane
        keep = on & shown & np.isfinite(X).all(axis=-1)
        return jacobians(X, keep, shown_xy)

    n, d, _ = fit_plane(pts, tol)
    J, fig.folds = on_plane(n, d)
    fig.plane_triangles = len(J)
    fig.upright_rule = plane_rule(n, run.up_p)
    if len(J) < 20:
        return fig, run
    fig.upright_deg = upright_error(J, n, fig.upright_rule, run.up_p)
    if region.planar:
        fig.angle, fig.size = angle_size(J)
        fig.spread = plane_spread(frame, region)[0]
    if spreads:
        if region.planar:
            u0, v0, u1, v1 = region.plane_box
            rows, cols = np.mgrid[v0:v1, u0:u1].reshape(2, -1)
        else:
            rows, cols = np.nonzero(subject)
        reads = []
        for coord in (cols, rows):
            for half in (coord < np.median(coord), coord >= np.median(coord)):
                if np.isfinite(pts[half]).all(axis=1).sum() < 50:
                    continue
                nh, dh, _ = fit_plane(pts[half], tol)
                Jh = on_plane(nh, dh)[0]
                if len(Jh) >= 20:
                    reads.append(upright_error(Jh, nh, plane_rule(nh, run.up_p), run.up_p))
        if reads:
            fig.upright_spread = max(abs(r - fig.upright_deg) for r in reads)
    return fig, run
