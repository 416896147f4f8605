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
    ys = np.arange(0, h, step)
    xs = np.arange(0, w, step)
    gx, gy = np.meshgrid(xs, ys)
    uv = np.stack([gx, gy], axis=-1).astype(np.float64)
    c = map_xy[gy, gx].astype(np.float64)  # content coords (r, c, 2)
    X = surface_points(surface, K, uv)  # (r, c, 3)
    tris = []
    for (a0, a1), (b0, b1), (c0, c1) in (
        ((0, 0), (0, 1), (1, 1)),
        ((0, 0), (1, 1), (1, 0)),
    ):
        sl = lambda o0, o1: (slice(o0, o0 + len(ys) - 1), slice(o1, o1 + len(xs) - 1))  # noqa: E731
        tris.append((sl(a0, a1), sl(b0, b1), sl(c0, c1)))
    angles, sizes, cents, cents_uv = [], [], [], []
    folds = 0
    nonfinite = int(np.sum(np.isinf(map_xy)))
    label = _labels(surface, X)
    for s0, s1, s2 in tris:
        c0, c1, c2 = c[s0].reshape(-1, 2), c[s1].reshape(-1, 2), c[s2].reshape(-1, 2)
        x0, x1, x2 = X[s0].reshape(-1, 3), X[s1].reshape(-1, 3), X[s2].reshape(-1, 3)
        l0, l1, l2 = label[s0].ravel(), label[s1].ravel(), label[s2].ravel()
        shown = (
            np.isfinite(c0).all(1)
            & np.isfinite(c1).all(1)
            & np.isfinite(c2).all(1)
            & np.isfinite(x0).all(1)
            & np.isfinite(x1).all(1)
            & np.isfinite(x2).all(1)
        )
        # a fold is a fold anywhere, across a crease too (the map stays continuous there)
        dc_all = np.stack([c1 - c0, c2 - c0], axis=2)[shown]
        det_all = dc_all[:, 0, 0] * dc_all[:, 1, 1] - dc_all[:, 0, 1] * dc_all[:, 1, 0]
        folds += int(np.sum(det_all <= 0))
        ok = shown & (l0 == l1) & (l1 == l2)  # the map is not differentiable across a crease
        dc = np.stack([c1 - c0, c2 - c0], axis=2)[ok]  # (n, 2, 2) columns
        dX = np.stack([x1 - x0, x2 - x0], axis=2)[ok]  # (n, 3, 2)
        det = dc[:, 0, 0] * dc[:, 1, 1] - dc[:, 0, 1] * dc[:, 1, 0]
        good = det > 0
        J = dX[good] @ np.linalg.inv(dc[good])  # (n, 3, 2)
        sv = np.linalg.svd(J, compute_uv=False)
        angles.append(sv[:, 0] / sv[:, 1] - 1.0)
        sizes.append(0.5 * np.log(sv[:, 0] * sv[:, 1]))
        cents.append(((c0 + c1 + c2) / 3.0)[ok][good])
        u0, u1, u2 = uv[s0].reshape(-1, 2), uv[s1].reshape(-1, 2), uv[s2].reshape(-1, 2)
        cents_uv.append(((u0 + u1 + u2) / 3.0)[ok][good])
    return Distortion(
        np.concatenate(angles),
        np.concatenate(sizes),
        np.concatenate(cents),
        np.concatenate(cents_uv),
        folds,
        nonfinite,
    )


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
    m = map_xy.reshape(-1, 2)
    m = m[np.isfinite(m).all(axis=1)]
    x = np.clip(np.rint(m[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(m[:, 1]).astype(int), 0, h - 1)
    canvas[y, x] = 1
    g = map_xy.astype(np.float64)
    quads = [g[:-1, :-1], g[:-1, 1:], g[1:, 1:], g[1:, :-1]]
    for tri in ((0, 1, 2), (0, 2, 3)):
        pts = np.stack([quads[k] for k in tri], axis=2).reshape(-1, 3, 2)
        pts = pts[np.isfinite(pts).all(axis=(1, 2))]
        q = np.rint(pts * 16).astype(np.int32)
        cv2.fillPoly(canvas, list(q), 1, lineType=cv2.LINE_8, shift=4)
    return float(canvas.mean())


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
