"""Walls: large planar pieces of an estimated surface, snapped onto their planes.

Walls, wall corners and tables are what a projector is pointed at most often. Stereo
noise of a few millimetres on them is small next to their size, but the warp reads
the surface's *shape* from neighbouring lattice nodes a few centimetres apart, so it
turns that noise into visible distortion of a surface that should show none. Where a
large connected piece of the lattice lies on one plane to within the noise, moving
its nodes onto the plane fitted to all of them (each along its own projector ray)
removes the noise there and changes nothing else.

:func:`snap_planes` finds up to ``max_planes`` such pieces, largest first: candidate
planes are fitted to small lattice windows, the one with the most nodes within
``tolerance_rel`` of the median depth wins, is refitted to those nodes by least
squares (twice), and its largest 4-connected set of inliers is accepted when it
covers ``min_fraction`` of the nodes and its RMS residual is below ``max_rms_rel`` of
the median depth (stereo noise grows with depth). Given the sensor's noise model
(:class:`~adaproj_edge.geometry.depth.sensor.SensorModel`) the tolerance and the RMS
also allow, per node, a part of its depth step there and of the sensor's slowly
varying error (the bands and bowls a real sensor makes of a flat wall, a few cm at
3 m), so the staircase a stereo camera makes of a wall (24 mm steps at 2.5 m for an
OAK-D) is snapped flat rather than left as waves; a piece that bends away from its
plane by no more than that slow error is planar whatever its bend ratio. Curved
surfaces (a column, a dome, a bowl) never meet that on a large piece and are left as
they are.

The sensor's slow error is smooth: over a wall it is nearly a quadratic in the image
coordinates, whose curvature the model bounds (``curve_px``, measured on real frames).
A piece its nodes' tolerance splits off or its bend rejects is still a plane when one
quadratic of at most that curvature fits its inverse depth (:func:`bent_plane`); it is
grown to the nodes near that bent fit and fitted with one plane. Two snapped planes
that one such quadratic joins are one plane, refitted jointly: the sensor cannot tell
their dihedral from its own bend. A crease it can resolve needs a larger curvature and
stays two planes.

Given the depth the lattice was estimated from before its smoothing (:class:`RawDepth`),
a piece's plane is fitted to the raw points under it, weighted by the sensor's noise
model and robustly (:func:`fit_plane_raw`): at a few metres a Kinect's depth error is
centimetres and the smoothed lattice of a small piece tilts with it. Where two planes
meet, the raw points within the sensor's footprint of their crease are left out of the
fit (their depth mixes both planes': :func:`find_planes`). And a lattice cell
that an object's edge runs through (some corners on a plane, some not) takes the plane
where its raw depth lies on it, rather than a slope interpolated across the edge, on
which content would be shown distorted.

The snapped surface's ``meta`` lists the planes (``PLANES_KEY``: ``[nx, ny, nz, d]``
each), so the warp can keep them undistorted (:func:`plane_equations`,
:attr:`~adaproj_edge.warp.mesh.MeshGeometry.planar`).

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import SurfaceError
from adaproj_edge.geometry.depth.sensor import SensorModel
from adaproj_edge.geometry.surface import Surface

PLANES_KEY = "plane_equations"  # a snapped surface's meta: its planes, [nx, ny, nz, d] each
TUKEY_C = 4.685  # Tukey's biweight: residuals beyond this many errors weigh nothing
FAR_BEYOND_BEND = 3.0  # see _join_bent
ON_PLANE_REL = 1e-4  # a point this close to a plane (of its depth) lies on it (float32's
# rounding of a snapped node is ~1e-7 of its depth; the sensor's noise is ~1e-3)


@dataclass(frozen=True)
class PlaneSettings:
    """Tuning of :func:`snap_planes` (metres, fractions of the lattice's nodes)."""

    tolerance_rel: float = 0.003  # of the median depth: 4.5 mm at 1.5 m
    max_rms_rel: float = 0.0015
    min_fraction: float = 0.25
    max_bend: float = 1.5  # see curvature_ratio
    max_planes: int = 3
    # with a sensor model: a node within this many of the sensor's depth steps at its
    # depth is on the plane, and a piece whose RMS is within this many is planar (a
    # wall seen by a stereo camera is a staircase of such steps)
    step_tolerance: float = 0.5
    step_rms: float = 0.3
    step_flat: float = 0.1  # a residual below this many steps bends with the staircase
    # ... and the sensor's slowly varying error (its RMS over a plane, ``bias_m``): a
    # node within this many of it (beyond its steps) is on the plane (the peaks of a
    # real sensor's warp are about 2.5 times its RMS), a piece may add this many of it
    # to its RMS, and a piece whose bend (the part of its residual a quadric explains)
    # is within this many of it is planar whatever its bend ratio
    bias_tolerance: float = 2.5
    bias_rms: float = 1.0
    bias_bend: float = 1.0
    # two planes are one plane (refitted jointly) when a quadratic that bends their raw
    # points' disparity as the sensor's slow error can (curvature within this many of
    # the sensor's ``curve_px``) joins them: see one_plane
    curve_tolerance: float = 1.0
    window: int = 2  # candidate planes from (2 w + 1)^2 node windows ...
    stride: int = 2  # ... centred on every stride-th node
    # fit an accepted piece's plane to the raw depth under it (fit_plane_raw) rather
    # than to its smoothed nodes: at a few metres the smoothing tilts a small piece
    raw_fit: bool = True


@dataclass(frozen=True)
class Plane:
    """``normal . X = offset`` (unit normal facing the projector), and its nodes."""

    normal: FloatArray
    offset: float
    nodes: NDArray[np.bool_]
    rms_m: float
    bend: float


def fit_plane(points: FloatArray) -> tuple[FloatArray, float]:
    """Least-squares plane (unit normal with negative z, offset) of points (n, 3)."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    n = vt[-1]
    if n[2] > 0:
        n = -n
    return n, float(n @ c)


def _candidates(points: FloatArray, valid: NDArray[np.bool_], s: PlaneSettings) -> FloatArray:
    """(k, 4) planes [n, offset] fitted to lattice windows with every node known."""
    size = 2 * s.window + 1
    if min(valid.shape) < size:
        return np.zeros((0, 4))
    win = np.lib.stride_tricks.sliding_window_view(points, (size, size), axis=(0, 1))
    ok = np.asarray(
        np.lib.stride_tricks.sliding_window_view(valid, (size, size)).all(axis=(-2, -1))
    )
    win, ok = win[:: s.stride, :: s.stride], ok[:: s.stride, :: s.stride]
    x = np.moveaxis(win[ok], 1, -1).reshape(-1, size * size, 3)  # (k, n, 3)
    if x.shape[0] == 0:
        return np.zeros((0, 4))
    c = x.mean(axis=1)
    d = x - c[:, None, :]
    _, vecs = np.linalg.eigh(np.einsum("kni,knj->kij", d, d))
    n = vecs[:, :, 0]  # the smallest eigenvalue's vector: the normal
    n = np.where(n[:, 2:3] > 0, -n, n)
    return np.concatenate([n, np.sum(n * c, axis=1, keepdims=True)], axis=1)


def curvature_ratio(points: FloatArray, normal: FloatArray, offset: float) -> float:
    """How much better a quadric than the plane fits ``points`` (n, 3): the RMS distance
    to the plane over the RMS residual of a quadratic height field above it. About 1
    for a noisy plane; larger for a gently curved piece (a strip of a column, which a
    plane can fit to within the noise)."""
    r = points @ normal - offset
    e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    c = points - points.mean(axis=0)
    a, b = c @ e1, c @ e2
    scale = max(float(np.abs(np.r_[a, b]).max()), 1e-9)
    a, b = a / scale, b / scale
    A = np.stack([np.ones_like(a), a, b, a * a, a * b, b * b], axis=1)
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    rq = float(np.sqrt(np.mean((r - A @ coef) ** 2)))
    return float(np.sqrt(np.mean(r**2))) / max(rq, 1e-12)


def node_tolerance(
    s: PlaneSettings, sensor: SensorModel | None, z: FloatArray, z_median: float
) -> float | FloatArray:
    """How far (m) a node at depth ``z`` (NaN: unknown) may lie from its plane and be on
    it: ``tolerance_rel`` of the median depth, or with a sensor model the part of its
    depth step and of the sensor's slowly varying error there, if more."""
    tol = s.tolerance_rel * z_median
    if sensor is None:
        return tol
    zn = np.where(np.isfinite(z), z, z_median)
    return np.maximum(
        tol, s.step_tolerance * sensor.step_m(zn) + s.bias_tolerance * sensor.bias_m(zn)
    )


def bend_m(points: FloatArray, normal: FloatArray, offset: float, bend: float) -> float:
    """RMS (m) of the part of ``points``' distances to the plane that a quadratic height
    field explains (see :func:`curvature_ratio`, whose value ``bend`` is): how far the
    piece bends away from its plane."""
    rms = float(np.sqrt(np.mean((points @ normal - offset) ** 2)))
    return rms * float(np.sqrt(max(1.0 - 1.0 / max(bend, 1.0) ** 2, 0.0)))


@dataclass(frozen=True)
class RawDepth:
    """The depth a surface was estimated from, before any smoothing across its lattice.

    ``points`` (fine rows, fine cols, 3): points in frame P on the rays of a lattice
    ``step`` times finer than the surface's (its nodes are every ``step``-th), NaN
    where the frame has no depth
    (:attr:`~adaproj_edge.geometry.depth.estimate.SurfaceEstimate.raw`)."""

    points: FloatArray
    step: int = 1

    def near_plane(
        self, plane: Plane, tolerance_m: float | FloatArray, shape: tuple[int, int]
    ) -> NDArray[np.bool_]:
        """(rows, cols) on a lattice of ``shape`` over the same projector frame (its
        corners the raw lattice's): whether the raw points there lie on ``plane``,
        within ``tolerance_m`` (a scalar, or per raw point): whether most of the known
        3 x 3 raw points around the nearest one do (one point's noise, or the one
        point across an object's edge, does not decide)."""
        r = np.abs(self.points.astype(np.float64) @ plane.normal - plane.offset)
        ok = np.asarray(r < tolerance_m, dtype=np.float64)
        ok[~np.isfinite(r)] = np.nan
        pad = np.pad(ok, 1, constant_values=np.nan)
        win = np.lib.stride_tricks.sliding_window_view(pad, (3, 3)).reshape(*ok.shape, 9)
        with np.errstate(invalid="ignore"):
            votes = np.nansum(win, axis=-1) / np.maximum(np.isfinite(win).sum(axis=-1), 1)
        i = np.rint(np.linspace(0.0, ok.shape[0] - 1.0, shape[0])).astype(np.intp)
        j = np.rint(np.linspace(0.0, ok.shape[1] - 1.0, shape[1])).astype(np.intp)
        return np.asarray(votes[i[:, None], j[None, :]] > 0.5)

    def samples(self, nodes: NDArray[np.bool_]) -> FloatArray:
        """(n, 3) the known raw points nearest to ``nodes`` (rows, cols) of the surface's
        lattice (within half a cell of one)."""
        k = self.step
        i = (np.arange(self.points.shape[0]) + k // 2) // k
        j = (np.arange(self.points.shape[1]) + k // 2) // k
        i, j = np.minimum(i, nodes.shape[0] - 1), np.minimum(j, nodes.shape[1] - 1)
        pts: FloatArray = self.points[nodes[i[:, None], j[None, :]]].astype(np.float64)
        return pts[np.isfinite(pts).all(axis=1)]


def crease_px(points: FloatArray, a: Plane, b: Plane, focal_px: float) -> FloatArray:
    """(n,) how far ``points`` (n, 3) in frame P lie from the crease of planes ``a``
    and ``b`` in the image of a camera there of focal length ``focal_px``: the sine of
    the angle between each point's ray and the plane through the origin and the crease
    line, times the focal length (the distance in pixels at the image's centre, a
    little less than it off the centre); inf for all when the planes are parallel or
    their crease runs through the origin."""
    u = np.cross(a.normal, b.normal)
    nu = float(np.linalg.norm(u))
    if nu < 1e-6:
        return np.full(len(points), np.inf)
    u /= nu
    # the point of the crease nearest the origin
    q = np.linalg.lstsq(np.stack([a.normal, b.normal, u]), [a.offset, b.offset, 0.0])[0]
    m = np.cross(q, u)
    nm = float(np.linalg.norm(m))
    if nm < 1e-9:
        return np.full(len(points), np.inf)
    return np.asarray(focal_px * np.abs(points @ (m / nm)) / np.linalg.norm(points, axis=1))


def fit_plane_raw(
    points: FloatArray, sensor: SensorModel | None, normal: FloatArray, offset: float
) -> tuple[FloatArray, float]:
    """A plane through raw depth points (n, 3) in their camera's frame, robustly,
    starting from ``normal``, ``offset``.

    Iteratively reweighted least squares of the distances to the plane: each point
    weighted by its depth's variance under the ``sensor``'s noise model
    (``1 / sigma(z)^2``: its error grows with z^2, so a far point counts less) times
    Tukey's biweight of its distance over its error, the random one and the sensor's
    slow one (no model: the distances' spread), so the points of another object beside
    the plane drop out. A point's error lies along its ray, not across the plane, so
    the scatter the noise adds along the rays (``sigma^2 r r^T`` for each, in
    expectation) is taken out of the points' scatter before its least direction is
    taken as the normal: left in, it tilts the plane of an oblique view towards the
    rays by a degree or more."""
    n, d = normal, offset
    ok = np.isfinite(points).all(axis=1) & (points[:, 2] > 0)
    p = points[ok]
    if len(p) < 3:
        return n, d
    rays = p / np.linalg.norm(p, axis=1, keepdims=True)
    if sensor is not None:
        sigma = np.asarray(sensor.sigma_m(p[:, 2]))
        scale = np.hypot(sigma, np.asarray(sensor.bias_m(p[:, 2])))
        base = 1.0 / np.maximum(sigma, 1e-6) ** 2
    else:
        sigma, base = None, np.ones(len(p))
    for _ in range(5):
        r = p @ n - d
        if sigma is None:
            scale = np.full(len(p), max(1.4826 * float(np.median(np.abs(r))), 1e-9))
        u = r / (TUKEY_C * scale)
        w = base * np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)
        if np.count_nonzero(w) < 3:
            break
        c = (w[:, None] * p).sum(axis=0) / w.sum()
        q = p - c
        scatter = (w[:, None] * q).T @ q
        if sigma is not None:  # the noise's own scatter, along the rays
            scatter -= ((w * sigma**2)[:, None] * rays).T @ rays
        _, vecs = np.linalg.eigh(scatter)
        n = vecs[:, 0] if vecs[2, 0] <= 0 else -vecs[:, 0]
        d = float(n @ c)
    return n, d


def find_planes(
    surface: Surface,
    settings: PlaneSettings | None = None,
    sensor: SensorModel | None = None,
    raw: RawDepth | None = None,
) -> list[Plane]:
    """The large planar pieces of ``surface``'s lattice, largest first (``sensor``: the
    noise model of the depth it came from, None for none). Given the ``raw`` depth the
    lattice was estimated from and ``settings.raw_fit``, a piece's plane is fitted to the
    raw points under it (:func:`fit_plane_raw`), not to its smoothed nodes; when two or
    more planes are found, each is fitted again without the raw points whose depth
    mixes in another's across their crease (with a ``sensor``: see :func:`_off_creases`)."""
    s = settings or PlaneSettings()
    pts = surface.points.astype(np.float64)
    valid = np.asarray(np.isfinite(pts).all(axis=-1))
    n_valid = int(valid.sum())
    if n_valid == 0:
        return []
    z = float(np.median(pts[valid][:, 2]))
    tol = node_tolerance(s, sensor, pts[..., 2], z)
    free = valid.copy()
    cand = _candidates(pts, valid, s)
    flat = pts.reshape(-1, 3)
    planes: list[Plane] = []
    for _ in range(3 * s.max_planes):  # a rejected piece is set aside, then the next
        if len(planes) == s.max_planes or cand.shape[0] == 0:
            break
        with np.errstate(invalid="ignore"):
            near = np.abs(flat @ cand[:, :3].T - cand[:, 3]) < np.reshape(tol, (-1, 1))
        counts = np.sum(near & free.reshape(-1, 1), axis=0)
        best = int(np.argmax(counts))
        if counts[best] < s.min_fraction * n_valid:
            break
        n, d = cand[best, :3], float(cand[best, 3])
        for _ in range(2):
            with np.errstate(invalid="ignore"):
                inliers = free & (np.abs(pts @ n - d) < tol)
            if inliers.sum() < 3:
                break
            n, d = fit_plane(pts[inliers])
        if raw is not None and s.raw_fit and inliers.sum() >= 3:
            n, d = fit_plane_raw(raw.samples(inliers), sensor, n, d)
        with np.errstate(invalid="ignore"):
            inliers = free & (np.abs(pts @ n - d) < tol)
        labels, count = ndimage.label(inliers)
        if count == 0:
            free &= ~near[:, best].reshape(free.shape)
            continue
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        piece = labels == int(np.argmax(sizes))
        free &= ~piece
        # the piece is judged planar on its own nodes' plane (a raw plane a little
        # off it would read as a bend)
        nl, dl = (n, d) if raw is None else fit_plane(pts[piece])
        rms = float(np.sqrt(np.mean((pts[piece] @ nl - dl) ** 2)))
        bend = curvature_ratio(pts[piece], nl, dl)
        max_rms, flat_rms, bias_bend = s.max_rms_rel * z, 0.0, 0.0
        if sensor is not None:  # the piece's own depth sets the sensor's error
            zp = float(np.median(pts[piece][:, 2]))
            step, bias = float(sensor.step_m(zp)), float(sensor.bias_m(zp))
            max_rms = max(max_rms, s.step_rms * step + s.bias_rms * bias)
            flat_rms = s.step_flat * step  # this close to its plane: flat whatever its bend
            bias_bend = s.bias_bend * bias  # bending no more than the sensor's warp
        planar = (
            rms <= flat_rms or bend <= s.max_bend or bend_m(pts[piece], nl, dl, bend) <= bias_bend
        )
        if piece.sum() < s.min_fraction * n_valid:
            continue
        if not (rms <= max_rms and planar) and sensor is not None and sensor.curve_px > 0:
            # a piece bent no more than the sensor's slow error bends a plane (a real
            # sensor's bowl) is a plane, whatever its RMS and bend ratio: grown to the
            # nodes near its bent fit (the rim of the bowl, beyond the plane's
            # tolerance), then fitted with one plane
            raw_fit = raw if s.raw_fit else None
            coef = bent_plane([_piece_points(piece, pts, raw_fit)], sensor, s.curve_tolerance)
            if coef is None:
                continue
            piece = _grow(piece, pts, free, coef, tol)
            free &= ~piece
            n, d = fit_plane(pts[piece])
            if raw_fit is not None:
                n, d = fit_plane_raw(raw_fit.samples(piece), sensor, n, d)
            rms = float(np.sqrt(np.mean((pts[piece] @ n - d) ** 2)))
            bend = curvature_ratio(pts[piece], n, d)
        elif rms > max_rms or not planar:
            continue
        planes.append(Plane(n, d, piece, rms, bend))
    if sensor is not None and sensor.curve_px > 0 and len(planes) > 1:
        planes = _join_bent(planes, pts, s, sensor, raw if s.raw_fit else None)
    if raw is not None and s.raw_fit and sensor is not None and len(planes) > 1:
        planes = [_off_creases(p, planes, raw, sensor) for p in planes]
    return planes


def _grow(
    piece: NDArray[np.bool_],
    pts: FloatArray,
    free: NDArray[np.bool_],
    coef: FloatArray,
    tol: float | FloatArray,
) -> NDArray[np.bool_]:
    """``piece`` and the ``free`` nodes of ``pts`` (rows, cols, 3) connected to it that lie
    within ``tol`` (m, per node or one) of the bent surface ``coef`` (:func:`bent_plane`)."""
    flat = pts.reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_fit = 1.0 / (_quadric_terms(flat) @ coef)
        near = np.abs(flat[:, 2] - z_fit) < np.reshape(tol, -1)
    near = (near.reshape(piece.shape) & free) | piece
    labels, _ = ndimage.label(near)
    return np.asarray(np.isin(labels, np.unique(labels[piece])) & near)


def _piece_points(nodes: NDArray[np.bool_], pts: FloatArray, raw: RawDepth | None) -> FloatArray:
    """(n, 3) the known raw points under ``nodes`` (none given: the nodes' points)."""
    q = raw.samples(nodes) if raw is not None else pts[nodes]
    return q[np.isfinite(q).all(axis=1) & (q[:, 2] > 0)]


def one_plane(points: list[FloatArray], sensor: SensorModel, tolerance: float = 1.0) -> bool:
    """Whether the pieces' ``points`` (each (n, 3), in a frame near the depth camera's)
    are one plane bent by the ``sensor``'s slow error (:func:`bent_plane`)."""
    return bent_plane(points, sensor, tolerance) is not None


def _quadric_terms(points: FloatArray) -> FloatArray:
    """(n, 6) ``1, x, y, x^2, x y, y^2`` of ``points``' (n, 3) image coordinates
    ``x = X / Z``, ``y = Y / Z``."""
    x, y = points[:, 0] / points[:, 2], points[:, 1] / points[:, 2]
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)


def bent_plane(
    points: list[FloatArray], sensor: SensorModel, tolerance: float = 1.0
) -> FloatArray | None:
    """The inverse depth (6,) over :func:`_quadric_terms` of the pieces' ``points`` (each
    (n, 3), in a frame near the depth camera's) when they are one plane bent by the
    ``sensor``'s slow error, else None.

    Their inverse depth ``1 / z`` (the disparity over ``f B``; a plane's is affine in
    ``x = X / Z``, ``y = Y / Z``) is fitted jointly, by least squares and once more without
    the points beyond Tukey's bound of the sensor's error (its random one and its slow
    one), with an affine part and a quadratic ``qxx x^2 + qxy x y + qyy y^2``. They are
    one plane when its curvature (``f B`` times the quadratic's largest ``|eig|``) is
    within ``tolerance`` of the sensor's ``curve_px`` and the fit keeps most of each
    piece's points (a step between two parallel planes, or another plane beside one,
    is not a bend). Two walls meeting at a crease need a curvature of about their
    disparity gradients' difference over twice the distance of their centroids
    (:meth:`~adaproj_edge.geometry.depth.sensor.SensorModel.max_dihedral_rad` is that
    bound as a dihedral). The curvature is read in the given frame's image coordinates,
    not the depth camera's: the projector's frame, a few cm away and turned by the aim,
    reads it within about the cosine of that turn."""
    pts = np.concatenate(points)
    A, w = _quadric_terms(pts), 1.0 / pts[:, 2]
    bound = TUKEY_C * float(np.hypot(sensor.disparity_total_px, sensor.bias_px)) / sensor.fb
    keep = np.isfinite(w) & np.isfinite(A).all(axis=1)
    coef: FloatArray = np.zeros(6)
    for _ in range(2):
        if keep.sum() < 12:
            return None
        coef = np.asarray(np.linalg.lstsq(A[keep], w[keep], rcond=None)[0], dtype=np.float64)
        with np.errstate(invalid="ignore"):
            keep = np.abs(w - A @ coef) < bound
    start = 0
    for p in points:  # every piece keeps most of its points on the joint fit
        if len(p) == 0 or keep[start : start + len(p)].mean() < 0.8:
            return None
        start += len(p)
    q = np.array([[coef[3], coef[4] / 2.0], [coef[4] / 2.0, coef[5]]])
    curve = sensor.fb * float(np.abs(np.linalg.eigvalsh(q)).max())
    return coef if curve <= tolerance * sensor.curve_px else None


def _join_bent(
    planes: list[Plane],
    pts: FloatArray,
    s: PlaneSettings,
    sensor: SensorModel,
    raw: RawDepth | None,
) -> list[Plane]:
    """``planes`` with every pair that is one plane bent by the sensor's slow error
    (:func:`one_plane`, on their raw points, else their nodes) replaced by one plane
    fitted to both (:func:`fit_plane_raw`), in the place of the first of the two. A
    pair whose dihedral is more than ``FAR_BEYOND_BEND`` times the largest the sensor's
    slow error makes between them
    (:meth:`~adaproj_edge.geometry.depth.sensor.SensorModel.max_dihedral_rad`, for their
    nodes' centroids) is two planes without the joint fit (a room's corner)."""

    def centre(p: Plane) -> FloatArray:
        q = pts[p.nodes]
        return np.asarray((q[:, :2] / q[:, 2:3]).mean(axis=0))

    out = list(planes)
    joined = True
    while joined and len(out) > 1:
        joined = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                limit = sensor.max_dihedral_rad(
                    max(abs(a.offset), abs(b.offset)), float(np.linalg.norm(centre(a) - centre(b)))
                )
                dihedral = float(np.arccos(min(1.0, abs(float(a.normal @ b.normal)))))
                if dihedral > FAR_BEYOND_BEND * s.curve_tolerance * limit:
                    continue
                pa, pb = _piece_points(a.nodes, pts, raw), _piece_points(b.nodes, pts, raw)
                if len(pa) < 6 or len(pb) < 6 or not one_plane([pa, pb], sensor, s.curve_tolerance):
                    continue
                n, d = fit_plane_raw(np.concatenate([pa, pb]), sensor, a.normal, a.offset)
                nodes = a.nodes | b.nodes
                rms = float(np.sqrt(np.mean((pts[nodes] @ n - d) ** 2)))
                out[i] = Plane(n, d, nodes, rms, curvature_ratio(pts[nodes], n, d))
                del out[j]
                joined = True
                break
            if joined:
                break
    return out


def _off_creases(plane: Plane, planes: list[Plane], raw: RawDepth, sensor: SensorModel) -> Plane:
    """``plane`` refitted to its raw points (:func:`fit_plane_raw`) but those whose depth
    the other side of a crease with another of ``planes`` is mixed into: a pixel within
    the sensor's footprint of the crease is made from a patch of the image that reaches
    across it, so its depth lies off both planes (in front of an inside corner's walls,
    behind an outside corner's), all on one side, and tilts the plane towards the other;
    the crease between two snapped walls moves with it (a millimetre moves it a
    projector pixel at 1.8 m). A point ``t`` pixels from the crease is left out when the
    two planes' depths there, across the part of its patch beyond the crease
    (``footprint - t`` pixels), differ by more than the sensor's depth step: within a
    step the sensor's quantisation reports the mix as one of the plane's own depths
    (so a wall that bends a few degrees, snapped as two planes, keeps its points)."""
    pts = raw.samples(plane.nodes)
    rays = pts / pts[:, 2:3]
    foot = sensor.footprint_px
    keep = np.ones(len(pts), dtype=bool)
    for other in planes:
        if other is plane:
            continue
        t = crease_px(pts, plane, other, sensor.focal_px)
        gap = np.abs(_plane_depth(rays, other) - _plane_depth(rays, plane))
        # the gap grows as t from the crease: (footprint - t) / t of it lies across
        with np.errstate(invalid="ignore"):
            mixed = (t < foot) & ~(gap * (foot - t) <= sensor.step_m(pts[:, 2]) * t)
        keep &= ~mixed
    if keep.sum() < 3 or keep.all():
        return plane
    n, d = fit_plane_raw(pts[keep], sensor, plane.normal, plane.offset)
    return replace(plane, normal=n, offset=d)


def plane_labels(
    surface: Surface, planes: list[Plane], tolerance_m: float | FloatArray
) -> NDArray[np.intp]:
    """(rows, cols) index of the plane each node belongs to, -1 for none: the plane's
    piece, grown by one ring of nodes that lie within ``tolerance_m`` of it (the nodes
    along a crease, which the depth smoothing may have pulled off both walls)."""
    pts = surface.points.astype(np.float64)
    labels = np.full(pts.shape[:2], -1, dtype=np.intp)
    for k, p in enumerate(planes):
        labels[p.nodes] = k
    for k, p in enumerate(planes):
        ring = ndimage.binary_dilation(p.nodes, structure=np.ones((3, 3), bool)) & (labels < 0)
        with np.errstate(invalid="ignore"):
            near = np.abs(pts @ p.normal - p.offset) < tolerance_m
        labels[ring & near] = k
    return labels


def _plane_depth(rays: FloatArray, plane: Plane) -> FloatArray:
    """Depth (z) where ``rays`` (..., 3; z = 1) meet ``plane``; NaN where they do not."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = plane.offset / (rays @ plane.normal)
    return np.where(np.isfinite(z) & (z > 0), z, np.nan)


def snap_planes(
    surface: Surface,
    settings: PlaneSettings | None = None,
    factor: int = 8,
    sensor: SensorModel | None = None,
    raw: RawDepth | None = None,
) -> tuple[Surface, list[Plane]]:
    """``surface`` with its large planar pieces replaced by their planes; the pieces.

    The result is a lattice ``factor`` times finer (when a plane was found), so the
    warp sees a crease between two walls where it is, not cut by the coarse lattice:
    a node whose lattice cell has all its corners on planes takes, of those planes,
    the one nearest the interpolated surface there (inside a wall corner the nearer
    wall, outside one the farther); other nodes are interpolated. Every node stays on
    its projector ray. ``sensor``: the noise model of the depth, ``raw``: the depth before
    smoothing (see :func:`find_planes`)."""
    s = settings or PlaneSettings()
    planes = find_planes(surface, s, sensor, raw)
    if not planes:
        return surface, planes
    z_med = float(np.nanmedian(surface.points[..., 2]))
    tol = node_tolerance(s, sensor, surface.points[..., 2].astype(np.float64), z_med)
    labels = plane_labels(surface, planes, tol)
    rows, cols = surface.shape
    p = surface.projector
    shape = ((rows - 1) * factor + 1, (cols - 1) * factor + 1)
    xs = np.linspace(0.0, p.width - 1.0, shape[1])
    ys = np.linspace(0.0, p.height - 1.0, shape[0])
    uv = np.stack(np.meshgrid(xs, ys), axis=-1)
    rays = p.rays(uv)
    z_interp = surface.depth_at(uv)
    # the coarse cell of every fine node, and its corners' plane labels
    i = np.minimum(np.arange(shape[0]) // factor, rows - 2)
    j = np.minimum(np.arange(shape[1]) // factor, cols - 2)
    ii, jj = np.meshgrid(i, j, indexing="ij")
    corner_labels = np.stack(
        [labels[ii, jj], labels[ii + 1, jj], labels[ii, jj + 1], labels[ii + 1, jj + 1]]
    )
    # every known corner on a plane (a cell at the edge of the data takes its plane
    # where the interpolation has a value, rather than that value held constant)
    known = np.isfinite(surface.points[..., 2])
    corner_known = np.stack(
        [known[ii, jj], known[ii + 1, jj], known[ii, jj + 1], known[ii + 1, jj + 1]]
    )
    on_planes = (
        np.all((corner_labels >= 0) | ~corner_known, axis=0)
        & np.any(corner_labels >= 0, axis=0)
        & np.isfinite(z_interp)
    )
    # a cell with only some corners on a plane (an object's edge runs through it):
    # its nodes whose raw depth is on one of those planes take it, rather than the
    # slope interpolated across the edge
    edge = ~on_planes & np.any(corner_labels >= 0, axis=0) & np.isfinite(z_interp)
    raw_tol: float | FloatArray = 0.0
    if raw is not None and edge.any():
        raw_tol = node_tolerance(s, sensor, raw.points[..., 2].astype(np.float64), z_med)
    z = z_interp.copy()
    best = np.full(shape, np.inf)
    for k, plane in enumerate(planes):
        zk = _plane_depth(rays, plane)
        mine = np.any(corner_labels == k, axis=0) & np.isfinite(zk)
        use = on_planes & mine
        if raw is not None and np.any(edge & mine):
            use |= edge & mine & raw.near_plane(plane, raw_tol, shape)
        with np.errstate(invalid="ignore"):
            gap = np.abs(zk - np.where(np.isfinite(z_interp), z_interp, zk))
        take = use & (gap < best)
        z = np.where(take, zk, z)
        best = np.where(take, gap, best)
    meta = {
        **surface.meta,
        "planes": len(planes),
        PLANES_KEY: [[*(float(x) for x in q.normal), q.offset] for q in planes],
    }
    points = (rays * z[..., None]).astype(np.float32)
    return Surface(points, p, meta), planes


def plane_equations(meta: dict[str, object]) -> FloatArray:
    """The planes (k, 4) ``[n, d]`` (unit ``n``, ``n . X = d``) a surface's ``meta``
    lists (:func:`snap_planes` writes them; none: (0, 4)); raises
    :class:`~adaproj_edge.errors.SurfaceError` when the entry is not such a list."""
    raw = meta.get(PLANES_KEY)
    if raw is None:
        return np.zeros((0, 4))
    try:
        eq = np.array(raw, dtype=np.float64).reshape(-1, 4)
    except (TypeError, ValueError):
        raise SurfaceError(f"surface meta {PLANES_KEY}: not a list of [nx, ny, nz, d]") from None
    norm = np.linalg.norm(eq[:, :3], axis=1) if eq.size else np.zeros(0)
    if not np.isfinite(eq).all() or np.any(np.abs(norm - 1.0) > 1e-6):
        raise SurfaceError(f"surface meta {PLANES_KEY}: not unit normals with finite offsets")
    return eq


def on_planes(points: FloatArray, equations: FloatArray) -> NDArray[np.bool_]:
    """(n, k): whether each of ``points`` (n, 3) lies on each plane of ``equations``
    (k, 4), within ``ON_PLANE_REL`` of its depth (a node on a crease lies on two)."""
    tol = ON_PLANE_REL * np.abs(points[:, 2])
    with np.errstate(invalid="ignore"):
        near = np.abs(points @ equations[:, :3].T - equations[:, 3]) < tol[:, None]
    return np.asarray(near, dtype=bool)
