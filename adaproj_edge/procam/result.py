"""From captured poses to a calibration: the projector solve, then the IMU rotation.

:func:`solve_capture` solves the projector model and ``T_P_D`` from every pose's
pairs (:mod:`~adaproj_edge.procam.solve`), then ``R_P_I`` from the scene's planes
and the gyro (:mod:`~adaproj_edge.procam.imu`) with the solved ``T_P_D`` and the
accelerometer's offset from the still poses' readings (:mod:`~adaproj_edge.procam.accel`),
and
returns the new :class:`~adaproj_edge.geometry.calibration.Calibration` (the depth
model stays the device's own) with what the report needs. The verdict is
:func:`adaproj_edge.procam.report.judge`'s.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.projector import Projector
from adaproj_edge.procam.accel import AccelOffsetSolution, solve_accel_offset
from adaproj_edge.procam.imu import ImuSolution, PoseMotion, solve_imu_rotation
from adaproj_edge.procam.pairs import Pairs
from adaproj_edge.procam.procedure import CaptureRun
from adaproj_edge.procam.solve import (
    ProjectorModel,
    ProjectorSolution,
    SolveSettings,
    solve_projector,
)


@dataclass(frozen=True)
class CalibrationResult:
    """The solved calibration, the solves behind it and the capture it came from."""

    calibration: Calibration
    nominal: Calibration
    projector: ProjectorSolution
    imu: ImuSolution
    run: CaptureRun
    accel: AccelOffsetSolution = field(default_factory=AccelOffsetSolution)


def nominal_model(calibration: Calibration) -> ProjectorModel:
    """The projector model of a calibration file (the solver's starting guess)."""
    return ProjectorModel(calibration.projector.K, calibration.distortion, calibration.T_P_D)


def solve_capture(
    run: CaptureRun, nominal: Calibration, settings: SolveSettings | None = None
) -> CalibrationResult:
    """Solve the calibration of the captured poses.

    Parameters
    ----------
    run : CaptureRun
        The poses (:func:`~adaproj_edge.procam.procedure.capture_poses`).
    nominal : Calibration
        The board's calibration: the starting guess, and the depth model kept.
    settings : SolveSettings, optional

    Raises
    ------
    CalibrationError
        Too few pairs, or no consistent projector model.
    """
    pairs = Pairs.concat([p.pairs for p in run.poses])
    p = nominal.projector
    sol = solve_projector(pairs, nominal_model(nominal), (p.width, p.height), settings)
    m = sol.model
    motions = [PoseMotion(q.normals, q.gyro_bias, q.accel, q.start_ns, q.end_ns) for q in run.poses]
    imu = solve_imu_rotation(motions, run.imu_t, run.imu_gyro, m.T_P_D[:3, :3], nominal.R_P_I)
    accel = solve_accel_offset(np.array([q.accel for q in run.poses]).reshape(-1, 3))
    offset = accel.offset if accel.measured else nominal.accel_offset
    K = m.K.copy()
    K[0, 1] = 0.0
    # the structured light does not measure the lens's vignetting: the nominal's is kept
    cal = Calibration(
        Projector(K, p.width, p.height),
        nominal.depth,
        m.T_P_D,
        imu.R_P_I,
        m.distortion.copy(),
        vignetting=nominal.vignetting,
        accel_offset=offset,
    )
    return CalibrationResult(cal, nominal, sol, imu, run, accel)


def pose_depths(run: CaptureRun) -> list[tuple[float, float, float]]:
    """Per pose: the 5th percentile, median and 95th percentile depth of its pairs (m)."""
    out = []
    for p in run.poses:
        z: FloatArray = p.pairs.points[:, 2] if len(p.pairs) else np.zeros(1)
        out.append(tuple(float(v) for v in np.percentile(z, [5, 50, 95])))
    return out  # type: ignore[return-value]
