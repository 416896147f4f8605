"""What the depth-aligned camera sees when the projector shows a frame on a surface.

For one device pose (:class:`LitView`): every camera pixel is cast into the scene at
``supersample`` x ``supersample`` points; each point is lit by the projector pixel
that covers it — when the projector sees the point (a shadow map from the
projector's side; lens distortion of the true projector applied) — with Lambertian
falloff ``cos(incidence) / distance^2`` and a textured albedo (a procedural grey
texture, or a :class:`Paint`: a coloured picture painted onto the scene from one
projector pose, as ``adaproj simulate-calibration --albedo`` asks). :func:`render_capture`
then turns a projector frame into a grey camera image: projector gamma and black
level, ambient light, a little light reflected between the surfaces (a wide blur
of the direct light), the camera's exposure and blur, shot and read noise, 8-bit
quantisation and saturation.

Used by the calibration simulator (:mod:`adaproj_edge.session.calibration_sim`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray, Image
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.session.simulator import Scene
from adaproj_edge.session.stereo import normals_cos


@dataclass(frozen=True)
class CameraOptics:
    """Photometry of the simulated projector and camera.

    ``white_level`` is the grey level of full white on a frontal surface of albedo 1
    at ``reference_m`` with the reference exposure (``reference_exposure_us`` at
    ``reference_iso``); ``ambient`` the grey level ambient light gives the same
    surface.
    """

    white_level: float = 90.0
    reference_m: float = 1.5
    reference_exposure_us: int = 8000
    reference_iso: int = 400
    ambient: float = 12.0
    gamma: float = 2.2
    black_level: float = 0.02
    albedo_texture: float = 0.15
    interreflection: float = 0.05
    blur_px: float = 0.6
    read_noise: float = 1.5
    shot_noise: float = 0.3
    supersample: int = 3


GREY_WEIGHTS = (0.114, 0.587, 0.299)
"""The grey camera's shares of the projector's blue, green and red light (OpenCV's
BGR-to-grey weights)."""


def distort(xn: FloatArray, yn: FloatArray, d: FloatArray) -> tuple[FloatArray, FloatArray]:
    """OpenCV's lens distortion ``d`` = (k1, k2, p1, p2, k3) of normalised coordinates."""
    k1, k2, p1, p2, k3 = (float(v) for v in d)
    r2 = xn * xn + yn * yn
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    return xd, yd


def project_points(points_p: FloatArray, K: FloatArray, dist: FloatArray | None) -> FloatArray:
    """Pixel coordinates (..., 2) of points (..., 3) in frame P, with lens distortion."""
    with np.errstate(divide="ignore", invalid="ignore"):
        xn = points_p[..., 0] / points_p[..., 2]
        yn = points_p[..., 1] / points_p[..., 2]
    if dist is not None and np.any(dist):
        xn, yn = distort(xn, yn, dist)
    return np.stack([K[0, 0] * xn + K[0, 1] * yn + K[0, 2], K[1, 1] * yn + K[1, 2]], axis=-1)


def _albedo(points_w: FloatArray, amplitude: float) -> FloatArray:
    """A smooth procedural texture (..., ) in [1 - amplitude, 1] of world points."""
    x, y, z = points_w[..., 0], points_w[..., 1], points_w[..., 2]
    t = np.sin(23.0 * x + 3.0 * z) * np.sin(19.0 * y - 5.0 * z) + 0.5 * np.sin(41.0 * (x + y))
    out: FloatArray = 1.0 - amplitude * (0.5 + t / 3.0)
    return out


@dataclass(frozen=True)
class Paint:
    """A picture painted onto the scene: ``albedo`` (H, W, 3) float32, the blue,
    green and red reflectance in [0, 1] of each pixel of a projector (intrinsics
    ``K``, lens ``distortion``) at pose (``R_W_P``, ``t_W_P``) -- the surface as that
    projector sees it. Points outside its frame take the nearest edge's colour."""

    albedo: NDArray[np.float32]
    R_W_P: FloatArray
    t_W_P: FloatArray
    K: FloatArray
    distortion: FloatArray | None = None

    def at(self, points_w: FloatArray) -> NDArray[np.float32]:
        """The reflectance (..., 3) of world points (..., 3) (NaN points: the corner's)."""
        pts_p = (points_w - self.t_W_P) @ self.R_W_P
        uv = np.nan_to_num(project_points(pts_p, self.K, self.distortion), nan=-1.0)
        uv = np.where(pts_p[..., 2:3] > 0, uv, -1.0).astype(np.float32)
        out = cv2.remap(
            np.ascontiguousarray(self.albedo, np.float32), uv[..., 0], uv[..., 1],
            cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE,
        )  # fmt: skip
        return np.asarray(out, np.float32)


@dataclass(frozen=True)
class LitView:
    """The geometry of one device pose, at ``supersample`` x the camera resolution.

    ``uv`` (H, W, 2) float32: the projector pixel lighting each point (-10 where
    none: no surface, outside the frame, or in the projector's shadow); ``light``
    (H, W) float32: albedo x cos(incidence) x (reference / distance)^2 where lit;
    ``albedo`` (H, W) float32 (0 where there is no surface); ``footprint_px``: the
    median distance in projector pixels between neighbouring points (the projector
    frame is blurred over it before it is sampled, so a point stands for its whole
    patch of the frame: no aliasing between the two pixel grids); ``colour`` (H, W, 3)
    float32 or None (grey): a painted point's reflectance per primary over its grey
    ``albedo`` (the :data:`GREY_WEIGHTS` mean of the three is 1).
    """

    uv: NDArray[np.float32]
    light: NDArray[np.float32]
    albedo: NDArray[np.float32]
    supersample: int
    footprint_px: float = 0.0
    colour: NDArray[np.float32] | None = None


def lit_view(
    scene: Scene,
    rig: Calibration,
    R_W_P: FloatArray,
    t_W_P: FloatArray,
    K_camera: FloatArray,
    size: tuple[int, int],
    optics: CameraOptics,
    distortion: FloatArray | None = None,
    paint: Paint | None = None,
) -> LitView:
    """Cast the camera's pixels (``K_camera`` at ``size`` (w, h), frame D of ``rig``)
    into ``scene`` with the device at pose (``R_W_P``, ``t_W_P``); see :class:`LitView`.
    With ``paint`` the scene's albedo is the painted picture's, not the procedural
    texture."""
    n = optics.supersample
    w, h = size
    Ks = DepthCameraModel(K_camera, w, h).intrinsics_at(n * w, n * h)
    T = rig.T_P_D
    R_W_D = R_W_P @ T[:3, :3]
    t_W_D = R_W_P @ T[:3, 3] + t_W_P
    pts_d = scene.points_seen(Ks, n * w, n * h, R_W_D, t_W_D)
    pts_p = pts_d @ T[:3, :3].T + T[:3, 3]
    proj = rig.projector
    uv = project_points(pts_p, proj.K, distortion)
    with np.errstate(invalid="ignore"):
        ui = np.rint(uv[..., 0]).astype(np.int64, copy=False)
        vi = np.rint(uv[..., 1]).astype(np.int64, copy=False)
        inside = (ui >= 0) & (ui < proj.width) & (vi >= 0) & (vi < proj.height)
        inside &= np.isfinite(pts_p[..., 2])
        ui, vi = np.where(inside, ui, 0), np.where(inside, vi, 0)
        # the projector's own view of the scene: a point it lights is the nearest on its
        # ray (a shadow map, cast only at the projector pixels the camera's points fall in)
        flat = vi * proj.width + ui
        shadow = np.full(proj.width * proj.height, np.nan)
        lit = np.zeros(shadow.size, dtype=bool)
        lit[flat[inside]] = True
        pixels = np.flatnonzero(lit)
        shadow[pixels] = scene.depths_seen(proj.K, proj.width, proj.height, R_W_P, t_W_P, pixels)
        z_first = shadow[flat]
        z = pts_p[..., 2]
        seen = inside & ~(z > np.where(np.isfinite(z_first), z_first, np.inf) * 1.01 + 0.005)
    # Lambertian falloff from the projector
    dist = np.linalg.norm(pts_p, axis=-1)
    cos = normals_cos(pts_p)
    cos = np.where(np.isfinite(cos), cos, 0.0)
    pts_w = pts_p @ R_W_P.T + t_W_P
    colour = None
    if paint is None:
        albedo = np.where(np.isfinite(z), _albedo(pts_w, optics.albedo_texture), 0.0)
    else:
        rgb = paint.at(pts_w)
        grey = rgb @ np.asarray(GREY_WEIGHTS, np.float32)
        albedo = np.where(np.isfinite(z), grey, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            colour = np.where(grey[..., None] > 0, rgb / grey[..., None], 1.0).astype(np.float32)
    light = np.where(seen, albedo * cos * (optics.reference_m / np.where(seen, dist, 1.0)) ** 2, 0)
    step = np.linalg.norm(np.diff(uv, axis=1), axis=-1)[seen[:, 1:] & seen[:, :-1]]
    footprint = float(np.median(step)) if step.size else 0.0
    uv = np.where(seen[..., None], uv, -10.0)
    return LitView(
        uv.astype(np.float32), light.astype(np.float32), albedo.astype(np.float32), n, footprint,
        colour,
    )  # fmt: skip


def projector_light(frame: Image, gamma: float, black_level: float) -> NDArray[np.float32]:
    """The light (h, w) in [black_level, 1] a projector sends for a frame (grey or BGR),
    as the grey camera weighs it: each primary's light ``(value / 255) ** gamma`` in
    the shares of OpenCV's BGR-to-grey (a grey frame: the light of its value)."""
    lut = (black_level + (1.0 - black_level) * (np.arange(256) / 255.0) ** gamma).astype(np.float32)
    if frame.ndim == 3 and not _grey(frame):
        weights = np.array(GREY_WEIGHTS, np.float32)
        mixed: NDArray[np.float32] = lut[frame] @ weights
        return mixed
    grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    out: NDArray[np.float32] = lut[grey]
    return out


def _grey(frame: Image) -> bool:
    """Whether a BGR frame's three channels are equal (a broadcast grey one at once)."""
    if frame.strides[2] == 0:
        return True
    return bool(
        np.array_equal(frame[..., 0], frame[..., 1])
        and np.array_equal(frame[..., 1], frame[..., 2])
    )


def clean_capture(
    view: LitView, frame: Image | None, optics: CameraOptics, exposure_us: int, iso: int
) -> NDArray[np.float32]:
    """The camera image (h, w) float32 of ``view`` while the projector shows ``frame``
    (None: the projector is off or covered), before noise and quantisation."""
    gain = (exposure_us / optics.reference_exposure_us) * (iso / optics.reference_iso)
    direct: NDArray[np.float32]
    if frame is None:
        direct = np.zeros(view.light.shape, np.float32)
    elif view.colour is not None and frame.ndim == 3 and not _grey(frame):
        # a coloured frame on a painted surface: each primary's light, reflected as
        # the paint returns that primary, in the grey camera's shares
        sent = np.zeros(view.light.shape, np.float32)
        for c, share in enumerate(GREY_WEIGHTS):
            prim = np.ascontiguousarray(frame[..., c])
            sent += np.float32(share) * view.colour[..., c] * _sent(view, prim, optics)
        direct = np.asarray(sent * view.light * np.float32(optics.white_level), np.float32)
    else:
        sent = _sent(view, frame, optics)
        direct = np.asarray(sent * view.light * np.float32(optics.white_level), np.float32)
    if optics.interreflection > 0:
        # light reflected between the surfaces: a wide blur of the direct light (on a
        # 32x smaller image; it has no detail)
        dh, dw = direct.shape[0], direct.shape[1]
        small = cv2.resize(
            direct, (max(dw // 32, 1), max(dh // 32, 1)), interpolation=cv2.INTER_AREA
        )
        small = cv2.GaussianBlur(small, (0, 0), max(small.shape) / 12.0)
        bounce = cv2.resize(small, (dw, dh), interpolation=cv2.INTER_LINEAR)
        direct = direct + np.asarray(bounce, np.float32) * np.float32(optics.interreflection) * (
            view.albedo > 0
        )
    radiance = direct + view.albedo * np.float32(optics.ambient)
    n = view.supersample
    h, w = radiance.shape[0] // n, radiance.shape[1] // n
    img = np.asarray(cv2.resize(radiance, (w, h), interpolation=cv2.INTER_AREA), np.float32)
    img *= np.float32(gain)
    if optics.blur_px > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), optics.blur_px), np.float32)
    return img


def _sent(view: LitView, frame: Image, optics: CameraOptics) -> NDArray[np.float32]:
    """The projector's light (H, W) reaching each of the view's points for ``frame``
    (grey, or BGR weighed as the grey camera sees it)."""
    lightmap = projector_light(frame, optics.gamma, optics.black_level)
    if view.footprint_px > 1.0:  # a box of the footprint's width, as a Gaussian
        lightmap = np.asarray(
            cv2.GaussianBlur(lightmap, (0, 0), view.footprint_px / np.sqrt(12.0)), np.float32
        )
    mx, my = view.uv[..., 0], view.uv[..., 1]
    sent = cv2.remap(lightmap, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    return np.asarray(sent, np.float32)


def noise_sigma(clean: NDArray[np.float32], optics: CameraOptics) -> NDArray[np.float32]:
    """The camera noise's standard deviation (h, w) at each pixel of a clean image."""
    var = np.float32(optics.read_noise**2) + np.float32(optics.shot_noise) * np.maximum(clean, 0)
    return np.asarray(np.sqrt(var), np.float32)


def expose(
    clean: NDArray[np.float32],
    optics: CameraOptics,
    rng: np.random.Generator,
    sigma: NDArray[np.float32] | None = None,
) -> Image:
    """A clean camera image (h, w) with shot and read noise (``sigma``: its
    :func:`noise_sigma`, when known), quantised to uint8."""
    if sigma is None:
        sigma = noise_sigma(clean, optics)
    img = rng.standard_normal(clean.shape, dtype=np.float32)
    img *= sigma
    img += clean
    np.rint(img, out=img)  # in place: a calibration simulates ~1000 frames of 1280x800
    np.clip(img, 0, 255, out=img)
    return img.astype(np.uint8)


def render_capture(
    view: LitView,
    frame: Image | None,
    optics: CameraOptics,
    exposure_us: int,
    iso: int,
    rng: np.random.Generator,
) -> Image:
    """The grey camera image (h, w) uint8 of ``view`` while the projector shows
    ``frame`` (None: the projector is off or covered)."""
    return expose(clean_capture(view, frame, optics, exposure_us, iso), optics, rng)
