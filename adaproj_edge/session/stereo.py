"""An OAK-D-like stereo error model: true depth in, a depth frame as the camera gives it.

- depth from disparity ``d = f B / z``: white plus spatially correlated disparity
  noise (block matching), so the depth error grows with z^2;
- disparity quantised to 1/2^bits pixel (subpixel mode), then median-filtered as the
  device does (``median`` = 0, 3 or 5; the board's 7x7 is approximated by 5x5);
- invalid (0) pixels: beyond the disparity search range (too close) or too far, at
  depth discontinuities (left-right check), in the left border band the other camera
  does not see, at grazing angles (more likely the more grazing), random dropouts.

:meth:`StereoNoise.of_sensor` is what a real sensor shows
(:class:`~adaproj_edge.geometry.depth.sensor.SensorModel`, on by default in
``adaproj simulate-session``): its matcher's random error as the model has it
(``disparity_sigma_px``, correlated over the model's footprint, the matcher's window),
so every wall comes out as a noisy staircase of steps ``z^2 / (f B 2^bits)`` whose
per-pixel spread is the model's ``disparity_total_px`` (what the device's smoothing,
plane snapping and cuts assume, and what real Kinect-class frames measure: 0.09-0.10
px); and besides:

- the band beside a silhouette the other camera cannot see (``occlusion``): with the
  right camera to the right of the reference (left) one, the background just left of
  a foreground object;
- flying pixels (``flying``: the fraction of pixels at a depth jump that get a depth
  between its two sides instead of none);
- holes on untextured or dark patches (``untextured``: the fraction of the surface,
  in patches fixed to the world, with no depth).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import DepthCameraModel
from adaproj_edge.geometry.depth.sensor import SENSORS, SensorKind, SensorModel

SMOOTH = "smooth"
"""The name of the smooth noise model (no visible steps, no edges' artefacts)."""

DEFAULT_SENSOR = "oak-d"
"""The sensor whose frames sessions are simulated with unless told otherwise."""

NOISE_MODELS = (*SENSORS, SMOOTH)
"""Every noise model by name: the real sensors' (:data:`SENSORS`), then the smooth one."""


@dataclass(frozen=True)
class StereoNoise:
    """Parameters of the stereo error model (pixels of disparity unless stated); the
    defaults are the smooth model, :meth:`named` gives a real sensor's; ``name`` says
    which (recorded in a simulated session's metadata)."""

    white_px: float = 0.1
    correlated_px: float = 0.1
    correlation_px: float = 4.0
    subpixel_bits: int = 3
    max_disparity_px: float = 95.0
    max_depth_m: float = 12.0
    dropout: float = 0.01
    grazing_cos: float = 0.3
    edge_jump: float = 0.04
    median: int = 5
    occlusion: bool = False
    flying: float = 0.0
    untextured: float = 0.0
    name: str = SMOOTH

    @classmethod
    def of_sensor(cls, sensor: SensorModel | SensorKind) -> StereoNoise:
        """A real sensor's frames: its step, its matcher's random error (the model's
        ``disparity_sigma_px``, correlated over its ``footprint_px``: a staircase on
        every wall, dithered as much as the device's model says), occlusion bands,
        flying pixels, untextured holes."""
        return cls(
            name=sensor.name,
            white_px=0.0,
            correlated_px=sensor.disparity_sigma_px,
            correlation_px=max(sensor.footprint_px, 1.0),
            subpixel_bits=sensor.subpixel_bits,
            occlusion=True,
            flying=0.3,
            untextured=0.03,
        )

    @classmethod
    def named(cls, name: str) -> StereoNoise:
        """The frames of the sensor ``name`` (:data:`NOISE_MODELS`): a real sensor's
        (:meth:`of_sensor`), or ``"smooth"``: smooth noise only, no visible steps."""
        if name == SMOOTH:
            return cls()
        kind = SENSORS.get(name)
        if kind is None:
            raise InputError(f"unknown depth sensor {name!r}: one of {', '.join(NOISE_MODELS)}")
        return cls.of_sensor(kind)


def default_noise() -> StereoNoise:
    """The noise model sessions are simulated with by default: :data:`DEFAULT_SENSOR`'s."""
    return StereoNoise.named(DEFAULT_SENSOR)


def normals_cos(points: FloatArray) -> FloatArray:
    """|cos| of the angle between the surface normal and the view ray, (h, w); NaN = none.

    The normal is the cross product of the point map's gradients along the rows and
    the columns, worked out component by component (the point map's channels are
    views: no (h, w, 3) temporaries)."""
    p = np.moveaxis(np.asarray(points), -1, 0)  # (3, h, w)
    dx = np.gradient(p, axis=2)
    dy = np.gradient(p, axis=1)
    nx = dx[1] * dy[2] - dx[2] * dy[1]
    ny = dx[2] * dy[0] - dx[0] * dy[2]
    nz = dx[0] * dy[1] - dx[1] * dy[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        dot = nx * p[0] + ny * p[1] + nz * p[2]
        norms = (nx * nx + ny * ny + nz * nz) * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        return np.abs(dot) / np.sqrt(norms)  # type: ignore[no-any-return]


def occluded(disparity: FloatArray, valid: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Pixels (h, w) of the reference (left) camera the right camera does not see: a
    point at column u with disparity d lands at u - d there, hidden when a closer point
    to its right lands left of it (at u' - d' < u - d)."""
    h, w = disparity.shape
    cols = np.arange(w, dtype=np.float64)[None, :]
    m = np.where(valid, cols - disparity, np.inf)
    # the least u' - d' over u' > u: a running minimum from the right, shifted by one
    right = np.minimum.accumulate(m[:, ::-1], axis=1)[:, ::-1]
    after = np.concatenate([right[:, 1:], np.full((h, 1), np.inf)], axis=1)
    return valid & (after < cols - disparity - 0.5)


def untextured_patches(points_w: FloatArray, fraction: float) -> NDArray[np.bool_]:
    """Where (h, w) world points (h, w, 3) fall on untextured patches (about
    ``fraction`` of a surface, patches some 20 cm across, fixed to the world)."""
    x, y, z = points_w[..., 0], points_w[..., 1], points_w[..., 2]
    with np.errstate(invalid="ignore"):
        t = np.sin(9.0 * x + 4.0 * z + 1.3) * np.sin(8.0 * y - 5.0 * z + 0.7)
        t *= np.sin(5.0 * (x - y) + 3.0 * z)
        limit = 1.0 - 2.2 * fraction**0.5  # |t| near 1 on about this fraction
        return np.asarray(np.isfinite(t) & (t > limit))


def stereo_depth(
    points: FloatArray,
    model: DepthCameraModel,
    noise: StereoNoise,
    rng: np.random.Generator,
    points_w: FloatArray | None = None,
) -> NDArray[np.uint16]:
    """Depth frame (h, w) uint16 mm of true points (h, w, 3) in frame D (NaN = none);
    ``points_w``: the same points in the world, for the untextured patches."""
    z = points[..., 2]
    h, w = z.shape
    valid = np.isfinite(z) & (z > 0)
    zt = np.where(valid, z, 1.0)
    fb = model.focal * model.baseline_m
    d = fb / zt
    field = rng.normal(size=(h, w)).astype(np.float32)
    sigma = noise.correlation_px
    field = cv2.GaussianBlur(field, (0, 0), sigma).astype(np.float64)
    field *= noise.correlated_px / max(float(field.std()), 1e-12)
    dn = d + field + rng.normal(scale=noise.white_px, size=(h, w))
    q = 2.0**noise.subpixel_bits
    counts = np.clip(np.round(np.where(valid, dn, 0.0) * q), 0, 65535).astype(np.uint16)
    if noise.median:
        counts = np.asarray(cv2.medianBlur(counts, noise.median), np.uint16)  # as on the device
    dq = counts.astype(np.float64) / q
    valid &= (
        (dq > 0) & (dq <= noise.max_disparity_px) & (fb / np.maximum(dq, 1e-9) < noise.max_depth_m)
    )
    # left-right check fails at depth discontinuities and where only one camera sees
    zz = np.where(valid, zt, np.nan)
    with np.errstate(invalid="ignore"):
        jump = np.zeros((h, w), bool)
        jx = np.abs(np.diff(zz, axis=1)) > noise.edge_jump * zz[:, 1:]
        jy = np.abs(np.diff(zz, axis=0)) > noise.edge_jump * zz[1:, :]
        jump[:, 1:] |= jx
        jump[:, :-1] |= jx
        jump[1:, :] |= jy
        jump[:-1, :] |= jy
        edge = ~np.isfinite(zz)
        edge = cv2.dilate(edge.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    jump = cv2.dilate(jump.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    if noise.flying > 0:
        # some pixels at a jump report a depth between its two sides
        lo = cv2.erode(np.where(valid, zt, 1e9).astype(np.float32), np.ones((3, 3), np.uint8))
        hi = cv2.dilate(np.where(valid, zt, 0.0).astype(np.float32), np.ones((3, 3), np.uint8))
        fly = jump & valid & (rng.random((h, w)) < noise.flying)
        t = rng.random((h, w))
        mixed = t * lo + (1 - t) * hi
        dq = np.where(fly, fb / np.maximum(mixed, 1e-3), dq)
        jump &= ~fly
    valid &= ~jump
    valid &= ~(edge & (rng.random((h, w)) < 0.5))
    if noise.occlusion:
        valid &= ~occluded(d, np.isfinite(z) & (z > 0))
    if noise.untextured > 0 and points_w is not None:
        valid &= ~untextured_patches(points_w, noise.untextured)
    cols = np.arange(w)[None, :]
    valid &= cols >= d  # the left border band the right camera does not see
    cos = normals_cos(np.where(valid[..., None], points, np.nan))
    p_graze = np.clip(
        (noise.grazing_cos - np.nan_to_num(cos, nan=1.0)) / (noise.grazing_cos / 2), 0, 1
    )
    valid &= rng.random((h, w)) >= p_graze
    valid &= rng.random((h, w)) >= noise.dropout
    depth_mm = np.where(valid, np.round(fb / np.where(valid, dq, 1.0) * 1000.0), 0.0)
    return np.clip(depth_mm, 0, 65535).astype(np.uint16)
