"""The verdict on a calibration, its JSON report and its picture.

:func:`judge` gives one line: **good** (reprojection RMS < 0.5 px), **acceptable**
(< 1 px), **poor** (what to redo and why) or **refused** (the captures cannot pin
the calibration down: one flat plane only, too few poses, parameters the poses do
not determine). Only good and acceptable calibrations are written. The IMU's
rotation left at the nominal one (not measured), or measured only loosely (standard
error over ``max_sigma_imu_deg``), makes a calibration acceptable at
best, with the reason.

:func:`report_dict` is the JSON report (every figure behind the verdict, the change
from the nominal calibration, each pose's capture); :func:`report_picture` draws the
pairs over the projector frame coloured by pose, their residual vectors (x
``magnify``, outliers in red), and the depth range each pose covered.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from adaproj_edge.arrays import Image
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.geometry.planes import fit_plane
from adaproj_edge.geometry.rotations import rotation_vector
from adaproj_edge.procam.result import CalibrationResult, pose_depths
from adaproj_edge.render.sheet import titled

LEVELS = ("refused", "poor", "acceptable", "good")


@dataclass(frozen=True)
class Limits:
    """What a calibration must meet (pixels, fractions, degrees, millimetres)."""

    good_px: float = 0.5
    acceptable_px: float = 1.0
    planar_rel: float = 0.004
    min_poses: int = 3
    max_sigma_focal: float = 0.0015
    max_sigma_centre_px: float = 1.5
    max_sigma_rotation_deg: float = 0.05
    max_sigma_translation_mm: float = 1.0
    max_sigma_imu_deg: float = 0.5


@dataclass(frozen=True)
class Verdict:
    """``level`` (one of :data:`LEVELS`), the one-line ``line`` and the ``reasons``."""

    level: str
    line: str
    reasons: list[str] = field(default_factory=list)

    @property
    def writable(self) -> bool:
        """Whether the calibration may be written: good or acceptable."""
        return self.level in ("good", "acceptable")


def changes(new: Calibration, old: Calibration) -> dict[str, float]:
    """How far ``new`` is from ``old``: focal (%), principal point (px), ``T_P_D``
    rotation (deg) and translation (mm), ``R_P_I`` (deg)."""
    Kn, Ko = new.projector.K, old.projector.K
    dR = new.T_P_D[:3, :3] @ old.T_P_D[:3, :3].T
    dI = new.R_P_I @ old.R_P_I.T
    return {
        "focal_pct": round(100 * (Kn[0, 0] / Ko[0, 0] - 1), 4),
        "principal_px": round(float(np.hypot(Kn[0, 2] - Ko[0, 2], Kn[1, 2] - Ko[1, 2])), 3),
        "T_P_D_deg": round(float(np.degrees(np.linalg.norm(rotation_vector(dR)))), 4),
        "T_P_D_mm": round(float(1000 * np.linalg.norm(new.T_P_D[:3, 3] - old.T_P_D[:3, 3])), 3),
        "R_P_I_deg": round(float(np.degrees(np.linalg.norm(rotation_vector(dI)))), 4),
    }


def _planar(result: CalibrationResult, limits: Limits) -> bool:
    """Whether every pose's points lie on one plane (to ``planar_rel`` of depth)."""
    for p in result.run.poses:
        pts = p.pairs.points
        if len(pts) < 10:
            continue
        n, d = fit_plane(pts)
        rms = float(np.sqrt(np.mean((pts @ n - d) ** 2)))
        if rms > limits.planar_rel * float(np.median(pts[:, 2])):
            return False
    return True


def _redo(result: CalibrationResult) -> list[str]:
    """Why a fit may be poor, from the captures."""
    why = []
    decs = [p.decoded for p in result.run.poses]
    if any(d.saturated_fraction > 0.05 for d in decs):
        why.append("saturated captures (lower exposure_us in [calibrate])")
    if any(d.ambient_ratio > 0.35 for d in decs):
        why.append("ambient light (dim the room)")
    if result.run.retakes:
        why.append(f"the device moved during {result.run.retakes} capture(s) (rest it)")
    sol = result.projector
    if float(np.mean(sol.inliers)) < 0.9:
        why.append(
            f"{100 * (1 - float(np.mean(sol.inliers))):.0f} % of the pairs disagree "
            "(reflections between surfaces, shiny surfaces)"
        )
    return why


def judge(result: CalibrationResult, limits: Limits | None = None) -> Verdict:
    """The verdict (see the module's description)."""
    lim = limits or Limits()
    sol = result.projector
    n_poses = len(result.run.poses)
    reasons: list[str] = []
    if _planar(result, lim):
        reasons.append(
            "one plane only: every pose saw a single flat surface, so the solve rests on "
            "how the poses differ alone (no pose holds depth of its own) and the IMU's "
            "rotation on one plane normal per pose; aim at a wall corner, or a wall and the "
            "floor"
        )
    if n_poses < lim.min_poses:
        reasons.append(f"too few poses ({n_poses}; at least {lim.min_poses})")
    sg = sol.sigma
    loose = []
    if max(sg.get("fx", np.inf), sg.get("fy", np.inf)) > lim.max_sigma_focal:
        loose.append("focal length")
    if max(sg.get("cx", np.inf), sg.get("cy", np.inf)) > lim.max_sigma_centre_px:
        loose.append("principal point")
    if sg.get("rotation_deg", np.inf) > lim.max_sigma_rotation_deg:
        loose.append("T_P_D rotation")
    if sg.get("translation_mm", np.inf) > lim.max_sigma_translation_mm:
        loose.append("T_P_D translation")
    if loose:
        reasons.append(
            "the poses do not pin down the " + ", ".join(loose) + ": add poses at other "
            "distances and angles"
        )
    summary = (
        f"reprojection RMS {sol.rms_px:.2f} px over {int(sol.inliers.sum())} point pairs "
        f"from {n_poses} poses"
    )
    if reasons:
        return Verdict("refused", f"refused ({summary}): " + "; ".join(reasons), reasons)
    if sol.rms_px >= lim.acceptable_px:
        why = _redo(result) or ["check the projector's focus and that the scene is matte"]
        return Verdict("poor", f"poor ({summary}); redo the calibration: " + "; ".join(why), why)
    level = "good" if sol.rms_px < lim.good_px else "acceptable"
    notes = []
    imu = result.imu
    if not imu.measured:
        level = "acceptable"
        notes.append(f"R_P_I kept nominal: {imu.problem}")
    elif imu.sigma_deg > lim.max_sigma_imu_deg:
        level = "acceptable"
        notes.append(
            f"R_P_I measured to +-{imu.sigma_deg:.2f} deg only: turn the device more between "
            "poses, left/right and up/down"
        )
    line = f"{level}: {summary}" + ("; " + "; ".join(notes) if notes else "")
    return Verdict(level, line, notes)


def report_dict(result: CalibrationResult, verdict: Verdict) -> dict[str, Any]:
    """The JSON report."""
    sol, imu, cal = result.projector, result.imu, result.calibration
    depths = pose_depths(result.run)
    return {
        "verdict": verdict.level,
        "line": verdict.line,
        "reasons": verdict.reasons,
        "rms_px": round(sol.rms_px, 4),
        "pairs": len(sol.pairs),
        "inliers": int(sol.inliers.sum()),
        "distortion_used": sol.distortion_used,
        "sigma": {k: float(f"{v:.4g}") for k, v in sol.sigma.items()},
        "calibration": cal.to_dict(),
        "change_from_nominal": changes(cal, result.nominal),
        "imu": {
            "measured": imu.measured,
            "problem": imu.problem,
            "rms_deg": round(imu.rms_deg, 4),
            "plane_matches": imu.matches,
            "max_turn_deg": round(imu.max_turn_deg, 2),
            "sigma_deg": float(f"{imu.sigma_deg:.4g}"),
            "up_in_P": [round(float(v), 4) for v in imu.up],
        },
        "accel_offset": {
            "measured": result.accel.measured,
            "problem": result.accel.problem,
            "offset_mps2": [round(float(v), 5) for v in result.accel.offset],
            "gravity_mps2": round(result.accel.gravity, 4),
            "rms_mps2": round(result.accel.rms, 5),
            "sigma_across_mps2": float(f"{result.accel.sigma_across:.4g}"),
            "spread_deg": round(result.accel.spread_deg, 2),
        },
        "depth_range_m": [round(min(d[0] for d in depths), 3), round(max(d[2] for d in depths), 3)]
        if depths
        else None,
        "retakes": result.run.retakes,
        "plan": None if result.run.plan is None else result.run.plan.status,
        "poses": [
            {
                "pose": p.index + 1,
                "pairs": len(p.pairs),
                "depth_m": [round(v, 3) for v in d],
                "planes": len(p.normals),
                "lit_fraction": round(p.decoded.lit_fraction, 4),
                "cell_px": [p.decoded.cell_x, p.decoded.cell_y],
                "saturated": round(p.decoded.saturated_fraction, 4),
                "ambient_ratio": round(p.decoded.ambient_ratio, 4),
                "signal": round(p.decoded.signal, 1),
            }
            for p, d in zip(result.run.poses, depths, strict=True)
        ],
    }


_COLOURS = [(230, 160, 40), (60, 200, 60), (40, 160, 230), (200, 80, 200), (40, 220, 220),
            (160, 160, 255), (255, 200, 160), (120, 120, 120)]  # fmt: skip


def report_picture(
    result: CalibrationResult, verdict: Verdict, scale: float = 0.5, magnify: float = 20.0
) -> Image:
    """The picture (h, w, 3) BGR uint8: the verdict and a legend above, pairs and
    residuals over the projector frame (``scale`` of its size, residuals ``magnify``
    times), each pose's depth range below."""
    sol = result.projector
    p = result.calibration.projector
    w, h = round(p.width * scale), round(p.height * scale)
    strip = 90
    img = np.full((h + strip, w, 3), 24, np.uint8)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (90, 90, 90), 1)
    uv = sol.pairs.projector_uv * scale
    tip = uv + sol.residuals * scale * magnify
    for i in np.linspace(0, len(uv) - 1, min(len(uv), 4000)).round().astype(int):
        a = (round(uv[i, 0]), round(uv[i, 1]))
        if not sol.inliers[i]:
            cv2.drawMarker(img, a, (0, 0, 255), cv2.MARKER_TILTED_CROSS, 5, 1)
            continue
        colour = _COLOURS[int(sol.pairs.pose[i]) % len(_COLOURS)]
        b = (round(tip[i, 0]), round(tip[i, 1]))
        cv2.line(img, a, b, (200, 200, 200), 1, cv2.LINE_AA)
        cv2.circle(img, a, 1, colour, -1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    depths = pose_depths(result.run)
    if depths:
        lo = min(d[0] for d in depths) * 0.9
        hi = max(d[2] for d in depths) * 1.05
        for k, (d0, dm, d1) in enumerate(depths):
            y = h + 14 + k * max(1, (strip - 20) // max(len(depths), 1))
            x0, x1, xm = (int(40 + (v - lo) / (hi - lo) * (w - 60)) for v in (d0, d1, dm))
            colour = _COLOURS[k % len(_COLOURS)]
            cv2.line(img, (x0, y), (x1, y), colour, 3)
            cv2.circle(img, (xm, y), 3, (255, 255, 255), -1)
            cv2.putText(img, str(k + 1), (8, y + 4), font, 0.35, colour, 1)
        cv2.putText(
            img, f"depth {lo / 0.9:.2f} - {hi / 1.05:.2f} m", (w - 150, h + strip - 6), font, 0.35,
            (200, 200, 200), 1,
        )  # fmt: skip
    legend = [
        verdict.line,
        "The projector frame: a dot per point pair, coloured by its pose; grey line: its "
        f"residual, x{magnify:g}; red cross: an outlier.",
        "Below: each pose's depth, nearest to farthest (white dot: median), numbered in "
        "the order taken.",
    ]
    return titled(img, legend, 0.45)
