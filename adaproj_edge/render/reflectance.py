"""The surface's own colour and the room's light, measured: a colour mixing matrix and
an ambient offset per projector pixel, and the compensation that undoes them.

The model is Grossberg and Nayar's ("Making one object look like another: controlling
appearance using a projector-camera system", CVPR 2004): what is seen of projector
pixel ``x`` is linear in the light it sends,

    L(x) = M(x) p(x) + a(x),

``p`` (3,) the projector's light per primary (blue, green, red; ``(value / 255) **
gamma``), ``M`` (3, 3) how much of each primary the surface returns in each colour
(its reflectance times the irradiance, and the projector's and camera's colour
crosstalk) and ``a`` (3,) the room's light (and the projector's black). A few captures
measure both (:func:`measure`): black gives ``a``, each primary at full a column of
``M``, and white checks that the primaries add up. A grey camera sees one number per
capture: each primary's capture is then divided by the camera's known sensitivity to
that primary (``weights``) and ``M`` is taken diagonal (the surface's reflectance per
primary; the room's light is tinted as the surface tints the projector's white).

Compensation (:func:`plan`, :func:`compensate`) asks for ``L = s t + b`` for content
``t`` (linear light in [0, 1]): one global scale ``s`` for every pixel and a uniform
black ``b``, so ``p = M^-1 (s t + b - a)``. ``s`` is the largest white most pixels can
show (a low quantile of what each pixel can reach, so little clips), but no less than
``min_brightness`` of the plain picture's mean (a few dark patches fall short rather
than dim everything); where a pixel cannot reach it, its light is scaled back along the
line from its black to the target (hue kept, as bright as it can be: clipping-aware,
after Grundhoefer and Iwai, "Robust, error-tolerant photometric projector
compensation", IEEE TIP 2015). A surface on which more than ``max_clipped`` of the
picture would fall short is refused.

Per displayed frame (:func:`colour_gain`) the compensation is a gain per pixel and
primary in 8 bits (one saturating multiply, like the geometric gain); the room's light
on the surface is left as it is there (``b = a``: no offset per frame).

Pure: arrays in, arrays out. The captures reach it mapped to projector pixels
(:func:`adaproj_edge.procam.photometric.to_projector`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import BoolArray, Float32Array, FloatArray
from adaproj_edge.errors import CalibrationError, InputError
from adaproj_edge.render.photometry import GainMap

log = logging.getLogger(__name__)

PRIMARY_WEIGHTS = (0.114, 0.587, 0.299)
"""A grey camera's response to the projector's blue, green and red at full, as shares
of its response to white (OpenCV's BGR-to-grey weights: what the simulated camera
sees; a unit's own come from its calibration)."""

PRIMARY_NAMES = ("blue", "green", "red")


@dataclass(frozen=True)
class ReflectanceSettings:
    """How captures are judged and the compensation chosen.

    Attributes
    ----------
    saturation : float
        The camera level (of 255) at and above which a capture pixel is saturated.
    max_saturated : float
        The share of the picture a capture may have saturated (those pixels are left
        out); more is refused (the exposure is too long).
    min_contrast : float
        The median of white minus black (camera levels) below which the captures are
        refused as dark (projector off or covered, or the room far brighter).
    max_disagreement : float
        The median relative difference between white and the sum of the primaries
        (each less black) above which the captures are refused (something changed
        between them).
    clip_quantile : float
        The share of the picture allowed to fall short of the global white.
    min_brightness : float
        The compensated white, at least this share of the plain picture's mean white
        (more of the picture falls short of it then).
    max_clipped : float
        The share of the picture that may fall short of the compensated white; a
        surface darker than that is refused (the geometric gain alone is used).
    chroma_sigma : float
        A grey camera's colour ratios are smoothed over this many pixels (Gaussian
        sigma; 0: not smoothed).
    gamma : float
        The projector's response: light ~ (value / 255) ** gamma.
    """

    saturation: float = 250.0
    max_saturated: float = 0.01
    min_contrast: float = 8.0
    max_disagreement: float = 0.15
    clip_quantile: float = 0.02
    min_brightness: float = 0.25
    max_clipped: float = 0.25
    chroma_sigma: float = 2.0
    gamma: float = 2.2

    def __post_init__(self) -> None:
        if not 0.0 <= self.max_saturated < 1.0 or not 0.0 <= self.clip_quantile < 0.5:
            raise InputError("reflectance max_saturated and clip_quantile must be shares")
        if not 0.0 < self.min_brightness <= 1.0:
            raise InputError("reflectance min_brightness must be in (0, 1]")


@dataclass(frozen=True)
class Response:
    """What the surface returns of each projector pixel, at 1/scale of the frame.

    Attributes
    ----------
    mix : (h, w, 3, 3) float32 array
        ``M``: row = colour seen (blue, green, red), column = primary; camera levels
        per unit projector light.
    ambient : (h, w, 3) float32 array
        ``a``: camera levels with the projector black.
    valid : (h, w) bool array
        Where it was measured (elsewhere ``mix`` and ``ambient`` are the picture's
        median, so a frame there is treated as on an average patch).
    """

    mix: Float32Array
    ambient: Float32Array
    valid: BoolArray

    def white(self) -> FloatArray:
        """The light (h, w, 3) seen of full white, less the ambient."""
        out: FloatArray = self.mix.astype(np.float64).sum(axis=-1)
        return out


@dataclass(frozen=True)
class Compensation:
    """The global target ``L = scale * t + lift`` chosen for a response.

    Attributes
    ----------
    scale : float
        ``s``: the light of content white above the black (camera levels).
    lift : float
        ``b``: the uniform black asked for (camera levels).
    kept : float
        ``s`` over the plain picture's mean white (the share of brightness kept).
    clipped : float
        The share of the measured pixels that cannot reach the target white.
    """

    scale: float
    lift: float
    kept: float
    clipped: float


def _as_channels(img: NDArray[np.floating] | NDArray[np.uint8]) -> FloatArray:
    a = np.asarray(img, dtype=np.float64)
    return a[..., None] if a.ndim == 2 else a


def measure(
    black: NDArray[np.floating],
    white: NDArray[np.floating],
    primaries: Sequence[NDArray[np.floating]],
    weights: Sequence[float] = PRIMARY_WEIGHTS,
    settings: ReflectanceSettings | None = None,
) -> Response:
    """The surface's :class:`Response` from captures mapped to projector pixels.

    Parameters
    ----------
    black, white : (h, w) or (h, w, 3) float arrays
        The camera (levels 0-255, linear; grey or blue-green-red) while the projector
        shows black and white; NaN where no camera pixel sees the projector pixel.
    primaries : three arrays like ``black``
        While it shows full blue, green and red.
    weights : three floats
        A grey camera's response to each primary as a share of white (ignored for a
        colour camera).
    settings : ReflectanceSettings, optional

    Returns
    -------
    Response

    Raises
    ------
    CalibrationError
        Saturated, dark or inconsistent captures, or nothing measured; the message
        says what to redo.
    """
    s = settings or ReflectanceSettings()
    if len(primaries) != 3:
        raise InputError("reflectance needs three primary captures (blue, green, red)")
    caps = [_as_channels(c) for c in (black, white, *primaries)]
    shape = caps[0].shape
    if any(c.shape != shape for c in caps) or shape[-1] not in (1, 3):
        raise InputError(f"reflectance captures differ in shape: {[c.shape for c in caps]}")
    k0, kw, kb, kg, kr = caps
    seen = np.all([np.all(np.isfinite(c), axis=-1) for c in caps], axis=0)
    if np.count_nonzero(seen) < 16:
        raise CalibrationError("no projector pixel was seen in the photometric captures")
    names = ("black", "white", *PRIMARY_NAMES)
    ok = seen.copy()
    for name, c in zip(names, caps, strict=True):
        sat = np.any(c >= s.saturation, axis=-1) & seen
        share = np.count_nonzero(sat) / np.count_nonzero(seen)
        if share > s.max_saturated:
            raise CalibrationError(
                f"the {name} capture is saturated on {share:.0%} of the picture: "
                "shorten the camera's exposure"
            )
        ok &= ~sat
    if np.count_nonzero(ok) < 16:
        raise CalibrationError("every measured pixel is saturated: shorten the exposure")
    lift = (kw - k0).mean(axis=-1)
    contrast = float(np.median(lift[ok]))
    if contrast < s.min_contrast:
        raise CalibrationError(
            f"white is barely brighter than black ({contrast:.1f} camera levels): is the "
            "projector on and uncovered, the room not far brighter than it?"
        )
    parts = (kb + kg + kr - 3 * k0).mean(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(parts - lift) / lift
    disagree = float(np.median(rel[ok]))
    if disagree > s.max_disagreement:
        raise CalibrationError(
            f"white and the primaries disagree by {disagree:.0%}: the device, the surface "
            "or the room's light changed between the captures; capture again"
        )
    h, w = shape[:2]
    mix = np.zeros((h, w, 3, 3))
    if shape[-1] == 3:
        for j, c in enumerate((kb, kg, kr)):
            mix[..., :, j] = c - k0
        ambient = k0
    else:
        wt = np.asarray(weights, dtype=np.float64)
        if wt.shape != (3,) or np.any(wt <= 0):
            raise InputError("primary weights must be three positive shares")
        diag = _grey_diagonal(lift, [(c - k0)[..., 0] for c in (kb, kg, kr)], wt, ok, s)
        diag = np.maximum(diag, 1e-3 * contrast)
        mix[..., [0, 1, 2], [0, 1, 2]] = diag
        with np.errstate(invalid="ignore", divide="ignore"):
            seen_white = (diag * wt).sum(axis=-1, keepdims=True)
            ambient = k0 * diag / seen_white
    ambient = np.maximum(ambient, 0.0)
    med_mix = np.median(mix[ok], axis=0)
    med_amb = np.median(ambient[ok], axis=0)
    mix[~ok] = med_mix
    ambient[~ok] = med_amb
    return Response(mix.astype(np.float32), ambient.astype(np.float32), ok)


def _grey_diagonal(
    white: FloatArray,
    primaries: list[FloatArray],
    weights: FloatArray,
    ok: BoolArray,
    s: ReflectanceSettings,
) -> FloatArray:
    """The reflectance (h, w, 3) per primary seen by a grey camera: the white capture
    (the brightest, least noisy) split between the primaries in the ratios of their
    own captures, smoothed over ``chroma_sigma`` pixels (a dim primary, blue above
    all, is seen at a few camera levels: its noise would otherwise print on the
    picture; colour varies more slowly than brightness on most surfaces)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = np.stack([p / weights[j] / white for j, p in enumerate(primaries)], -1)
    ratios = np.where(ok[..., None] & np.isfinite(ratios), ratios, 0.0)
    if s.chroma_sigma > 0:
        wgt = cv2.GaussianBlur(ok.astype(np.float64), (0, 0), s.chroma_sigma)
        ratios = cv2.GaussianBlur(ratios, (0, 0), s.chroma_sigma)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios = ratios / wgt[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = ratios / (ratios @ weights)[..., None]
    out: FloatArray = np.where(np.isfinite(ratios), ratios, 1.0) * white[..., None]
    return out


def _inverse(mix: Float32Array) -> FloatArray:
    """``M^-1`` (h, w, 3, 3) per pixel (a pseudo-inverse where singular)."""
    m = mix.astype(np.float64)
    try:
        inv = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(m)
    return np.asarray(inv, np.float64)


def plan(
    response: Response, settings: ReflectanceSettings | None = None, lift: bool = True
) -> Compensation:
    """The global target for ``response``: the largest white that all but
    ``clip_quantile`` of the measured pixels reach (at least ``min_brightness`` of the
    plain mean white), above a uniform black ``b`` (with
    ``lift``: the room's light at its brightest but for the same share; without:
    ``b = 0``, the room's light left where it falls).

    Raises
    ------
    CalibrationError
        The surface is too dark: more than ``max_clipped`` of it falls short of
        ``min_brightness`` of the plain picture's mean white.
    """
    s = settings or ReflectanceSettings()
    ok = response.valid
    inv = _inverse(response.mix)[ok]
    amb = response.ambient.astype(np.float64)[ok]
    b = float(np.quantile(amb.max(axis=-1), 1.0 - s.clip_quantile)) if lift else 0.0
    # p(t) = inv @ (s t + b - a): white reaches 1 when s * (inv @ 1) + inv @ (b - a) <= 1
    per_unit = inv.sum(axis=-1)
    black = np.einsum("nij,nj->ni", inv, b - amb) if lift else np.zeros_like(per_unit)
    with np.errstate(invalid="ignore", divide="ignore"):
        reach = np.where(per_unit > 0, (1.0 - black) / per_unit, np.inf).min(axis=-1)
    reach = np.where(np.isfinite(reach), np.maximum(reach, 0.0), 0.0)
    scale = float(np.quantile(reach, s.clip_quantile))
    plain = float(np.mean(response.white()[ok]))
    if plain <= 0:
        raise CalibrationError("the surface returns no light: nothing to compensate")
    # a dark patch would dim the whole picture: it falls short instead, up to a point
    scale = max(scale, s.min_brightness * plain)
    clipped = float(np.count_nonzero(reach < scale)) / max(reach.size, 1)
    if clipped > s.max_clipped:
        raise CalibrationError(
            f"the surface is too dark to compensate: keeping {s.min_brightness:.0%} of the "
            f"picture's brightness, {clipped:.0%} of it would fall short (at most "
            f"{s.max_clipped:.0%}); the light is evened out from the surface's shape alone"
        )
    return Compensation(scale, b, scale / plain, clipped)


def compensate(response: Response, comp: Compensation, target: FloatArray) -> FloatArray:
    """The projector's light ``p`` (h, w, 3) in [0, 1] that shows ``target`` (h, w, 3;
    linear light in [0, 1], blue-green-red) as ``scale * target + lift``: exactly where
    the pixel can; where it cannot, scaled back towards the pixel's black along the
    same line (hue kept), then clipped to [0, 1]."""
    inv = _inverse(response.mix)
    want = comp.scale * np.asarray(target, np.float64) + comp.lift
    base = np.einsum("...ij,...j->...i", inv, comp.lift - response.ambient.astype(np.float64))
    step = np.einsum("...ij,...j->...i", inv, want - comp.lift)
    with np.errstate(invalid="ignore", divide="ignore"):
        room = np.where(step > 0, (1.0 - base) / step, np.inf).min(axis=-1, keepdims=True)
    shrink = np.clip(np.where(np.isfinite(room), room, 1.0), 0.0, 1.0)
    out: FloatArray = np.clip(base + shrink * step, 0.0, 1.0)
    return out


def colour_gain(
    response: Response,
    comp: Compensation,
    size: tuple[int, int],
    gamma: float = 2.2,
) -> GainMap:
    """The per-frame compensation as a gain of light per pixel and primary (the
    diagonal of ``scale * M^-1``; ``lift`` is not applied: the room's light stays where
    it falls); where a pixel's gain would pass 1 all three are scaled back together
    (hue kept). ``size`` (width, height) is the frame's."""
    g = comp.scale * np.diagonal(_inverse(response.mix), axis1=-2, axis2=-1)
    g = np.where(np.isfinite(g) & (g > 0), g, 1.0)
    top = g.max(axis=-1, keepdims=True)
    g = np.where(top > 1.0, g / top, g)
    ok = response.valid
    white = response.white()
    before = white.mean(axis=-1)[ok]
    after = np.einsum("...ij,...j->...i", response.mix.astype(np.float64), g).mean(axis=-1)[ok]
    lo, hi = 0.001, 0.999
    ratio_before = float(np.quantile(before, hi) / np.quantile(before, lo))
    ratio_after = float(np.quantile(after, hi) / np.quantile(after, lo))
    mean_ratio = float(after.mean() / before.mean())
    light = np.asarray(g, np.float32)
    return GainMap(light, size, gamma, ratio_before, ratio_after, mean_ratio, 0.0, None)
