"""Ground-truth distortion of what the projector displays, computed independently of the
engine: only the per-pixel map (``map_xy``) and rays cast at the analytic surface.

Per small triangle of a ``step``-pixel sampling of the projector frame: J is the 3x2
Jacobian of the map content -> surface, sigma1 >= sigma2 its singular values;
angle error = sigma1 / sigma2 - 1, size = sqrt(sigma1 sigma2); size inconsistency is the
standard deviation of log size.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.geometry.analytic import AnalyticSurface


@dataclass
class Distortion:
    angle: NDArray[np.float64]  # per triangle
    log_size: NDArray[np.float64]
    centroid_xy: NDArray[np.float64]  # content-space centroid per triangle
    centroid_uv: NDArray[np.float64]  # projector-space centroid per triangle
    folds: int  # triangles whose content orientation is reversed (creases included)
    nonfinite: int

    def select(self, keep: NDArray[np.bool_]) -> Distortion:
        return Distortion(
            self.angle[keep],
            self.log_size[keep],
            self.centroid_xy[keep],
            self.centroid_uv[keep],
            0,
            0,
        )

    @property
    def angle_mean(self) -> float:
        return float(np.mean(self.angle))

    @property
    def size_std(self) -> float:
        return float(np.std(self.log_size))


def surface_points(
    surface: AnalyticSurface, K: NDArray[np.float64], uv: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Rays of pixels ``uv`` (..., 2) cast at the analytic surface (pinhole K at the origin)."""
    x = (uv[..., 0] - K[0, 2]) / K[0, 0]
    y = (uv[..., 1] - K[1, 2]) / K[1, 1]
    d = np.stack([x, y, np.ones_like(x)], axis=-1)
    t = surface.intersect(np.zeros_like(d), d)
    return d * t[..., None]


def measure(
    map_xy: NDArray[np.float32], surface: AnalyticSurface, K: NDArray[np.float64], step: int = 4
) -> Distortion:
    h, w = map_xy.shape[:2]
    uv, X, label = _lattice(surface, K, h, w, step)
    ys, xs = uv[:, 0, 1].astype(np.intp), uv[0, :, 0].astype(np.intp)
    c = map_xy[np.ix_(ys, xs)].astype(np.float64)  # content coords (r, c, 2)
    c_ok = np.isfinite(c[..., 0]) & np.isfinite(c[..., 1])  # (r, c)
    angles, sizes, cents, cents_uv = [], [], [], []
    folds = 0
    nonfinite = int(np.sum(np.isinf(map_xy)))
    slices = _triangle_slices(len(ys), len(xs))
    for (s0, s1, s2), tri in zip(slices, _geometry(uv, X, label), strict=True):
        c0, c1, c2 = c[s0].reshape(-1, 2), c[s1].reshape(-1, 2), c[s2].reshape(-1, 2)
        shown = np.flatnonzero(c_ok[s0].ravel() & c_ok[s1].ravel() & c_ok[s2].ravel() & tri.x_ok)
        c0, c1, c2 = c0[shown], c1[shown], c2[shown]
        e1, e2 = c1 - c0, c2 - c0  # the content edges: the columns of dc
        det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
        # a fold is a fold anywhere, across a crease too (the map stays continuous there)
        folds += int(np.sum(det <= 0))
        # the map is not differentiable across a crease
        at = np.flatnonzero(tri.smooth[shown] & (det > 0))
        dc = np.stack([e1[at], e2[at]], axis=2)  # (n, 2, 2) columns
        s_big, s_small = _singular_values(tri.dX[shown[at]], dc, det[at])
        angles.append(s_big / s_small - 1.0)
        sizes.append(0.5 * np.log(s_big * s_small))
        cents.append((c0[at] + c1[at] + c2[at]) / 3.0)
        cents_uv.append(tri.centroid_uv[shown[at]])
    return Distortion(
        np.concatenate(angles),
        np.concatenate(sizes),
        np.concatenate(cents),
        np.concatenate(cents_uv),
        folds,
        nonfinite,
    )


Slices = tuple[tuple[slice, slice], tuple[slice, slice], tuple[slice, slice]]


def _triangle_slices(rows: int, cols: int) -> tuple[Slices, Slices]:
    """The corners of the lattice's two triangles per cell (split along the top-left to
    bottom-right diagonal) as slices of an (rows, cols) lattice."""

    def at(o0: int, o1: int) -> tuple[slice, slice]:
        return slice(o0, o0 + rows - 1), slice(o1, o1 + cols - 1)

    return (at(0, 0), at(0, 1), at(1, 1)), (at(0, 0), at(1, 1), at(1, 0))


@dataclass(frozen=True)
class _Triangles:
    """What the scorer needs of one set of the lattice's triangles on the surface, the
    same for every map: corners hit the surface (n,), corners on one smooth patch (n,),
    the surface edge vectors (n, 3, 2) and the centroids in the projector (n, 2)."""

    x_ok: NDArray[np.bool_]
    smooth: NDArray[np.bool_]
    dX: NDArray[np.float64]
    centroid_uv: NDArray[np.float64]


def _geometry(
    uv: NDArray[np.float64], X: NDArray[np.float64], label: NDArray[np.int64]
) -> tuple[_Triangles, _Triangles]:
    """:class:`_Triangles` of both triangle sets of a :func:`_lattice`, worked out once per
    lattice (kept with it, by the identity of its read-only arrays)."""
    key = id(X)
    kept = _GEOMETRY.get(key)
    if kept is not None and kept[0] is X:
        return kept[1]
    out = []
    for s0, s1, s2 in _triangle_slices(*X.shape[:2]):
        x0, x1, x2 = X[s0].reshape(-1, 3), X[s1].reshape(-1, 3), X[s2].reshape(-1, 3)
        l0, l1, l2 = label[s0].ravel(), label[s1].ravel(), label[s2].ravel()
        u0, u1, u2 = uv[s0].reshape(-1, 2), uv[s1].reshape(-1, 2), uv[s2].reshape(-1, 2)
        x_ok = np.asarray(np.isfinite(x0).all(1) & np.isfinite(x1).all(1) & np.isfinite(x2).all(1))
        tri = _Triangles(
            x_ok,
            (l0 == l1) & (l1 == l2),
            np.stack([x1 - x0, x2 - x0], axis=2),
            (u0 + u1 + u2) / 3.0,
        )
        for a in (tri.x_ok, tri.smooth, tri.dX, tri.centroid_uv):
            a.setflags(write=False)
        out.append(tri)
    pair = (out[0], out[1])
    if len(_GEOMETRY) >= 16:
        del _GEOMETRY[next(iter(_GEOMETRY))]
    _GEOMETRY[key] = (X, pair)
    return pair


_GEOMETRY: dict[int, tuple[NDArray[np.float64], tuple[_Triangles, _Triangles]]] = {}


def _singular_values(
    dX: NDArray[np.float64], dc: NDArray[np.float64], det: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """sigma1 >= sigma2 of each Jacobian J = dX inv(dc) (n, 3, 2), in closed form (a
    batched SVD of small matrices costs ~50x more).

    With J's columns j0, j1, sigma1^2 is the larger eigenvalue of J^T J,
    ``(|j0|^2 + |j1|^2) / 2 + hypot((|j0|^2 - |j1|^2) / 2, j0.j1)``, and sigma1 sigma2
    is the area factor ``|j0 x j1|``: each is a sum or product of like-signed terms,
    correct to a few rounding errors, so ``sigma1 / sigma2 - 1`` is as accurate as an
    SVD's where the map is nearly conformal and where it is thin
    (``tests/test_distortion.py`` holds the two together)."""
    inv = np.empty_like(dc)  # inv(dc), written out (a stack of stacks costs more)
    inv[:, 0, 0] = dc[:, 1, 1] / det
    inv[:, 0, 1] = -dc[:, 0, 1] / det
    inv[:, 1, 0] = -dc[:, 1, 0] / det
    inv[:, 1, 1] = dc[:, 0, 0] / det
    j = dX @ inv  # (n, 3, 2)
    j0, j1 = j[:, :, 0], j[:, :, 1]
    a, b, d = np.sum(j0 * j0, 1), np.sum(j0 * j1, 1), np.sum(j1 * j1, 1)
    half_gap = np.hypot(0.5 * (a - d), b)  # (sigma1^2 - sigma2^2) / 2
    big = np.sqrt(0.5 * (a + d) + half_gap)
    # |j0 x j1| component by component (np.cross and norm's general paths cost more)
    cx = j0[:, 1] * j1[:, 2] - j0[:, 2] * j1[:, 1]
    cy = j0[:, 2] * j1[:, 0] - j0[:, 0] * j1[:, 2]
    cz = j0[:, 0] * j1[:, 1] - j0[:, 1] * j1[:, 0]
    small = np.sqrt(cx * cx + cy * cy + cz * cz) / big
    return big, small


def _lattice(
    surface: AnalyticSurface, K: NDArray[np.float64], h: int, w: int, step: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The scorer's sample pixels (r, c, 2), their rays' hits on ``surface`` (r, c, 3)
    and smooth-patch labels (r, c): the same for every map of one surface and frame,
    so they are cast once (read-only, kept for the last few). Kept only for a surface
    that is a value (a frozen dataclass of hashable fields, as the analytic ones are);
    any other (a mesh holding arrays) is cast on every call."""
    key = (surface, tuple(np.asarray(K, dtype=np.float64).ravel()), h, w, step)
    params = getattr(surface, "__dataclass_params__", None)
    try:
        if params is None or not params.frozen:
            raise TypeError
        hash(key)
    except TypeError:
        return _cast(surface, K, h, w, step)
    if key not in _LATTICES:
        if len(_LATTICES) >= 16:
            del _LATTICES[next(iter(_LATTICES))]
        _LATTICES[key] = _cast(surface, K, h, w, step)
    return _LATTICES[key]


_LATTICES: dict[
    tuple[object, ...], tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]
] = {}


def _cast(
    surface: AnalyticSurface, K: NDArray[np.float64], h: int, w: int, step: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    gx, gy = np.meshgrid(np.arange(0, w, step), np.arange(0, h, step))
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    X = surface_points(surface, K, uv)  # (r, c, 3)
    label = _labels(surface, X)
    for a in (uv, X, label):
        a.setflags(write=False)
    return uv, X, label


def _labels(surface: AnalyticSurface, X: NDArray[np.float64]) -> NDArray[np.int64]:
    """Smooth-patch label of each point (the walls of a corner, a wall and its floor);
    -1 where the ray meets nothing."""
    ok = np.isfinite(X).all(axis=-1)
    label = surface.patch(np.where(ok[..., None], X, 0.0)).astype(np.int64)
    return np.where(ok, label, -1)


def in_mask(d: Distortion, mask: NDArray[np.floating]) -> NDArray[np.bool_]:
    """Triangles whose content centroid lies where ``mask`` (content-sized) is >= 0.5."""
    h, w = mask.shape
    x = np.clip(np.rint(d.centroid_xy[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(d.centroid_xy[:, 1]).astype(int), 0, h - 1)
    return np.asarray(mask[y, x] >= 0.5)


def visible_fraction(map_xy: NDArray[np.float32], content_size: tuple[int, int]) -> float:
    """Fraction of the content's pixels that the projector displays.

    A content pixel is displayed when a projector pixel shows it, or when it lies
    inside a triangle of neighbouring displayed pixels (where the content is shown
    smaller than its own pixels: shrunk, not lost).
    """
    w, h = content_size
    canvas = np.zeros((h, w), dtype=np.uint8)
    finite = np.isfinite(map_xy[..., 0]) & np.isfinite(map_xy[..., 1])  # (H, W)
    m = map_xy[finite]
    x = np.clip(np.rint(m[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(m[:, 1]).astype(int), 0, h - 1)
    canvas[y, x] = 1
    # every pixel's corner in 1/16 pixels (fillPoly's shift=4) once, not per triangle
    g = np.zeros(map_xy.shape, dtype=np.int32)
    g[finite] = np.rint(map_xy[finite].astype(np.float64) * 16).astype(np.int32)
    quads = [(slice(0, -1), slice(0, -1)), (slice(0, -1), slice(1, None)),
             (slice(1, None), slice(1, None)), (slice(1, None), slice(0, -1))]  # fmt: skip
    # fillPoly fills by parity along each row, edges drawn too: a triangle changes only
    # pixels within a pixel of its box, so one whose box (2 pixels wider) the projector's
    # pixels cover already would change nothing; leaving those out is exact
    holes = np.zeros((h + 1, w + 1), dtype=np.int64)  # summed area of the uncovered pixels
    holes[1:, 1:] = np.cumsum(np.cumsum(canvas == 0, axis=0), axis=1)
    for tri in ((0, 1, 2), (0, 2, 3)):
        kept = finite[quads[tri[0]]] & finite[quads[tri[1]]] & finite[quads[tri[2]]]
        q = np.stack([g[quads[k]][kept] for k in tri], axis=1)  # (n, 3, 2)
        x0 = np.clip(q[:, :, 0].min(axis=1) // 16 - 2, 0, w)
        x1 = np.clip(-(-q[:, :, 0].max(axis=1) // 16) + 3, 0, w)
        y0 = np.clip(q[:, :, 1].min(axis=1) // 16 - 2, 0, h)
        y1 = np.clip(-(-q[:, :, 1].max(axis=1) // 16) + 3, 0, h)
        open_ = holes[y1, x1] - holes[y0, x1] - holes[y1, x0] + holes[y0, x0] > 0
        cv2.fillPoly(canvas, list(q[open_]), 1, lineType=cv2.LINE_8, shift=4)
    return float(canvas.mean())


def lit_coverage(
    map_xy: NDArray[np.float32], points: NDArray[np.floating], content_size: tuple[int, int]
) -> float:
    """Fraction of the lit projector pixels (those whose ray meets the surface: finite
    ``points`` (H, W, 3)) that show the content: the displayed map ``map_xy`` (H, W, 2)
    lands inside the content's pixels (edges included). As the projector sees it,
    which is about as a viewer beside it does."""
    w, h = content_size
    lit = np.isfinite(points).all(axis=-1)
    x, y = map_xy[..., 0], map_xy[..., 1]
    with np.errstate(invalid="ignore"):
        shown = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    return float(np.mean(shown[lit]))


# Lines the distortion of a warp made from measured depth is held to, beside that of the
# warp made from the true surface ("within twice the truth, plus what the depth costs").
NONE = 0.003
"""A distortion this small counts as none: where the true warp has (almost) none, as on
a plane, "twice the true distortion" would ask for exactly zero (smooth depth noise)."""

SENSOR_STEPS = 0.02
"""What a real sensor's depth steps (disparity in 1/8 px, z^2 growth) may add: the
displayed angle distortion and size inconsistency allowed on a planar region, where the
truth has none (the target for real depth frames)."""


def allowance(sensor: str) -> float:
    """What depth from the noise model ``sensor`` (a simulated session's metadata
    ``sensor``: ``smooth``, or a real sensor's name) may add to twice the truth."""
    return NONE if sensor == "smooth" else SENSOR_STEPS
