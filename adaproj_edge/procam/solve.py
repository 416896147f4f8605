"""The projector's model and its pose in the depth frame, from point pairs.

All poses share one rigid rig, so every pair of every pose — a 3D point in frame D
and the projector pixel that lit it — belongs to one point set for one projector:
intrinsics ``K`` (``fx, fy, cx, cy``), lens distortion when it pays, and ``T_P_D``.
The point set is not planar when the scene has depth variety (a corner, a wall and
the floor) or the poses differ, which is what lets focal length and principal point
be told from the projector's distance and tilt.

Steps (:func:`solve_projector`):

1. start from the nominal calibration, and from the direct linear transform of the
   pairs (``P = K [R | t]``, decomposed), and keep the start with the lower robust
   cost: a unit whose principal point is hundreds of pixels from the nominal one is
   found all the same;
2. Levenberg-Marquardt style trust-region fits (``scipy.optimize.least_squares``)
   of the reprojection error, each pair weighed by its expected error: the spread
   of its decode fit plus its depth error carried into projector pixels (the depth
   confidence), with a soft-L1 loss, then rounds that drop the pairs beyond
   ``reject`` robust standard deviations (depth edges, inter-reflections, decode
   errors) and refit;
3. lens distortion (k1, k2, p1, p2) is fitted on top and kept only when it pays:
   it moves some pixel of the frame by more than ``distortion_min_px`` and lowers
   the RMS by ``distortion_min_gain``;
4. the standard errors of the parameters come from the Jacobian at the solution;
   :mod:`adaproj_edge.procam.report` refuses a solve they do not pin down.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.optimize import least_squares

from adaproj_edge.arrays import BoolArray, FloatArray
from adaproj_edge.errors import CalibrationError
from adaproj_edge.geometry.rotations import rotation_matrix, rotation_vector
from adaproj_edge.procam.pairs import Pairs

N_PINHOLE = 10  # fx, fy, cx, cy, rotation vector (3), translation (3)
N_DISTORTION = 4  # k1, k2, p1, p2


@dataclass(frozen=True)
class SolveSettings:
    """Tuning of :func:`solve_projector` (projector pixels unless stated)."""

    distortion: str = "auto"  # "auto": when it pays; "none"; "always"
    min_pairs: int = 60
    max_pairs: int = 40_000
    floor_px: float = 0.08
    loss_scale: float = 2.5  # soft-L1 scale, in expected errors
    reject: float = 3.5  # robust standard deviations
    rounds: int = 3
    distortion_min_px: float = 0.3
    distortion_min_gain: float = 0.03


@dataclass(frozen=True)
class ProjectorModel:
    """Intrinsics ``K`` (3, 3), lens ``distortion`` (5,) in OpenCV's order
    (k1, k2, p1, p2, k3; zeros for a pinhole) and ``T_P_D`` (4, 4)."""

    K: FloatArray
    distortion: FloatArray
    T_P_D: FloatArray

    def project(self, points_d: FloatArray) -> FloatArray:
        """Projector pixels (n, 2) of points (n, 3) in frame D."""
        pts = points_d @ self.T_P_D[:3, :3].T + self.T_P_D[:3, 3]
        return _project(pts, self.K, self.distortion)

    @property
    def params(self) -> FloatArray:
        """The solver's parameter vector (14,)."""
        K, T = self.K, self.T_P_D
        return np.concatenate(
            [
                [K[0, 0], K[1, 1], K[0, 2], K[1, 2]],
                rotation_vector(T[:3, :3]),
                T[:3, 3],
                self.distortion[:4],
            ]
        )

    @classmethod
    def from_params(cls, p: FloatArray) -> ProjectorModel:
        K = np.array([[p[0], 0.0, p[2]], [0.0, p[1], p[3]], [0.0, 0.0, 1.0]])
        T = np.eye(4)
        T[:3, :3] = rotation_matrix(p[4:7])
        T[:3, 3] = p[7:10]
        dist = np.zeros(5)
        dist[:4] = p[10:14] if len(p) >= 14 else 0.0
        return cls(K, dist, T)


def _project(pts: FloatArray, K: FloatArray, dist: FloatArray) -> FloatArray:
    with np.errstate(divide="ignore", invalid="ignore"):
        x = pts[:, 0] / pts[:, 2]
        y = pts[:, 1] / pts[:, 2]
    if np.any(dist):
        k1, k2, p1, p2, k3 = dist
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        x, y = (
            x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y,
        )
    return np.stack([K[0, 0] * x + K[0, 2], K[1, 1] * y + K[1, 2]], axis=1)


@dataclass(frozen=True)
class ProjectorSolution:
    """The solved model and how well it fits.

    Attributes
    ----------
    model : ProjectorModel
    pairs : Pairs
        The pairs solved from (thinned to ``max_pairs``).
    inliers : (n,) bool
        The pairs the final fit used.
    residuals : (n, 2) float
        Model projection minus the observed projector pixel, every pair.
    rms_px : float
        RMS reprojection error over the inliers (projector pixels, both axes).
    sigma : dict
        Standard errors: ``fx``, ``fy`` (relative), ``cx``, ``cy`` (px),
        ``rotation_deg``, ``translation_mm``.
    distortion_used : bool
    """

    model: ProjectorModel
    pairs: Pairs
    inliers: BoolArray
    residuals: FloatArray
    rms_px: float
    sigma: dict[str, float] = field(default_factory=dict)
    distortion_used: bool = False


def dlt(points: FloatArray, uv: FloatArray) -> ProjectorModel:
    """Direct linear transform: the pinhole model (zero skew forced) whose projection
    matrix best maps ``points`` (n >= 6, 3) to ``uv`` (n, 2), Hartley-normalised."""
    if len(points) < 6:
        raise CalibrationError("too few point pairs for a projector model")
    c3, c2 = points.mean(axis=0), uv.mean(axis=0)
    s3 = np.sqrt(3) / max(float(np.mean(np.linalg.norm(points - c3, axis=1))), 1e-12)
    s2 = np.sqrt(2) / max(float(np.mean(np.linalg.norm(uv - c2, axis=1))), 1e-12)
    T3 = np.diag([s3, s3, s3, 1.0])
    T3[:3, 3] = -s3 * c3
    T2 = np.diag([s2, s2, 1.0])
    T2[:2, 2] = -s2 * c2
    X = np.c_[(points - c3) * s3, np.ones(len(points))]
    x = (uv - c2) * s2
    A = np.zeros((2 * len(points), 12))
    A[0::2, 0:4] = X
    A[0::2, 8:12] = -x[:, :1] * X
    A[1::2, 4:8] = X
    A[1::2, 8:12] = -x[:, 1:] * X
    P = np.linalg.svd(A, full_matrices=False)[2][-1].reshape(3, 4)
    P = np.linalg.inv(T2) @ P @ T3
    K, R = scipy.linalg.rq(P[:, :3])
    D = np.diag(np.sign(np.diag(K)))
    K, R = K @ D, D @ R
    t = np.linalg.solve(K, P[:, 3])
    if np.linalg.det(R) < 0:
        R, t = -R, -t
    K = K / K[2, 2]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    if np.median(points @ R[2] + t[2]) < 0:  # the solution behind the projector
        raise CalibrationError("the point pairs do not fit a projector in front of them")
    K[0, 1] = 0.0
    return ProjectorModel(K, np.zeros(5), T)


def _depth_gain(model: ProjectorModel, points: FloatArray) -> FloatArray:
    """Projector pixels per metre of depth error at each point (n,): how far its
    projection moves when the point slides along the camera ray."""
    eps = 1e-3
    a = model.project(points)
    b = model.project(points * (1 + eps / np.maximum(points[:, 2:3], 1e-6)))
    return np.linalg.norm(b - a, axis=1) / eps  # type: ignore[no-any-return]


def _fit(
    p0: FloatArray, pairs: Pairs, sigma: FloatArray, n_params: int, loss: str, scale: float
) -> FloatArray:
    fixed = p0[n_params:]

    def fun(p: FloatArray) -> FloatArray:
        m = ProjectorModel.from_params(np.concatenate([p, fixed]))
        r = (m.project(pairs.points) - pairs.projector_uv) / sigma[:, None]
        return np.nan_to_num(r, nan=1e6).ravel()

    res = least_squares(
        fun, p0[:n_params], method="trf", loss=loss, f_scale=scale, x_scale="jac", max_nfev=200
    )
    return np.concatenate([res.x, fixed])


def _robust_cost(model: ProjectorModel, pairs: Pairs) -> float:
    r = np.linalg.norm(model.project(pairs.points) - pairs.projector_uv, axis=1)
    return float(np.nanmedian(np.where(np.isfinite(r), r, 1e9)))


def _sigma(model: ProjectorModel, pairs: Pairs, s: SolveSettings) -> FloatArray:
    """Expected error (n,) of each pair's projector pixel, in projector pixels."""
    g = _depth_gain(model, pairs.points)
    return np.sqrt(pairs.sigma_uv**2 + (g * pairs.sigma_z) ** 2 + s.floor_px**2)


def _refine(
    p: FloatArray, pairs: Pairs, n_params: int, s: SolveSettings
) -> tuple[FloatArray, BoolArray, FloatArray]:
    """Robust fit, then rounds of rejection and refit; parameters, inliers, sigma."""
    inl = np.ones(len(pairs), bool)
    sigma = _sigma(ProjectorModel.from_params(p), pairs, s)
    p = _fit(p, pairs, sigma, n_params, "soft_l1", s.loss_scale * 4)
    for _ in range(s.rounds):
        model = ProjectorModel.from_params(p)
        sigma = _sigma(model, pairs, s)
        r = np.linalg.norm(model.project(pairs.points) - pairs.projector_uv, axis=1) / sigma
        r = np.where(np.isfinite(r), r, np.inf)
        mad = float(np.median(r[inl])) / 0.8326  # median of a 2-D Rayleigh(1) norm
        inl = r <= s.reject * max(mad, 1e-9)
        if inl.sum() < s.min_pairs:
            raise CalibrationError(
                f"only {int(inl.sum())} point pairs agree with one projector model: the "
                "captures are inconsistent (did the device move during a pose?)"
            )
        p = _fit(p, pairs.select(inl), sigma[inl], n_params, "soft_l1", s.loss_scale)
    return p, inl, _sigma(ProjectorModel.from_params(p), pairs, s)


def _errors(p: FloatArray, pairs: Pairs, sigma: FloatArray, n_params: int) -> dict[str, float]:
    """Standard errors of the parameters (covariance from the Jacobian)."""
    m0 = ProjectorModel.from_params(p)
    r0 = ((m0.project(pairs.points) - pairs.projector_uv) / sigma[:, None]).ravel()
    J = np.zeros((r0.size, n_params))
    steps = np.r_[np.abs(p[:4]) * 1e-6 + 1e-6, [1e-7] * 3, [1e-6] * 3, [1e-6] * 4][:n_params]
    for i in range(n_params):
        q = p.copy()
        q[i] += steps[i]
        mi = ProjectorModel.from_params(q)
        J[:, i] = ((mi.project(pairs.points) - pairs.projector_uv) / sigma[:, None]).ravel() - r0
        J[:, i] /= steps[i]
    dof = max(r0.size - n_params, 1)
    s2 = float(r0 @ r0) / dof
    try:
        cov = np.linalg.inv(J.T @ J) * s2
    except np.linalg.LinAlgError:
        cov = np.full((n_params, n_params), np.inf)
    sd = np.sqrt(np.abs(np.diag(cov)))
    return {
        "fx": float(sd[0] / p[0]),
        "fy": float(sd[1] / p[1]),
        "cx": float(sd[2]),
        "cy": float(sd[3]),
        "rotation_deg": float(np.degrees(np.linalg.norm(sd[4:7]))),
        "translation_mm": float(1000 * np.linalg.norm(sd[7:10])),
    }


def _thin(pairs: Pairs, n: int) -> Pairs:
    """At most ``n`` pairs, evenly spread over the list (deterministic)."""
    if len(pairs) <= n:
        return pairs
    return pairs.select(np.linspace(0, len(pairs) - 1, n).round().astype(np.intp))


def _distortion_shift(model: ProjectorModel, width: int, height: int) -> float:
    """The largest distance (px) distortion moves a pixel of the frame's border."""
    t = np.linspace(0, 1, 33)
    u = np.r_[t * (width - 1), t * (width - 1), np.zeros(33), np.full(33, width - 1.0)]
    v = np.r_[np.zeros(33), np.full(33, height - 1.0), t * (height - 1), t * (height - 1)]
    K = model.K
    pts = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=1)
    d = _project(pts, K, model.distortion) - np.stack([u, v], axis=1)
    return float(np.max(np.linalg.norm(d, axis=1)))


def solve_projector(
    pairs: Pairs,
    nominal: ProjectorModel,
    size: tuple[int, int],
    settings: SolveSettings | None = None,
) -> ProjectorSolution:
    """Solve the projector model from the pairs of all poses.

    Parameters
    ----------
    pairs : Pairs
        Every pose's pairs (3D points in frame D, projector pixels).
    nominal : ProjectorModel
        The starting guess (the board's calibration).
    size : (width, height)
        The projector frame, for the distortion check.
    settings : SolveSettings, optional

    Raises
    ------
    CalibrationError
        Too few pairs, or no consistent model.
    """
    s = settings or SolveSettings()
    if len(pairs) < s.min_pairs:
        raise CalibrationError(
            f"only {len(pairs)} point pairs decoded (at least {s.min_pairs} are needed)"
        )
    pairs = _thin(pairs, s.max_pairs)
    starts = [nominal.params.copy()]
    try:
        starts.append(dlt(pairs.points, pairs.projector_uv).params)
    except (CalibrationError, np.linalg.LinAlgError, ValueError):
        pass
    starts[0][10:] = 0.0
    p = min(starts, key=lambda q: _robust_cost(ProjectorModel.from_params(q), pairs))
    p, inl, sigma = _refine(p, pairs, N_PINHOLE, s)
    used = False
    if s.distortion != "none":
        q, inl_d, sigma_d = _refine(p, pairs, N_PINHOLE + N_DISTORTION, s)
        md = ProjectorModel.from_params(q)
        keep = s.distortion == "always"
        if not keep:
            rms0 = _rms(ProjectorModel.from_params(p), pairs, inl)
            rms1 = _rms(md, pairs, inl_d)
            keep = (
                _distortion_shift(md, *size) >= s.distortion_min_px
                and rms1 <= (1 - s.distortion_min_gain) * rms0
            )
        if keep:
            p, inl, sigma, used = q, inl_d, sigma_d, True
    n_params = N_PINHOLE + (N_DISTORTION if used else 0)
    if not used:
        p[10:] = 0.0
    model = ProjectorModel.from_params(p)
    residuals = model.project(pairs.points) - pairs.projector_uv
    return ProjectorSolution(
        model,
        pairs,
        inl,
        residuals,
        _rms(model, pairs, inl),
        _errors(p, pairs.select(inl), sigma[inl], n_params),
        used,
    )


def _rms(model: ProjectorModel, pairs: Pairs, inl: BoolArray) -> float:
    r = model.project(pairs.points[inl]) - pairs.projector_uv[inl]
    return float(np.sqrt(np.mean(np.sum(r * r, axis=1))))
