"""How many poses are still needed, and what to tell the user.

A calibration needs (:func:`assess`):

- point pairs over most of the projector frame (``cells`` regions, each with a few
  pairs): the lens and the principal point are read from the whole frame;
- a range of distances (the farthest pose's median depth ``min_depth_ratio`` times
  the nearest's): the focal length is told from the distance by it;
- a scene that is not one flat surface at every pose (a corner, or a wall and the
  floor): the IMU's rotation is read from planes, and one plane pins little;
- turns about two different axes between poses (left/right and up/down), by at
  least ``min_turn_deg``: the IMU's rotation is read from them.

Each unmet need costs one more pose (at least ``min_poses`` in all); the advice
says which move meets it.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray


@dataclass(frozen=True)
class PlanSettings:
    """What counts as enough."""

    min_poses: int = 4
    cells: tuple[int, int] = (8, 5)
    pairs_per_cell: int = 3
    min_coverage: float = 0.6
    min_depth_ratio: float = 1.3
    min_turn_deg: float = 8.0
    min_axis_spread: float = 0.3


@dataclass(frozen=True)
class PoseSummary:
    """What the plan needs of a pose: its pairs' projector pixels (n, 2) and 3D
    points (n, 3), the scene's plane normals (k, 3), and its turn from the previous
    pose (3,), a rotation vector in frame P (radians; zeros for the first)."""

    projector_uv: FloatArray
    points: FloatArray
    normals: FloatArray
    turn: FloatArray


@dataclass(frozen=True)
class Plan:
    """The verdict on the poses so far: ``done`` when nothing is missing,
    ``poses_needed`` more otherwise; ``advice`` for the next pose, ``status`` a one-
    line summary; the measures behind them."""

    done: bool
    poses_needed: int
    advice: str
    status: str
    coverage: float
    depth_range_m: tuple[float, float]
    planes: int
    axis_spread: float
    max_turn_deg: float


def coverage(uv: FloatArray, size: tuple[int, int], s: PlanSettings) -> FloatArray:
    """Pairs per region of the projector frame, (rows, cols) = ``s.cells`` reversed."""
    cols, rows = s.cells
    w, h = size
    if len(uv) == 0:
        return np.zeros((rows, cols))
    ix = np.clip((uv[:, 0] / w * cols).astype(np.intp), 0, cols - 1)
    iy = np.clip((uv[:, 1] / h * rows).astype(np.intp), 0, rows - 1)
    return np.bincount(iy * cols + ix, minlength=rows * cols).reshape(rows, cols).astype(float)


def _where(missing: NDArray[np.bool_]) -> str:
    """Which sides of the frame the missing regions (rows, cols) lie at."""
    rows, cols = missing.shape
    r3, c3 = max(rows // 3, 1), max(cols // 3, 1)
    sides = [
        name
        for name, part in (
            ("top", missing[:r3]),
            ("bottom", missing[-r3:]),
            ("left", missing[:, :c3]),
            ("right", missing[:, -c3:]),
        )
        if part.mean() > 0.5
    ]
    return ", ".join(sides) + " parts" if sides else "scattered parts"


def assess(
    poses: list[PoseSummary], size: tuple[int, int], settings: PlanSettings | None = None
) -> Plan:
    """The plan after ``poses`` (see the module's description); ``size`` is the
    projector frame (width, height)."""
    s = settings or PlanSettings()
    uv = np.concatenate([p.projector_uv for p in poses]) if poses else np.zeros((0, 2))
    cov_cells = coverage(uv, size, s) >= s.pairs_per_cell
    cov = float(np.mean(cov_cells))
    depths = [float(np.median(p.points[:, 2])) for p in poses if len(p.points)]
    lo, hi = (min(depths), max(depths)) if depths else (0.0, 0.0)
    planes = max((len(p.normals) for p in poses), default=0)
    turns = [p.turn for p in poses[1:]]
    angles = [float(np.degrees(np.linalg.norm(t))) for t in turns]
    big = [t / np.linalg.norm(t) for t, a in zip(turns, angles, strict=True) if a >= s.min_turn_deg]
    spread = float(np.linalg.svd(np.asarray(big), compute_uv=False)[1]) if len(big) >= 2 else 0.0
    advice: list[str] = []
    missing = 0
    if cov < s.min_coverage:
        missing += 1
        advice.append(
            f"aim so the projection's {_where(~cov_cells)} also land on the walls "
            f"(pairs cover {100 * cov:.0f} % of the frame)"
        )
    if depths and hi < s.min_depth_ratio * lo:
        missing += 1
        mid = (lo + hi) / 2
        target = lo / s.min_depth_ratio if mid > 1.2 else hi * s.min_depth_ratio
        way = "closer" if target < lo else "farther"
        advice.append(f"move {way} (about {target:.1f} m from the wall)")
    if len(poses) >= 2 and spread < s.min_axis_spread:
        missing += 1
        axes = np.abs(np.asarray(big)) if big else np.zeros((0, 3))
        yaw = bool(len(axes)) and float(axes[:, 1].max()) > 0.7
        advice.append("tilt the device up or down" if yaw else "turn the device left or right")
    if poses and planes < 2:
        advice.append(
            "aim at a wall corner, or a wall and the floor (one flat surface is not enough)"
        )
    needed = max(s.min_poses - len(poses), missing, 1 if planes < 2 and poses else 0)
    done = needed == 0
    if not advice:
        advice.append("change the distance and the angle a little")
    status = (
        f"pairs over {100 * cov:.0f} % of the frame, depth {lo:.2f}-{hi:.2f} m, "
        f"{planes} plane{'s' if planes != 1 else ''}"
    )
    status += "; enough poses" if done else f"; {needed} more pose{'s' if needed > 1 else ''}"
    return Plan(
        done,
        needed,
        "; ".join(advice),
        status,
        cov,
        (lo, hi),
        planes,
        spread,
        max(angles, default=0),
    )
