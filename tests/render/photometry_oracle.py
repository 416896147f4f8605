"""What a viewer sees of a projector frame on an analytic surface, from the geometry
alone: the ground truth of the photometric tests and of ``tools/bench_photometric.py``.

The brightness (:func:`seen_brightness`) calls none of the code under test
(``geometry/irradiance.py``, ``render/photometry.py``): each viewer pixel's ray is
cast onto the analytic surface, its normal comes from two more rays a quarter pixel
away, the point is lit only if the projector's own ray through it meets it first, and
the light is the frame's value
through the projector's response (``(value / 255) ** gamma``) times
``V(r) cos(incidence) / d^2``. A Lambertian surface of uniform reflectance and no
ambient light: radiance is irradiance up to a constant, whatever the view direction.
:func:`grey_case` makes the frames it judges (the warp, the gain map and its
application are the code under test).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.analytic import AnalyticSurface, get_surface, simulate_surface
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.photometry import GainMap, PhotometrySettings, apply_gain, gain_map
from adaproj_edge.render.project import show
from adaproj_edge.render.viewer import DEFAULT_VIEWER, Viewer, viewer_for
from adaproj_edge.warp.engine import Mode, WarpSettings
from adaproj_edge.warp.planner import compute_warp

EDGE_PX = 3
"""Projector pixels dropped at the picture's edge (its anti-aliased rim) and at the
frame's."""
STRADDLE_PX = 1.5
"""Projector pixels this close to another smooth patch (a crease) are not judged."""


def _viewer_rays(viewer: Viewer, du: float = 0.0, dv: float = 0.0) -> FloatArray:
    f = 0.5 * viewer.width / np.tan(np.deg2rad(viewer.fov_deg) / 2)
    v, u = np.mgrid[0 : viewer.height, 0 : viewer.width].astype(np.float64)
    x = (u + du - (viewer.width - 1) / 2) / f
    y = (v + dv - (viewer.height - 1) / 2) / f
    cam = np.stack([x, y, np.ones_like(x)], axis=-1)
    world: FloatArray = cam @ viewer.rotation()
    return world


def _hits(surface: AnalyticSurface, origin: FloatArray, dirs: FloatArray) -> FloatArray:
    o = np.broadcast_to(origin, dirs.shape)
    t = surface.intersect(o, dirs)
    out: FloatArray = o + t[..., None] * dirs
    return out


@dataclass(frozen=True)
class Seen:
    """What the viewer sees.

    Attributes
    ----------
    brightness : (h, w) float array
        Relative radiance of each viewer pixel inside the picture, NaN elsewhere.
    deg_per_px : float
        The viewer camera's visual angle per pixel.
    """

    brightness: FloatArray
    deg_per_px: float

    @property
    def picture(self) -> NDArray[np.bool_]:
        """Viewer pixels inside the picture."""
        return np.asarray(np.isfinite(self.brightness))

    def ratio(self) -> float:
        """Max/min of the brightness over the picture."""
        b = self.brightness[self.picture]
        return float(b.max() / b.min())

    def mean(self) -> float:
        """Mean brightness over the picture as the viewer sees it (per viewer pixel)."""
        return float(np.mean(self.brightness[self.picture]))

    def gradient_per_deg(self, baseline_deg: float = 1.0) -> float:
        """The largest relative change of brightness per degree, over ``baseline_deg``
        (brightness averaged over a window that wide first, so the frame's 8-bit steps
        do not count as gradients); only windows wholly inside the picture."""
        n = max(round(baseline_deg / self.deg_per_px), 1)
        pic = self.picture.astype(np.float64)
        lb = np.where(self.picture, np.log(np.where(self.picture, self.brightness, 1.0)), 0.0)
        k = (n, n)
        inside = cv2.blur(pic, k, borderType=cv2.BORDER_CONSTANT) > 1 - 1e-9
        mean = cv2.blur(lb, k, borderType=cv2.BORDER_CONSTANT)
        worst = 0.0
        for dy, dx in ((0, n), (n, 0), (n, n), (n, -n)):
            a, b = _pair(mean, dy, dx)
            ia, ib = _pair(inside, dy, dx)
            step = np.abs(a - b)[ia & ib] / (np.hypot(dx, dy) * self.deg_per_px)
            if step.size:
                worst = max(worst, float(step.max()))
        return float(np.expm1(worst))


def _pair(a: NDArray[Any], dy: int, dx: int) -> tuple[NDArray[Any], NDArray[Any]]:
    """The values of ``a`` at (y + dy, x + dx) and at (y, x), wherever both exist
    (``dy`` >= 0)."""
    h, w = a.shape
    if dx >= 0:
        return a[dy:, dx:], a[: h - dy, : w - dx]
    return a[dy:, : w + dx], a[: h - dy, -dx:]


def seen_brightness(
    surface: AnalyticSurface,
    projector: Projector,
    frame: NDArray[np.uint8],
    viewer: Viewer,
    gamma: float = 2.2,
    vignetting: tuple[float, float] = (0.0, 0.0),
) -> Seen:
    """The brightness the viewer sees of ``frame`` (H, W[, 3]) projected on ``surface``.

    Parameters
    ----------
    surface : AnalyticSurface
    projector : Projector
    frame : (H, W[, 3]) uint8 array
        The projector frame (its channels averaged: grey content).
    viewer : Viewer
    gamma : float
        The projector's response.
    vignetting : (a1, a2)
        The lens's relative illumination ``1 + a1 r^2 + a2 r^4``.
    """
    eye = np.asarray(viewer.eye, dtype=np.float64)
    x = _hits(surface, eye, _viewer_rays(viewer))
    xu = _hits(surface, eye, _viewer_rays(viewer, du=0.25))
    xv = _hits(surface, eye, _viewer_rays(viewer, dv=0.25))
    n = np.cross(xu - x, xv - x)
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
    same = (surface.patch(np.nan_to_num(x)) == surface.patch(np.nan_to_num(xu))) & (
        surface.patch(np.nan_to_num(x)) == surface.patch(np.nan_to_num(xv))
    )
    # lit: the projector's ray through the point meets it first
    d = np.linalg.norm(x, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        first = _hits(surface, np.zeros(3), x / d[..., None])
    lit = np.linalg.norm(first - x, axis=-1) < 1e-4
    uvh = x @ projector.K.T
    with np.errstate(invalid="ignore", divide="ignore"):
        u, v = uvh[..., 0] / uvh[..., 2], uvh[..., 1] / uvh[..., 2]
    grey = frame.astype(np.float64)
    if grey.ndim == 3:
        grey = grey.mean(axis=2)
    content = (frame.reshape(*frame.shape[:2], -1).max(axis=2) > 0).astype(np.uint8)
    kernel = np.ones((2 * EDGE_PX + 1, 2 * EDGE_PX + 1), np.uint8)
    # the frame's own border counts as an edge too
    core = cv2.erode(content, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
    ok = same & lit & np.isfinite(u) & np.isfinite(v)
    # a projector pixel that straddles a crease lights both sides: no gain of its own
    # can suit both, so its neighbourhood must lie on one patch
    label = surface.patch(np.nan_to_num(x))
    for du, dv in ((-STRADDLE_PX, 0), (STRADDLE_PX, 0), (0, -STRADDLE_PX), (0, STRADDLE_PX)):
        with np.errstate(invalid="ignore"):
            rays = projector.rays(np.stack([u + du, v + dv], axis=-1))
        near = _hits(surface, np.zeros(3), np.nan_to_num(rays, nan=0.0))
        ok &= surface.patch(np.nan_to_num(near)) == label
    ok &= (u >= 0) & (v >= 0) & (u <= projector.width - 1) & (v <= projector.height - 1)
    mu, mv = np.where(ok, u, -10).astype(np.float32), np.where(ok, v, -10).astype(np.float32)
    # every projector pixel the sample takes part of its value from is in the core
    ok &= cv2.remap(core.astype(np.float32), mu, mv, cv2.INTER_LINEAR) > 1 - 1e-6
    value = cv2.remap(grey.astype(np.float32), mu, mv, cv2.INTER_LINEAR).astype(np.float64)
    rx, ry = (
        (u - projector.K[0, 2]) / projector.K[0, 0],
        (v - projector.K[1, 2]) / projector.K[1, 1],
    )
    r2 = rx * rx + ry * ry
    falloff = 1.0 + vignetting[0] * r2 + vignetting[1] * r2 * r2
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.abs(np.sum(n * x, axis=-1)) / d
        light = (value / 255.0) ** gamma * falloff * cos / (d * d)
    out = np.where(ok & (value > 0), light, np.nan)
    deg = float(np.rad2deg(np.deg2rad(viewer.fov_deg) / viewer.width))
    return Seen(out, deg)


GREY = 128
"""Mid-grey content, the value of the Done-when figures."""

CITED_GRADIENT = 0.02
"""The threshold the viewer's brightness must stay under: 2 % per degree of visual angle
(docs/photometry.md); the gain is made for 1 % in the projector's own angles."""


@dataclass(frozen=True)
class GreyCase:
    """Flat mid-grey content on one analytic surface, seen by one viewer, plain and
    compensated.

    Attributes
    ----------
    before, after : Seen
        What the viewer sees without and with the gain.
    gain : GainMap
        The gain applied.
    frame : (H, W, 3) uint8 array
        The uncompensated frame.
    surface : Surface or None
        The surface the gain was made from (the device's estimate, walls snapped);
        None where it is the analytic surface itself.
    """

    before: Seen
    after: Seen
    gain: GainMap
    frame: NDArray[np.uint8]
    surface: Surface | None = None


def grey_case(
    name: str,
    projector: Projector | None = None,
    eye: tuple[float, float, float] = DEFAULT_VIEWER,
    settings: PhotometrySettings | None = None,
    mode: Mode = "content",
) -> GreyCase:
    """Mid-grey content warped onto the built-in surface ``name`` (``mode``), its gain
    map made from the surface the projector measures, and the brightness the viewer
    at ``eye`` sees before and after (from :func:`seen_brightness`)."""
    p = projector or Projector.default()
    analytic = get_surface(name)
    surface = simulate_surface(analytic, p)
    grey = np.full((600, 800, 3), GREY, np.uint8)
    warp = compute_warp(surface, (800, 600), None, WarpSettings(mode=mode))
    shown = show(surface, grey, warp)
    s = settings or PhotometrySettings()
    gain = gain_map(surface, None, s, picture=np.isfinite(shown.map_xy[..., 0]))
    viewer = viewer_for(surface, eye)
    before = seen_brightness(analytic, p, shown.frame, viewer, s.gamma)
    after = seen_brightness(analytic, p, apply_gain(shown.frame, gain), viewer, s.gamma)
    return GreyCase(before, after, gain, shown.frame)


def device_grey_case(
    name: str,
    eye: tuple[float, float, float] = DEFAULT_VIEWER,
    frames: int = 3,
    seed: int = 0,
) -> GreyCase:
    """Mid-grey content on the built-in surface ``name`` as the device shows it, with
    ``[display] compensate`` on: ``frames`` simulated OAK-D depth frames of it (the
    nominal calibration's rig, the device still at the origin) through the runtime's
    surface source (estimate at the warp grid's lattice, average, walls snapped), its
    warp source (the pose's content-free warp, its display maps and its gain, at the
    runtime's settings) and the frame rendered from those maps; the brightness the
    viewer at ``eye`` sees before and after (:func:`seen_brightness` of the true
    analytic surface)."""
    from adaproj_edge.app.settings import AppSettings
    from adaproj_edge.app.surfaces import SurfaceSource
    from adaproj_edge.app.telemetry import Telemetry
    from adaproj_edge.app.warps import WarpSource
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.hal.depth import DepthFrame
    from adaproj_edge.render.frame import render_frame
    from adaproj_edge.session.simulator import Scene
    from adaproj_edge.session.stereo import default_noise, stereo_depth

    cal = Calibration.default()
    d, T = cal.depth, cal.T_P_D
    pts = Scene.load(name).points_seen(d.K, d.width, d.height, T[:3, :3], T[:3, 3])
    rng = np.random.default_rng(seed)
    settings = AppSettings(photometry=PhotometrySettings(scale=AppSettings().map_scale))
    telemetry = Telemetry(100)
    surfaces = SurfaceSource(cal, settings, telemetry.times)
    for k in range(frames):
        depth = stereo_depth(pts, d, default_noise(), rng, pts @ T[:3, :3].T + T[:3, 3])
        est = surfaces.filter.update(surfaces.estimate(DepthFrame(k, k, k, depth)), k > 0)
    surface = surfaces.prepared(est)
    warps = WarpSource(cal.projector, settings, telemetry)
    size = (800, 600)
    entry, _ = warps.pose(surface, frames, 0, np.zeros(3), size, WarpSettings(mode="content"))
    gain = warps.gain(entry, surface)
    assert gain is not None
    grey = np.full((size[1], size[0], 3), GREY, np.uint8)
    plain = render_frame(grey, warps.content_free_maps(entry))
    analytic = get_surface(name)
    viewer = viewer_for(surface, eye)
    before = seen_brightness(analytic, cal.projector, plain, viewer)
    after = seen_brightness(analytic, cal.projector, apply_gain(plain, gain), viewer)
    return GreyCase(before, after, gain, plain, surface)


def creased(
    projector: Projector, angle_deg: float, slope: float
) -> tuple[Surface, FloatArray, FloatArray]:
    """A wall facing the projector 1.5 m away, folded away along a straight crease
    through the frame's centre at ``angle_deg`` (the other wall's depth grows by
    ``slope`` per unit of the ray's offset across the crease): the surface, its exact
    relative irradiance per frame pixel (cos / d^2 from the analytic normals, written
    here) and each pixel's signed distance from the crease (pixels)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    r = projector.rays(projector.pixel_grid())
    r = r / r[..., 2:3]
    q = r[..., 0] * c + r[..., 1] * s
    pts = r * (1.5 / (1.0 + slope * np.maximum(q, 0.0)))[..., None]
    side = (q > 0).astype(np.float64)
    n = np.stack([slope * side * c, slope * side * s, np.ones_like(q)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    d = np.linalg.norm(pts, axis=-1)
    e = np.abs(np.sum(n * pts, axis=-1)) / d**3
    return Surface(pts.astype(np.float32), projector), e, q * float(projector.K[0, 0])
