"""A rendered frame moved by a rotation of the projector: the homography ``K C K^-1``.

A frame rendered for the projector at one orientation, shown while it points another
way (``C`` rotates the new orientation into the old one, ``C = R_old^T R_new``), must
show at each pixel ``u`` what the frame holds at ``H u`` with ``H = K C K^-1``: for a
pure rotation every ray keeps its direction in the world, whatever the surface (no
depth needed). Translation and parallax are left to the next depth-driven frame.

:func:`reproject` draws the moved frame with ``cv2.warpPerspective`` (bilinear or
nearest, black outside): on 4-channel frames (BGRX, the framebuffer's own layout)
OpenCV's vectorised path is about twice as fast as on 3-channel ones
(``tools/bench_handheld.py``).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.warp.warpmap import Warp

Interpolation = Literal["linear", "nearest"]
_FLAGS = {"linear": cv2.INTER_LINEAR, "nearest": cv2.INTER_NEAREST}


def rotation_homography(K: FloatArray, C: FloatArray) -> FloatArray:
    """The homography (3, 3) ``K C K^-1`` from a displayed pixel to the rendered frame's
    pixel showing the same ray.

    Parameters
    ----------
    K : (3, 3) float array
        Projector intrinsics.
    C : (3, 3) float array
        Rotation from the orientation the frame is shown at to the one it was rendered
        for (``R_rendered^T R_shown``).

    Returns
    -------
    (3, 3) float array, normalised so that ``H[2, 2] == 1``.
    """
    K = np.asarray(K, dtype=np.float64)
    H = K @ np.asarray(C, dtype=np.float64) @ np.linalg.inv(K)
    out: FloatArray = H / H[2, 2]
    return out


def map_points(H: FloatArray, uv: FloatArray) -> FloatArray:
    """Pixels (..., 2) mapped by the homography ``H`` (3, 3)."""
    uv = np.asarray(uv, dtype=np.float64)
    h = uv @ H[:, :2].T + H[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        out: FloatArray = h[..., :2] / h[..., 2:3]
    return out


def reproject(
    frame: NDArray[np.uint8],
    H: FloatArray,
    out: NDArray[np.uint8] | None = None,
    interpolation: Interpolation = "linear",
) -> NDArray[np.uint8]:
    """``frame`` (h, w, c) as shown after the rotation of ``H``: pixel ``u`` of the
    result is ``frame`` at ``H u`` (black outside the frame). Drawn into ``out`` when it
    has the frame's shape and type."""
    h, w = frame.shape[:2]
    dst = out if out is not None and out.shape == frame.shape and out.dtype == np.uint8 else None
    got = cv2.warpPerspective(
        frame,
        np.asarray(H, dtype=np.float64),
        (w, h),
        dst=dst,
        flags=_FLAGS[interpolation] | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    return np.asarray(got, dtype=np.uint8)


def rotation_between(K: FloatArray, u_from: FloatArray, u_to: FloatArray) -> FloatArray:
    """The rotation ``M`` (3, 3) that best turns the rays of pixels ``u_from`` (N, 2)
    onto those of ``u_to`` (N, 2) (least squares on unit rays, Kabsch); pixels ``u_to``
    are then shown at about ``K M K^-1 u_from``. Rows with NaN are left out; fewer than
    three points give the identity."""
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))
    ok = np.all(np.isfinite(u_from), axis=1) & np.all(np.isfinite(u_to), axis=1)
    if int(ok.sum()) < 3:
        return np.eye(3)

    def rays(u: FloatArray) -> FloatArray:
        r = np.concatenate([u[ok], np.ones((int(ok.sum()), 1))], axis=1) @ K_inv.T
        out: FloatArray = r / np.linalg.norm(r, axis=1, keepdims=True)
        return out

    a, b = rays(u_from), rays(u_to)
    U, _, Vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(U @ Vt))
    M: FloatArray = U @ np.diag([1.0, 1.0, d]) @ Vt
    return M


def inner_corners(size: tuple[int, int], margin: float) -> FloatArray:
    """The corners (4, 2) of the frame ``size`` (w, h) inset by ``margin`` of its width
    and height on each side (pixel centres at integers)."""
    w, h = size
    x0, y0 = margin * w - 0.5, margin * h - 0.5
    x1, y1 = w - 0.5 - margin * w, h - 0.5 - margin * h
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def margin_usage(K: FloatArray, C: FloatArray, size: tuple[int, int], margin: float) -> float:
    """How much of the stabilisation margin the correction ``C`` uses: the largest
    displacement of the inset content's corners on the display, as a fraction of the
    margin (per axis); 1 means a corner reaches the frame's edge. Infinite without a
    margin and a correction that moves anything."""
    corners = inner_corners(size, margin)
    moved = map_points(rotation_homography(K, np.asarray(C).T), corners)
    d = np.abs(moved - corners)
    w, h = size
    if margin <= 0:
        return 0.0 if float(d.max()) < 1e-9 else float("inf")
    return float(max(d[:, 0].max() / (margin * w), d[:, 1].max() / (margin * h)))


def inset_warp(warp: Warp, margin: float) -> Warp:
    """``warp`` with its content shrunk about the content's centre by ``1 - 2 margin``:
    a content that filled the frame keeps ``margin`` of its width and height free on
    each side (room for the stabiliser). A similarity in content space: the warp's
    distortion does not change. ``margin`` 0 returns ``warp`` itself."""
    if margin <= 0:
        return warp
    if margin >= 0.25:
        raise ValueError(f"a stabilisation margin of {margin} leaves too little picture")
    w, h = warp.content_size
    c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    k = 1.0 / (1.0 - 2.0 * margin)
    map_xy = None
    if warp.map_xy is not None:
        map_xy = (c + (warp.map_xy - c) * k).astype(np.float32)
    return replace(warp, image_xy=c + (warp.image_xy - c) * k, map_xy=map_xy)
