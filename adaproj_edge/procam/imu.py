"""``R_P_I``, the IMU's rotation in the projector frame, from the device's own motion.

Between two poses the device turns. The depth camera sees the scene's planes (the
walls of a corner, a wall and the floor) turn the other way: their normals give the
rotation ``A`` of the projector frame between the poses (through ``T_P_D``). The
gyroscope, integrated from one pose to the next with its bias measured while the
device stood still at each pose, gives the same rotation ``B`` in the IMU's frame.
``A = X B X^T`` for ``X = R_P_I``: every plane seen at two poses says
``n_i = X B X^T n_j``, and a least-squares fit over every pair of poses finds ``X``
(:func:`solve_imu_rotation`; plane matches that disagree with the others by more
than three times their median are dropped). Turns about two different axes are
needed; a plane
normal pins two of the three degrees of freedom of each turn, so two planes (or
more poses) are needed too.

The accelerometer's mean at rest (gravity, in frame I) is kept per pose; through
``R_P_I`` it gives the runtime "up" in the projector frame, and the fit reports
where up points at the first pose.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.planes import PlaneSettings, find_planes, fit_plane
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.geometry.rotations import rodrigues, rotation_matrix, rotation_vector
from adaproj_edge.geometry.surface import Surface

PLANES = PlaneSettings(tolerance_rel=0.006, max_rms_rel=0.004, min_fraction=0.08, max_planes=3)


def scene_planes(depth_m: FloatArray, K: FloatArray, block: int = 8) -> FloatArray:
    """Unit normals (k, 3) of the large planes in a depth image (frame D), each
    facing the camera, largest first.

    The depth (h, w) is averaged over ``block`` x ``block`` pixels into a lattice of
    points, whose planar pieces :func:`~adaproj_edge.geometry.planes.find_planes`
    finds; each plane is then refitted to the depth pixels near it (and not as near
    another plane), three times, the band narrowing to 2.5 times its RMS.
    """
    h, w = depth_m.shape
    z = np.where(np.isfinite(depth_m) & (depth_m > 0), depth_m, 0.0).astype(np.float32)
    ok = (z > 0).astype(np.float32)
    size = (w // block, h // block)
    zs = cv2.resize(z, size, interpolation=cv2.INTER_AREA)
    ns = cv2.resize(ok, size, interpolation=cv2.INTER_AREA)
    with np.errstate(invalid="ignore", divide="ignore"):
        zl = np.where(ns > 0.7, zs / ns, np.nan)
    Kl = K.copy()
    Kl[:2] /= block
    Kl[0, 2] = (K[0, 2] + 0.5) / block - 0.5
    Kl[1, 2] = (K[1, 2] + 0.5) / block - 0.5
    lattice = Projector(Kl, size[0], size[1])
    rays = lattice.rays(lattice.pixel_grid())
    if not np.isfinite(zl).any():
        return np.zeros((0, 3))
    planes = find_planes(Surface((rays * zl[..., None]).astype(np.float32), lattice), PLANES)
    full = Projector(K, w, h)
    sub = (slice(None, None, 2), slice(None, None, 2))  # every other pixel: plenty
    pts = (full.rays(full.pixel_grid()[sub]) * z[sub][..., None])[z[sub] > 0]
    normals = []
    for p in planes:
        n, d = p.normal, p.offset
        tol = 0.01 * abs(d)
        for _ in range(3):  # refit to the pixels near the plane, closer each time
            near = np.abs(pts @ n - d) < tol
            for q in planes:  # not where another plane is as near (a crease)
                if q is not p:
                    near &= np.abs(pts @ q.normal - q.offset) > 2 * tol
            if near.sum() < 100:
                break
            n, d = fit_plane(pts[near])
            rms = float(np.sqrt(np.mean((pts[near] @ n - d) ** 2)))
            tol = max(2.5 * rms, 1e-4)
        normals.append(n)
    return np.asarray(normals).reshape(-1, 3)


def integrate_gyro(
    t_ns: FloatArray, gyro: FloatArray, t0: int, t1: int, bias0: FloatArray, bias1: FloatArray
) -> FloatArray:
    """The rotation (3, 3) of the IMU frame from ``t0`` to ``t1`` (taking vectors in
    the frame at ``t1`` to the frame at ``t0``), from gyro samples (n,) ns, (n, 3)
    rad/s, the bias going linearly from ``bias0`` at ``t0`` to ``bias1`` at ``t1``."""
    t = np.asarray(t_ns, dtype=np.float64)
    keep = (t > t0) & (t <= t1)
    tk, wk = t[keep], np.asarray(gyro, np.float64)[keep]
    prev = np.r_[float(t0), tk[:-1]]
    dt = (tk - prev) * 1e-9
    frac = ((tk - t0) / max(t1 - t0, 1))[:, None]
    steps = rodrigues((wk - (bias0 + frac * (bias1 - bias0))) * dt[:, None])
    R = np.eye(3)
    for d in steps:
        R = R @ d
    return R


@dataclass(frozen=True)
class PoseMotion:
    """What the rotation fit needs of one pose.

    ``normals`` (k, 3): the scene's plane normals in frame D; ``gyro_bias`` (3,) and
    ``accel`` (3,): the mean gyro (rad/s) and accelerometer (m/s^2) while the device
    stood still for the capture, between ``start_ns`` and ``end_ns``.
    """

    normals: FloatArray
    gyro_bias: FloatArray
    accel: FloatArray
    start_ns: int
    end_ns: int


@dataclass(frozen=True)
class ImuSolution:
    """``R_P_I`` (3, 3) when it could be measured (else the nominal one), with the
    fit's RMS (degrees), the number of plane matches used, the largest turn between
    two poses (degrees), the standard error of the rotation (degrees), ``up`` (3,)
    in frame P at the first pose, and ``problem``: why it was not measured (empty
    when it was)."""

    R_P_I: FloatArray
    measured: bool
    rms_deg: float = 0.0
    matches: int = 0
    max_turn_deg: float = 0.0
    sigma_deg: float = float("inf")
    up: FloatArray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    problem: str = ""


def _skew_axis_spread(axes: list[FloatArray]) -> float:
    """How far apart the turn axes are: the second singular value of the stacked
    unit axes, scaled by the turn (0 when all turns share one axis)."""
    if len(axes) < 2:
        return 0.0
    return float(np.linalg.svd(np.asarray(axes), compute_uv=False)[1])


def solve_imu_rotation(
    poses: list[PoseMotion],
    t_ns: FloatArray,
    gyro: FloatArray,
    R_P_D: FloatArray,
    nominal: FloatArray,
    max_match_deg: float = 12.0,
    normal_floor_deg: float = 0.1,
) -> ImuSolution:
    """Fit ``R_P_I`` (see the module's description).

    Parameters
    ----------
    poses : list of PoseMotion
        In capture order.
    t_ns, gyro : (n,), (n, 3)
        Every gyro sample of the procedure (sensor time ns, rad/s, frame I).
    R_P_D : (3, 3)
        Rotation of ``T_P_D`` (the solved one).
    nominal : (3, 3)
        The board's ``R_P_I``: the start, and the answer when it cannot be measured.
    max_match_deg : float
        How far (after the predicted turn) a plane may be from its match.
    normal_floor_deg : float
        The least error assumed of a plane normal, for the standard error of the fit.
    """
    up0 = _up(nominal, poses)
    if len(poses) < 2:
        return ImuSolution(nominal, False, up=up0, problem="one pose only")
    # from the middle of each capture to the next one's (still at both), the bias
    # going from one pose's to the next's; longer spans are products of these
    step = []
    for a, b in itertools.pairwise(poses):
        ti, tj = (a.start_ns + a.end_ns) // 2, (b.start_ns + b.end_ns) // 2
        step.append(integrate_gyro(t_ns, gyro, ti, tj, a.gyro_bias, b.gyro_bias))
    B: dict[tuple[int, int], FloatArray] = {}
    for i in range(len(poses)):
        R = np.eye(3)
        for j in range(i + 1, len(poses)):
            R = R @ step[j - 1]
            B[(i, j)] = R
    normals_p = [p.normals @ R_P_D.T for p in poses]
    cos_max = np.cos(np.radians(max_match_deg))
    pairs: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    axes: list[FloatArray] = []
    turns: list[float] = []
    for (i, j), Bij in B.items():
        A_pred = nominal @ Bij @ nominal.T
        rv = rotation_vector(Bij)
        turns.append(float(np.degrees(np.linalg.norm(rv))))
        used = False
        for nj in normals_p[j]:
            pred = A_pred @ nj
            c = normals_p[i] @ pred
            if c.size and float(c.max()) >= cos_max:
                pairs.append((normals_p[i][int(np.argmax(c))], nj, Bij))
                used = True
        if used and np.linalg.norm(rv) > np.radians(2.0):
            axes.append(rv / np.linalg.norm(rv))
    max_turn = max(turns) if turns else 0.0
    if len(pairs) < 3 or _skew_axis_spread(axes) < 0.15:
        return ImuSolution(
            nominal,
            False,
            matches=len(pairs),
            max_turn_deg=max_turn,
            up=up0,
            problem="the device did not turn about two different axes between poses with "
            "the same planes in view (tilt it up or down as well as left or right)",
        )

    def fit(use: list[tuple[FloatArray, FloatArray, FloatArray]], r0: FloatArray) -> Any:
        def fun(r: FloatArray) -> FloatArray:
            X = rotation_matrix(r) @ nominal
            return np.concatenate([ni - X @ (Bij @ (X.T @ nj)) for ni, nj, Bij in use])

        return least_squares(fun, r0, method="lm")

    # robustly: a plane found badly at one pose (a grazing floor, a piece of two
    # walls) is dropped when it disagrees with the others
    res = fit(pairs, np.zeros(3))
    for _ in range(2):
        err = np.linalg.norm(res.fun.reshape(-1, 3), axis=1)
        keep = err <= max(3.0 * float(np.median(err)), np.radians(0.15))
        if keep.all() or keep.sum() < 3:
            break
        pairs = [q for q, k in zip(pairs, keep, strict=True) if k]
        res = fit(pairs, res.x)
    X = rotation_matrix(res.x) @ nominal
    r = res.fun.reshape(-1, 3)
    rms = float(np.degrees(np.sqrt(np.mean(np.sum(r * r, axis=1)))))
    J = res.jac
    dof = max(r.size - 3, 1)
    # the normals' own error is at least ``normal_floor_deg`` (a handful of matches
    # fitted closely says little about it)
    s2 = max(float(res.fun @ res.fun) / dof, np.radians(normal_floor_deg) ** 2)
    try:
        cov = np.linalg.inv(J.T @ J) * s2
        sigma = float(np.degrees(np.sqrt(np.trace(cov))))
    except np.linalg.LinAlgError:
        sigma = float("inf")
    return ImuSolution(X, True, rms, len(pairs), max_turn, sigma, _up(X, poses))


def _up(R_P_I: FloatArray, poses: list[PoseMotion]) -> FloatArray:
    """'Up' (3,) in frame P at the first pose: the accelerometer at rest (the specific
    force, which points up) rotated into P."""
    if not poses or not np.linalg.norm(poses[0].accel):
        return np.array([0.0, -1.0, 0.0])
    a = R_P_I @ poses[0].accel
    return a / np.linalg.norm(a)
