"""The accelerometer's zero-g offset from the calibration's still poses.

Held still, the accelerometer reads the specific force (gravity's reaction, of size
``g`` whatever the orientation) plus its own offset ``b``: the mean readings ``a_i`` of
poses in several orientations lie on a sphere of radius ``g`` centred at ``b``. The
fit is least squares on ``|a_i - b| - g`` (Gauss-Newton), ``g`` free but held near
standard gravity by a prior (local gravity differs from it by at most 0.3 %): with the
poses of a calibration (the device turned some tens of degrees around pointing at a
wall) the offset across the mean reading is measured by how the readings turn, the
part along it only through ``g``, and that part does not tilt "up" (it changes the
reading's length, not its direction). A 10 mg offset across gravity tilts "up" by
0.6 degrees, which no filter can tell from gravity: this is the only way to see it.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from adaproj_edge.arrays import FloatArray

STANDARD_G = 9.80665
"""Standard gravity, m/s^2: the prior on the sphere's radius."""
G_SIGMA = 0.03
"""How far local gravity may be from standard, m/s^2 (one sigma of the prior)."""
READING_SIGMA = 0.003
"""The error of a still pose's mean reading, m/s^2 (noise averaged, quantisation)."""
MIN_SPREAD_DEG = 10.0
"""The poses' readings must turn at least this much apart (else: not measured)."""


@dataclass(frozen=True)
class AccelOffsetSolution:
    """The offset (3,) in frame I, m/s^2 (zeros when not measured), whether it was
    measured, the fitted gravity, the RMS of the fit (m/s^2), the standard error of the
    offset across the mean reading (m/s^2: what tilts "up"), the largest angle between
    two poses' readings (degrees) and ``problem``: why it was not measured."""

    offset: FloatArray = field(default_factory=lambda: np.zeros(3))
    measured: bool = False
    gravity: float = STANDARD_G
    rms: float = 0.0
    sigma_across: float = float("inf")
    spread_deg: float = 0.0
    problem: str = ""


def solve_accel_offset(accel: FloatArray, iterations: int = 20) -> AccelOffsetSolution:
    """The offset ``b`` (3,) that puts the still poses' mean readings ``accel`` (n, 3)
    at one distance (gravity) from it.

    Returns a solution with ``measured`` False (offset zero) when there are fewer than
    three poses, a reading is not finite or not near ``g``, or the readings turn less
    than :data:`MIN_SPREAD_DEG` apart.

    Examples
    --------
    >>> up = np.array([[0, -1, 0], [0.3, -0.95, 0], [0, -0.95, 0.3], [-0.3, -0.95, -0.1]])
    >>> a = 9.81 * up / np.linalg.norm(up, axis=1)[:, None] + [0.05, -0.02, 0.1]
    >>> s = solve_accel_offset(a)
    >>> bool(s.measured), np.round(s.offset[[0, 2]], 3).tolist()
    (True, [0.05, 0.1])
    """
    a = np.asarray(accel, dtype=np.float64).reshape(-1, 3)
    if a.shape[0] < 3:
        return AccelOffsetSolution(problem=f"{a.shape[0]} still poses (3 or more needed)")
    norms = np.linalg.norm(a, axis=1)
    if not np.all(np.isfinite(a)) or np.any(np.abs(norms - STANDARD_G) > 1.0):
        return AccelOffsetSolution(problem="a still pose's accelerometer is not near 1 g")
    u = a / norms[:, None]
    spread = float(np.degrees(np.arccos(np.clip((u @ u.T).min(), -1.0, 1.0))))
    if spread < MIN_SPREAD_DEG:
        return AccelOffsetSolution(
            spread_deg=spread,
            problem=f"the poses turn {spread:.1f} deg apart ({MIN_SPREAD_DEG:g} needed)",
        )
    x = np.array([0.0, 0.0, 0.0, STANDARD_G])  # b, g
    J = np.zeros((a.shape[0] + 1, 4))
    for _ in range(iterations):
        d = a - x[:3]
        dist = np.linalg.norm(d, axis=1)
        r = np.concatenate([(dist - x[3]) / READING_SIGMA, [(x[3] - STANDARD_G) / G_SIGMA]])
        J[:-1, :3] = -d / dist[:, None] / READING_SIGMA
        J[:-1, 3] = -1.0 / READING_SIGMA
        J[-1, 3] = 1.0 / G_SIGMA
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        x += step
        if np.max(np.abs(step)) < 1e-9:
            break
    d = a - x[:3]
    res = np.linalg.norm(d, axis=1) - x[3]
    rms = float(np.sqrt(np.mean(res * res)))
    # the offset's covariance, and its part across the mean reading
    cov = np.linalg.pinv(J.T @ J)[:3, :3]
    m = u.mean(axis=0)
    m /= np.linalg.norm(m)
    across = np.eye(3) - np.outer(m, m)
    sigma = float(np.sqrt(max(np.trace(across @ cov @ across), 0.0)))
    return AccelOffsetSolution(x[:3].copy(), True, float(x[3]), rms, sigma, spread)
