"""How much projector light each point of the surface receives: the relative irradiance.

A projector pixel sends a fixed flux into its small solid angle. On a surface point at
distance ``d`` from the projector's centre, whose normal makes the angle ``theta`` with
the ray, that flux spreads over an area growing as ``d^2 / cos(theta)``, so the
irradiance is proportional to ``V(r) * cos(theta) / d^2``; ``V`` is the lens's
vignetting (relative illumination), a radial falloff from the calibration
(:class:`Vignetting`). On a Lambertian surface the radiance a viewer sees is the
irradiance times the reflectance over pi, whatever the viewer's direction, so the
relative irradiance is also the relative apparent brightness of uniform content for
every viewer (a glossy surface breaks this: not modelled).

Everything here is relative (the projector's power and the surface's reflectance are
unknown): the values are meaningful only as ratios between pixels of one frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.projector import Projector

MIN_FALLOFF = 0.05
"""The vignetting may dim the frame's corners to this fraction of its centre, not less."""
MAX_COEFFICIENT = 10.0


@dataclass(frozen=True)
class Vignetting:
    """The projector lens's relative illumination ``V(r) = 1 + a1 r^2 + a2 r^4``.

    ``r`` is the distance from the principal point in normalised image coordinates
    (``K^-1 (u, v, 1)``: the tangent of the angle off the optical axis), so ``V`` does
    not depend on the frame's resolution. No coefficients (or zeros): no vignetting.

    Parameters
    ----------
    coefficients : tuple of float
        ``(a1, a2)``; fewer are padded with zeros.
    """

    coefficients: tuple[float, ...] = (0.0, 0.0)

    def __post_init__(self) -> None:
        c = np.asarray(self.coefficients, dtype=np.float64).ravel()
        if c.size > 2 or not np.all(np.isfinite(c)) or np.any(np.abs(c) > MAX_COEFFICIENT):
            raise InputError(
                f"vignetting must be up to 2 finite coefficients within +-{MAX_COEFFICIENT:g}"
            )
        padded = np.zeros(2)
        padded[: c.size] = c
        object.__setattr__(self, "coefficients", (float(padded[0]), float(padded[1])))

    @property
    def none(self) -> bool:
        """Whether the lens is taken as evenly lit (all coefficients zero)."""
        return not any(self.coefficients)

    def falloff(self, r2: FloatArray) -> FloatArray:
        """``V`` at squared normalised radii ``r2`` (...)."""
        a1, a2 = self.coefficients
        out: FloatArray = 1.0 + r2 * (a1 + a2 * r2)
        return out

    def at(self, projector: Projector, uv: FloatArray) -> FloatArray:
        """``V`` (...) at projector pixels ``uv`` (..., 2)."""
        rays = projector.rays(uv)
        return self.falloff(rays[..., 0] ** 2 + rays[..., 1] ** 2)

    def check(self, projector: Projector) -> None:
        """Raise :class:`InputError` unless ``V`` stays in [``MIN_FALLOFF``, 1.5] from the
        centre to the frame's farthest corner (a polynomial that turns negative, or
        brightens the edges, is a wrong fit, not a lens)."""
        if self.none:
            return
        w, h = projector.width - 1, projector.height - 1
        corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
        rays = projector.rays(corners)
        r2max = float(np.max(rays[..., 0] ** 2 + rays[..., 1] ** 2))
        v = self.falloff(np.linspace(0.0, r2max, 65))
        if float(v.min()) < MIN_FALLOFF or float(v.max()) > 1.5:
            raise InputError(
                f"vignetting {list(self.coefficients)} gives a relative illumination of "
                f"{float(v.min()):.3g}..{float(v.max()):.3g} over the frame "
                f"(it must stay within [{MIN_FALLOFF:g}, 1.5])"
            )


BEND = 0.02
"""Consecutive steps of the lattice differing by more than this share of their length
meet at a crease (or a silhouette): the normal is taken from one side, not across."""


def surface_normals(points: FloatArray) -> FloatArray:
    """Unit normals (h, w, 3) of a point map (h, w, 3) on a regular pixel lattice,
    facing the projector (n . X < 0); NaN where the lattice is degenerate.

    Tangents are central differences where the surface runs straight through a node,
    else the one-sided difference of the side that runs on straight (so a node beside
    a crease has its own wall's normal, not the mean of both); one-sided at the border
    and beside a missing node.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.cross(_tangent(p, 1), _tangent(p, 0))
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
        flip = np.sum(n * p, axis=-1, keepdims=True) > 0
    out: FloatArray = np.where(flip, -n, n)
    return out


def _tangent(p: FloatArray, axis: int) -> FloatArray:
    """The derivative (h, w, 3) of ``p`` along ``axis`` (0: rows, 1: columns), per node."""
    size = p.shape[axis]
    pad = [(0, 0)] * 3
    pad[axis] = (2, 2)
    q = np.pad(p, pad, constant_values=np.nan)

    def at(k: int) -> FloatArray:
        index: list[slice] = [slice(None)] * 3
        index[axis] = slice(2 + k, 2 + k + size)
        out: FloatArray = q[tuple(index)]
        return out

    def sq(a: FloatArray) -> FloatArray:
        out: FloatArray = np.einsum("...i,...i->...", a, a)
        return out

    p0 = at(0)
    b, f = p0 - at(-1), at(1) - p0
    with np.errstate(invalid="ignore"):
        mean_len = 0.5 * (np.sqrt(sq(f)) + np.sqrt(sq(b)))
        bend = sq(f - b) > (BEND * mean_len) ** 2
        kink_f = np.nan_to_num(sq(at(2) - at(1) - f), nan=np.inf)
        kink_b = np.nan_to_num(sq(b - at(-1) + at(-2)), nan=np.inf)
    one = np.where((kink_f < kink_b)[..., None], f, b)
    one = np.where(np.isnan(one), np.where(np.isnan(f), b, f), one)
    d: FloatArray = np.where(bend[..., None], one, 0.5 * (b + f))
    d = np.where(np.isnan(d), np.where(np.isnan(f), b, f), d)
    return d


def relative_irradiance(
    points: FloatArray,
    projector: Projector,
    uv: FloatArray,
    vignetting: Vignetting | None = None,
) -> FloatArray:
    """The irradiance (h, w) of the surface points ``points`` (h, w, 3) lit by the
    projector pixels ``uv`` (h, w, 2) (a regular lattice of the frame), relative:
    ``V(r) * cos(incidence) / d^2`` with ``d`` in metres. NaN where the point or its
    normal is unknown.

    Parameters
    ----------
    points : (h, w, 3) float array
        Surface points in frame P, NaN where the ray meets nothing.
    projector : Projector
    uv : (h, w, 2) float array
        The projector pixel of each point (for the vignetting).
    vignetting : Vignetting, optional
        The lens's falloff; None: none.

    Returns
    -------
    (h, w) float array
    """
    p = np.asarray(points, dtype=np.float64)
    n = surface_normals(p)
    d2 = np.sum(p * p, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = -np.sum(n * p, axis=-1) / np.sqrt(d2)
        e: FloatArray = cos / d2
    if vignetting is not None and not vignetting.none:
        e = e * vignetting.at(projector, uv)
    bad = ~np.isfinite(e) | (e <= 0.0)
    e[bad] = np.nan
    return e
