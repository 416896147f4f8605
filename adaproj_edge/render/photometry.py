"""Even brightness from the surface alone: a gain map that evens out the projector's
light over the picture, and its application to a frame.

The relative irradiance ``E`` of every projector pixel comes from the surface's
distance and incidence and the lens's vignetting
(:func:`~adaproj_edge.geometry.irradiance.relative_irradiance`; on a lattice coarser
than the gain, as the device's, from its snapped planes and its nodes' light:
:func:`~adaproj_edge.geometry.surface_irradiance.irradiance_at`). A Lambertian surface
looks as bright as it is lit from every direction, so evening out ``E`` evens out
what every viewer sees of uniform content (the surface's own colour and the room's
light are not known here: not compensated).

The target brightness ``B <= E`` follows Majumder and Stevens ("Perceptual photometric
seamlessness in projection-based tiled displays", ACM Transactions on Graphics 24(1),
2005): not flat down to the dimmest pixel, but smooth enough that the eye does not see
it vary, and no dimmer than needed. Here:

- smooth: ``log B`` changes by at most ``gradient_per_deg`` (relative brightness) per
  degree of visual angle, taking one projector pixel to subtend about what it does
  from the projector (a viewer about as far from the surface as the device). ``B`` is
  the largest such function below ``E`` (a lower envelope, two sweeps per axis), so it
  stays continuous across a crease where ``E`` jumps, and the gain ``B / E`` jumps
  instead;
- even: ``B`` is capped at ``evenness`` times the dimmest ``E`` (a low quantile, so a
  few grazing pixels do not dim the picture);
- within the budget: the mean brightness over the picture (weighted by surface area:
  what a viewer sees) stays at least ``budget`` times the uncompensated mean. When the
  smooth target alone dims more, its gradient bound is loosened in doublings; when the
  cap does, the cap is raised until the budget holds (the picture is left less even;
  :attr:`GainMap.reason` says so and it is logged). Light that cannot be evened out
  smoothly within the budget at all is left as it is (a gain of 1).

The gain never brightens, and the picture's max/min never grows: every pixel keeps at
least the light of the dimmest judged pixel, or its own.

The gain is for light; the pixel values are multiplied by ``gain ** (1 / gamma)`` (the
projector's response ``light ~ value ** gamma``), as an 8-bit fixed-point map at the
frame's size, made once per pose: a frame costs one saturating multiply.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, Float32Array, FloatArray, Image
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.irradiance import Vignetting, relative_irradiance
from adaproj_edge.geometry.planes import plane_equations
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.geometry.surface_irradiance import (
    irradiance_at,
    node_irradiance,
    plane_irradiance,
)

log = logging.getLogger(__name__)

MAX_LOOSEN = 6
"""Doublings of the gradient bound tried when even the smooth envelope breaks the budget."""
KINK = 0.005
"""A reduced pixel whose log gain bends by more than this (its second difference along
a row or column) is taken to be beside a crease: the gain there is made at every frame
pixel (:func:`crease_gain`). Smooth light on the reduced frame bends it by far less
(its second differences are below 1e-4 on smooth surfaces)."""
FINE_LATTICE = 0.55
"""The gain is made apart beside a crease only on a surface whose lattice step is at
most this share of the reduced frame's pixel: on the 90-degree corner at 1/4, a
lattice of 1 or 2 frame pixels gives max/min 1.07 and 1.10 with it (1.12 and 1.14
without), one of 3 or 4 pixels 1.17 and 1.33 (1.14 without)."""
MAX_ROUGHNESS = 0.01
"""The median |second difference| of log irradiance between neighbouring pixels of the
reduced frame above which the normals are taken to follow depth noise, not the surface:
smooth surfaces, creased or carrying relief, stay under 1e-4; a stereo staircase of
depth steps fed in unsmoothed gives 0.08 and more."""
MAX_NODE_ROUGHNESS = 0.05
"""The same limit for a lattice coarser than the reduced frame, judged on its nodes'
own light before it is blurred (:mod:`adaproj_edge.geometry.surface_irradiance`; the
blur absorbs noise of that size): the device's estimated surfaces give 0.0001-0.015
(a bowl at 1.75 m the most), the stereo staircase fed in unsmoothed on a 4-pixel
lattice 0.17."""


@dataclass(frozen=True)
class PhotometrySettings:
    """How the gain map is made.

    Attributes
    ----------
    gradient_per_deg : float
        The largest relative change of brightness per degree of visual angle (0.01: 1 %
        per degree, below what the eye notices in a smooth ramp).
    evenness : float
        The target max/min of the brightness over the picture (some room is left
        below a 1.10 goal for the frame's 8-bit steps).
    budget : float
        The mean brightness after compensation, at least this share of the mean before.
    gamma : float
        The projector's response: light ~ (pixel value / 255) ** gamma.
    scale : int
        The gain is computed at 1/``scale`` of the frame and interpolated up (a crease
        is resolved to about ``scale`` pixels; the cost grows as ``1 / scale^2``).
    dim_quantile : float
        The share of the lit pixels allowed below the cap's reference (the dimmest
        pixels, mostly grazing ones at a silhouette).
    """

    gradient_per_deg: float = 0.01
    evenness: float = 1.05
    budget: float = 0.7
    gamma: float = 2.2
    scale: int = 2
    dim_quantile: float = 0.001

    def __post_init__(self) -> None:
        if not 0.0 < self.gradient_per_deg <= 1.0:
            raise InputError("photometry gradient_per_deg must be in (0, 1]")
        if not 1.0 <= self.evenness <= 10.0:
            raise InputError("photometry evenness must be in [1, 10]")
        if not 0.0 < self.budget <= 1.0:
            raise InputError("photometry budget must be in (0, 1]")
        if not 1.0 <= self.gamma <= 4.0:
            raise InputError("photometry gamma must be in [1, 4]")
        if not 1 <= self.scale <= 16:
            raise InputError("photometry scale must be in [1, 16]")
        if not 0.0 <= self.dim_quantile < 0.5:
            raise InputError("photometry dim_quantile must be in [0, 0.5)")


@dataclass(frozen=True)
class GainMap:
    """A frame's brightness gain, made from its surface.

    Attributes
    ----------
    light : (h, w) or (h, w, 3) float32 array
        The gain of light (<= 1) at 1/``scale`` of the frame; 1 where no surface. Three
        channels (blue, green, red): a gain per primary
        (:func:`adaproj_edge.render.reflectance.colour_gain`).
    size : (width, height)
        The frame's size.
    gamma : float
        The projector's response the pixel gain is made for.
    ratio_before, ratio_after : float
        Max/min of the relative irradiance over the lit pixels, before and after.
    mean_ratio : float
        Mean brightness after over before.
    gradient_per_deg : float
        The largest relative change of the brightness after, per degree.
    reason : str or None
        Why the picture was left less even than asked (None: it was not).
    fine : (indices, light) or None
        Full-frame pixels (flat indices, intp) whose gain of light (float32) is set
        apart from the interpolation of :attr:`light`: beside a crease, where the gain
        jumps (:func:`gain_map`). Grey gains only.
    """

    light: Float32Array
    size: tuple[int, int]
    gamma: float
    ratio_before: float
    ratio_after: float
    mean_ratio: float
    gradient_per_deg: float
    reason: str | None = None
    fine: tuple[NDArray[np.intp], Float32Array] | None = field(default=None, compare=False)
    _pixels: dict[int, Image] = field(default_factory=dict, repr=False, compare=False)

    def pixels(self, channels: int = 3) -> Image:
        """The 8-bit multiplier of pixel values (H, W[, channels]): 255 is 1; made on
        first use and kept (the pose cache keeps the gain map with its warp)."""
        got = self._pixels.get(channels)
        if got is None:
            w, h = self.size
            big = cv2.resize(self.light, (w, h), interpolation=cv2.INTER_LINEAR)
            if self.fine is not None and big.ndim == 2:
                big.reshape(-1)[self.fine[0]] = self.fine[1]
            factor = np.power(np.clip(big, 0.0, 1.0), 1.0 / self.gamma)
            one = np.rint(255.0 * factor).astype(np.uint8)
            if one.ndim == 3:
                if channels != one.shape[2]:
                    raise InputError(f"a colour gain does not fit a {channels}-channel frame")
                got = one
            else:
                got = one if channels == 1 else np.repeat(one[..., None], channels, axis=2)
            self._pixels[channels] = got
        return got

    def summary(self) -> dict[str, float | str | None]:
        """The figures of :attr:`ratio_before` and the rest, for reports."""
        return {
            "ratio_before": round(self.ratio_before, 4),
            "ratio_after": round(self.ratio_after, 4),
            "mean_ratio": round(self.mean_ratio, 4),
            "gradient_per_deg": round(self.gradient_per_deg, 5),
            "reason": self.reason,
        }


def apply_gain(
    frame: NDArray[np.uint8], gain: GainMap, out: NDArray[np.uint8] | None = None
) -> NDArray[np.uint8]:
    """``frame`` (H, W[, 3]) uint8 with each pixel's value multiplied by its gain
    (rounded, in 8 bits: no float copy of the frame); drawn into ``out`` when it has
    the frame's shape and type (``out`` may be ``frame`` itself)."""
    channels = 1 if frame.ndim == 2 else int(frame.shape[2])
    g = gain.pixels(channels)
    if g.shape != frame.shape:
        raise InputError(f"gain map {g.shape} does not fit the frame {frame.shape}")
    dst = out if out is not None and out.shape == frame.shape and out.dtype == np.uint8 else None
    got = cv2.multiply(frame, g, dst=dst, scale=1.0 / 255.0)
    return np.asarray(got, dtype=np.uint8)


def degrees_per_pixel(projector: Projector) -> float:
    """The visual angle (degrees) of one projector pixel seen from the projector."""
    f = math.sqrt(float(projector.K[0, 0]) * float(projector.K[1, 1]))
    return math.degrees(1.0 / f)


def reduced_grid(projector: Projector, scale: int) -> FloatArray:
    """The pixel centres (h, w, 2) of the frame at 1/``scale``, in full-frame pixels
    (centres aligned, as ``cv2.resize`` and the display maps align them)."""
    h, w = max(projector.height // scale, 2), max(projector.width // scale, 2)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    sx, sy = projector.width / w, projector.height / h
    return np.stack([(u + 0.5) * sx - 0.5, (v + 0.5) * sy - 0.5], axis=-1)


def gain_map(
    surface: Surface,
    vignetting: Vignetting | None = None,
    settings: PhotometrySettings | None = None,
    picture: BoolArray | None = None,
) -> GainMap:
    """The gain map of ``surface`` (any lattice; its projector gives the frame).

    Parameters
    ----------
    surface : Surface
        The surface the frame is projected on.
    vignetting : Vignetting, optional
        The projector lens's falloff (the calibration's); None: none.
    settings : PhotometrySettings, optional
    picture : (H, W) or (h, w) bool array, optional
        Where the frame shows content (the full frame, or the reduced one): evenness
        and the budget are judged there. None: wherever the surface is lit.

    Returns
    -------
    GainMap
    """
    s = settings or PhotometrySettings()
    p = surface.projector
    uv = reduced_grid(p, s.scale)
    h, w = uv.shape[:2]
    got = irradiance_at(surface, uv, vignetting)
    e, rough = got.light, got.roughness
    # surface area per pixel ~ d^2 / cos = V / E: brightness means are over the surface
    v = np.ones((h, w)) if vignetting is None else vignetting.at(p, uv)
    with np.errstate(invalid="ignore", divide="ignore"):
        area = v / e
    mask = None
    if picture is not None:
        mask = np.asarray(picture, dtype=bool)
        if mask.shape != (h, w):
            pic = mask.astype(np.uint8) * 255
            mask = cv2.resize(pic, (w, h), interpolation=cv2.INTER_AREA) > 127
    step = degrees_per_pixel(p) * p.width / w
    limit = MAX_NODE_ROUGHNESS if got.smoothed else MAX_ROUGHNESS
    stats: Stats
    fine = None
    if rough > limit:
        said = (
            f"the surface's light varies from pixel to pixel ({rough:.3f} > {limit}): "
            "its normals follow depth noise, not compensated"
        )
        light, stats = np.ones((h, w), np.float32), (1.0, 1.0, 1.0, 0.0, said)
    else:
        light, target, stats = _solve(e, step, s, mask, area)
        if target is not None:
            fine = crease_gain(surface, vignetting, light, target)
    gm = GainMap(light, (p.width, p.height), s.gamma, *stats, fine=fine)
    if gm.reason is not None:
        log.info("photometric compensation: %s", gm.reason)
    return gm


def crease_gain(
    surface: Surface,
    vignetting: Vignetting | None,
    light: Float32Array,
    target: FloatArray,
) -> tuple[NDArray[np.intp], Float32Array] | None:
    """The gain of the full-frame pixels beside a crease (flat indices and gain of
    light), where interpolating ``light`` (h, w, at a fraction of the frame) would
    blend the two walls' gains; None where the gain bends nowhere.

    A reduced pixel is beside a crease when its log gain bends by more than ``KINK``
    along a row or column (smooth light bends it by far less). It and its two
    neighbours along the crease (across the direction it bends in) are made again at
    every frame pixel they cover: the irradiance there from the surface (normals from
    the full-frame lattice, each wall's own) and the smooth target ``target`` (log,
    continuous across the crease) interpolated, so the gain jumps where the surface
    bends, not over a reduced pixel. Only on a surface sampled at least twice as finely
    as the reduced frame (``FINE_LATTICE``), or whose walls were snapped onto planes
    (their pixels' light is exact: :func:`~adaproj_edge.geometry.surface_irradiance.
    plane_irradiance`; the rest is its nodes' light): between the nodes of a coarser
    lattice the surface is bilinear, and the normals of the patch that straddles the
    crease are neither wall's.
    """
    p = surface.projector
    h, w = light.shape
    sx, sy = p.width / w, p.height / h
    lx, ly = surface.lattice_scale()
    fine = lx <= FINE_LATTICE * sx and ly <= FINE_LATTICE * sy
    if (sx <= 1.0 and sy <= 1.0) or not (fine or plane_equations(surface.meta).size):
        return None  # the frame's pixels know no more of the surface than the reduced ones
    lg = np.log(light.astype(np.float64))
    along_x = np.zeros((h, w), np.uint8)
    along_y = np.zeros((h, w), np.uint8)
    along_x[:, 1:-1] = np.abs(lg[:, 2:] - 2.0 * lg[:, 1:-1] + lg[:, :-2]) > KINK
    along_y[1:-1, :] = np.abs(lg[2:] - 2.0 * lg[1:-1] + lg[:-2]) > KINK
    if not (along_x.any() or along_y.any()):
        return None
    # a crease cutting a cell's corner off bends the gain at the corner's neighbours
    # across it, not at the corner: each bend reaches one pixel along the crease
    across_x = np.asarray(cv2.dilate(along_x, np.ones((3, 1), np.uint8)), bool)
    across_y = np.asarray(cv2.dilate(along_y, np.ones((1, 3), np.uint8)), bool)
    # runs of reduced pixels down each column, each made as one strip of frame pixels
    # with a margin of two (the normals' stencil); the strips stacked along the rows,
    # so a node's stencil stays within its own strip
    ix, iy = np.nonzero((across_x | across_y).T)  # column by column, rows in order
    start = np.ones(ix.size, bool)
    start[1:] = (ix[1:] != ix[:-1]) | (iy[1:] != iy[:-1] + 1)
    end = np.roll(start, -1)
    end[-1] = True
    m = 2
    bw, bh = math.ceil(sx), math.ceil(sy)
    top = np.floor(iy[start] * sy).astype(np.intp) - m
    rows = np.floor(iy[end] * sy).astype(np.intp) + bh + m - top
    left = np.floor(ix[start] * sx).astype(np.intp) - m
    first = np.cumsum(rows) - rows
    k = np.arange(int(rows.sum())) - np.repeat(first, rows)  # the row within its strip
    v = np.repeat(top, rows) + k
    u = np.repeat(left, rows)[:, None] + np.arange(bw + 2 * m)[None, :]
    v = np.broadcast_to(v[:, None], u.shape)
    uv = np.stack([u, v], axis=-1).astype(np.float64)
    inner = (k >= m) & (k < np.repeat(rows, rows) - m)
    u, v = u[inner, m:-m], v[inner, m:-m]
    at = np.stack([u, v], axis=-1).astype(np.float64)
    e, on = plane_irradiance(surface, at, vignetting)  # exact on snapped planes
    if not on.all():
        if fine:
            rest = relative_irradiance(surface.points_at(uv), p, uv, vignetting)[inner, m:-m]
        else:  # the lattice's cells are no guide at a frame pixel: its nodes' light
            rest = node_irradiance(surface, at, vignetting)
        e = np.where(on, e, rest)
    t = _bilinear(target, (u + 0.5) / sx - 0.5, (v + 0.5) / sy - 0.5)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = np.minimum(np.exp(t) / e, 1.0)
    ok = np.isfinite(g) & (u < p.width) & (v < p.height)
    return (v * p.width + u)[ok].astype(np.intp), g[ok].astype(np.float32)


def _bilinear(a: FloatArray, x: FloatArray, y: FloatArray) -> FloatArray:
    """``a`` (h, w; both >= 2) at the fractional pixels ``x``, ``y`` (...), its edge
    held beyond it (as ``cv2.resize`` samples)."""
    h, w = a.shape
    x = np.clip(x, 0.0, w - 1.0)
    y = np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(x.astype(np.intp), w - 2)
    y0 = np.minimum(y.astype(np.intp), h - 2)
    fx, fy = x - x0, y - y0
    top = a[y0, x0] * (1.0 - fx) + a[y0, x0 + 1] * fx
    bottom = a[y0 + 1, x0] * (1.0 - fx) + a[y0 + 1, x0 + 1] * fx
    out: FloatArray = top * (1.0 - fy) + bottom * fy
    return out


Stats = tuple[float, float, float, float, str | None]


def gain_from_irradiance(
    irradiance: FloatArray,
    deg_per_px: float,
    settings: PhotometrySettings,
    picture: BoolArray | None = None,
    area: FloatArray | None = None,
) -> tuple[Float32Array, Stats]:
    """The light gain (h, w) for the relative irradiance ``irradiance`` (h, w; NaN
    where nothing is lit) on a lattice of ``deg_per_px`` degrees, and its figures
    (ratio before, ratio after, mean ratio, gradient per degree, reason).

    ``picture`` (h, w): where evenness and the budget are judged (None: every lit
    pixel); ``area`` (h, w): the surface area of each pixel, the weight of its
    brightness in the means (None: equal).
    """
    gain, _, stats = _solve(irradiance, deg_per_px, settings, picture, area)
    return gain, stats


def _solve(
    irradiance: FloatArray,
    deg_per_px: float,
    settings: PhotometrySettings,
    picture: BoolArray | None,
    area: FloatArray | None,
) -> tuple[Float32Array, FloatArray | None, Stats]:
    """:func:`gain_from_irradiance`, and the log of its smooth target (h, w; finite
    everywhere, the gain is ``min(exp(target) / irradiance, 1)``), None when the gain
    is 1 throughout."""
    s = settings
    lit = np.isfinite(irradiance) & (irradiance > 0)
    judged = lit if picture is None else lit & picture
    gain = np.ones(irradiance.shape, np.float32)
    if np.count_nonzero(judged) < 2:
        return gain, None, (1.0, 1.0, 1.0, 0.0, "no lit picture to even out")
    weight = np.ones(irradiance.shape) if area is None else np.asarray(area, np.float64)
    wj = np.where(np.isfinite(weight[judged]), weight[judged], 0.0)
    le = np.full(irradiance.shape, np.inf)
    le[lit] = np.log(irradiance[lit])
    values = le[judged]
    # only the picture constrains the target (a dim silhouette outside it shows black),
    # and its dimmest few (grazing) pixels neither set the cap nor pull the target
    # down around them: they keep their own light
    floor = float(np.quantile(values, s.dim_quantile))
    bounded = np.where(judged & (le >= floor), le, np.inf)
    total_before = float(np.sum(wj * np.exp(values)))
    want = s.budget * total_before

    def total_of(logs: FloatArray) -> float:
        return float(np.dot(wj, np.exp(logs)))

    # L1-Lipschitz per pixel step: at most sqrt(2) times that in any direction
    bound = math.log1p(s.gradient_per_deg) * deg_per_px / math.sqrt(2.0)
    reasons = []
    smooth = _lower_envelope(bounded, bound)
    env = np.minimum(smooth, le)
    loosened = 0
    while total_of(env[judged]) < want and loosened < MAX_LOOSEN:
        loosened += 1
        smooth = _lower_envelope(bounded, bound * 2**loosened)
        env = np.minimum(smooth, le)
    before = _ratio(values)
    if total_of(env[judged]) < want:
        reason = (
            "the light varies too steeply to even out smoothly within the budget: not compensated"
        )
        return gain, None, (before, before, 1.0, 0.0, reason)
    if loosened:
        reasons.append(
            f"the gradient bound was loosened {2**loosened}x to keep "
            f"{s.budget:.0%} of the brightness"
        )
    cap = floor + math.log(s.evenness)
    kept = _capped_total(np.exp(env[judged]), wj)
    if kept(math.exp(cap)) < want:
        asked = kept(math.exp(cap)) / total_before
        cap = math.log(_lowest_cap(np.exp(env[judged]), wj, want))
        reasons.append(
            f"evening out to {s.evenness:.2f} would keep {asked:.0%} of the brightness "
            f"(budget {s.budget:.0%}): left at {math.exp(cap - floor):.2f}"
        )
    target = np.minimum(env, cap)
    gain[lit] = np.minimum(np.exp(target[lit] - le[lit]), 1.0).astype(np.float32)
    after = target[judged]
    mean_ratio = total_of(after) / total_before
    # the change of what the target sets (the dimmest few keep their own, as before)
    grad = _max_log_gradient(np.where(np.isfinite(bounded), target, np.nan)) / deg_per_px
    said = "; ".join(reasons) if reasons else None
    return (
        gain,
        np.minimum(smooth, cap),
        (before, _ratio(after), mean_ratio, math.expm1(grad), said),
    )


def _capped_total(values: FloatArray, weights: FloatArray) -> Callable[[float], float]:
    """``c -> sum(weights * min(values, c))``."""

    def total(c: float) -> float:
        return float(np.dot(weights, np.minimum(values, c)))

    return total


def _lowest_cap(values: FloatArray, weights: FloatArray, want: float) -> float:
    """The least ``c`` with ``sum(weights * min(values, c)) >= want`` (exact: the sum is
    piecewise linear in ``c`` between the sorted values; ``want`` at most the sum of
    ``weights * values``)."""
    order = np.argsort(values)
    x, w = values[order], weights[order]
    below = np.concatenate([[0.0], np.cumsum(w * x)])  # sum over the k smallest
    above = float(w.sum()) - np.concatenate([[0.0], np.cumsum(w)])  # weight of the rest
    at_x = below[:-1] + x * above[:-1]  # the total when capped at x[k]
    k = int(np.searchsorted(at_x, want))
    if k >= x.size:
        return float(x[-1])
    return float((want - below[k]) / above[k]) if above[k] > 0 else float(x[k])


def _ratio(log_values: FloatArray) -> float:
    return float(math.exp(float(log_values.max() - log_values.min())))


def _max_log_gradient(lv: FloatArray) -> float:
    """The largest |grad| (per pixel) of ``lv`` (h, w) from forward differences between
    lit neighbours (NaN: unlit)."""
    dx = np.diff(lv, axis=1)[:-1, :]
    dy = np.diff(lv, axis=0)[:, :-1]
    g = np.hypot(dx, dy)
    g = g[np.isfinite(g)]
    return float(g.max()) if g.size else 0.0


def _lower_envelope(values: FloatArray, step: float) -> FloatArray:
    """The largest function below ``values`` (h, w; +inf: no constraint) that changes
    by at most ``step`` per pixel along each axis (L1-Lipschitz): two sweeps per axis,
    each a loop over columns or rows of vector operations."""
    out = values.copy()
    _sweep(out, step)
    _sweep(out.T, step)
    return out


def _sweep(a: FloatArray, step: float) -> None:
    """In place: ``a[:, j] = min(a[:, j], a[:, j -+ 1] + step)`` forward, then back."""
    cols = a.shape[1]
    for j in range(1, cols):
        np.minimum(a[:, j], a[:, j - 1] + step, out=a[:, j])
    for j in range(cols - 2, -1, -1):
        np.minimum(a[:, j], a[:, j + 1] + step, out=a[:, j])
