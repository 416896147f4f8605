"""Writing a calibration, and the entry point that makes one on the device.

:func:`write_outputs` writes ``OUT.toml`` (the calibration, its ``[quality]`` table
saying how it was solved), ``OUT.report.json`` and ``OUT.report.png`` beside it,
each atomically (temporary file, fsync, rename), and with the surface's colour
measured (``photometric``) ``OUT.photometric.npz``. Nothing is written for a verdict
that is not good enough, and an existing calibration is never replaced by a worse
one (a lower verdict, or the same verdict with a larger RMS) unless forced.

:func:`calibrate` is the whole thing on a set of devices — the procedure, the solve,
the verdict, the files — for ``adaproj calibrate`` and for the runtime's "hold the
button 5 s" gesture.
"""

from __future__ import annotations

import json
import logging
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import cv2

from adaproj_edge.errors import CalibrationError
from adaproj_edge.fileio import atomic_write_bytes
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.camera import CameraSettings
from adaproj_edge.procam.photometric import Measured, photometric_path, surface_distance
from adaproj_edge.procam.procedure import Devices, Listener, ProcedureSettings, capture_poses
from adaproj_edge.procam.report import LEVELS, Verdict, judge, report_dict, report_picture
from adaproj_edge.procam.result import CalibrationResult, solve_capture
from adaproj_edge.procam.solve import SolveSettings

log = logging.getLogger(__name__)


def report_paths(out: Path) -> tuple[Path, Path]:
    """The JSON and PNG report files of calibration file ``out``."""
    stem = out.with_suffix("")
    return stem.with_name(stem.name + ".report.json"), stem.with_name(stem.name + ".report.png")


def existing_quality(path: Path) -> tuple[str, float] | None:
    """(verdict, RMS) of the calibration already at ``path``; None when there is none
    or it holds no solve (a nominal file)."""
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    q = data.get("quality")
    if not isinstance(q, dict) or q.get("verdict") not in LEVELS:
        return None
    try:
        return str(q["verdict"]), float(q["rms_px"])
    except (KeyError, TypeError, ValueError):
        return None


def is_worse(verdict: Verdict, rms: float, old: tuple[str, float]) -> bool:
    """Whether (``verdict``, ``rms``) is worse than the existing ``old``."""
    new_rank, old_rank = LEVELS.index(verdict.level), LEVELS.index(old[0])
    return new_rank < old_rank or (new_rank == old_rank and rms > old[1])


def with_quality(result: CalibrationResult, verdict: Verdict) -> Calibration:
    """The result's calibration with its ``[quality]`` table."""
    sol = result.projector
    quality = {
        "verdict": verdict.level,
        "rms_px": round(sol.rms_px, 4),
        "pairs": int(sol.inliers.sum()),
        "poses": len(result.run.poses),
        "distortion": sol.distortion_used,
        "imu_measured": result.imu.measured,
    }
    return replace(result.calibration, quality=quality)


def write_outputs(
    result: CalibrationResult, verdict: Verdict, out: str | Path, force: bool = False
) -> list[Path]:
    """Write the reports, and the calibration when the verdict allows; the files
    written. Raises :class:`CalibrationError` when the calibration was not written
    (a verdict not good enough, or a better calibration already at ``out``)."""
    out = Path(out)
    json_path, png_path = report_paths(out)
    report = report_dict(result, verdict)
    written = [json_path, png_path]
    _write(json_path, (json.dumps(report, indent=1) + "\n").encode())
    ok, png = cv2.imencode(".png", report_picture(result, verdict))
    if ok:
        _write(png_path, png.tobytes())
    if not verdict.writable:
        raise CalibrationError(f"{verdict.line}; no calibration written (report: {json_path})")
    old = existing_quality(out)
    if old is not None and not force and is_worse(verdict, result.projector.rms_px, old):
        raise CalibrationError(
            f"{out} holds a better calibration ({old[0]}, {old[1]:.2f} px) than this one "
            f"({verdict.level}, {result.projector.rms_px:.2f} px); not replaced (--force "
            "replaces it)"
        )
    cal = with_quality(result, verdict)
    comment = (
        "Calibration written by `adaproj calibrate` (format: "
        "adaproj_edge/geometry/calibration.py).\n" + verdict.line
    )
    _write(out, cal.to_toml(comment).encode())
    written.insert(0, out)
    return written


def _write(path: Path, data: bytes) -> None:
    """Atomically, with a clear error when the place cannot be written."""
    try:
        atomic_write_bytes(path, data)
    except OSError as e:
        raise CalibrationError(f"cannot write {path}: {e.strerror or e}") from None


@dataclass(frozen=True)
class Outcome:
    """What :func:`calibrate` did: the result, its verdict, the files written and,
    when the calibration was not written, why."""

    result: CalibrationResult
    verdict: Verdict
    written: list[Path]
    refused: str = ""


def calibrate(
    devices: Devices,
    camera: CameraSettings,
    nominal: Calibration,
    out: str | Path,
    listener: Listener,
    force: bool = False,
    procedure: ProcedureSettings | None = None,
    solve: SolveSettings | None = None,
) -> Outcome:
    """Capture, solve, judge and write (see the module's description).

    Raises
    ------
    CalibrationError
        The captures cannot give a calibration (the message says what to redo).
    """
    p = nominal.projector
    run = capture_poses(devices, camera, listener, procedure, (p.width, p.height), nominal.R_P_I)
    result = solve_capture(run, nominal, solve)
    verdict = judge(result)
    try:
        written = write_outputs(result, verdict, out, force)
        refused = ""
    except CalibrationError as e:
        written = [q for q in report_paths(Path(out)) if q.exists()]
        refused = str(e)
    if run.response is not None and not refused:
        # the first pose's surface, with its distance from the solved projector
        where = photometric_path(Path(out))
        first = run.poses[0]
        dist = surface_distance(
            first.depth_m,
            run.camera_K,
            result.calibration.T_P_D,
            first.decoded,
            (p.width, p.height),
        )
        try:
            Measured(run.response, dist, (p.width, p.height)).save(where)
        except OSError as e:
            raise CalibrationError(f"cannot write {where}: {e.strerror or e}") from None
        written.append(where)
    listener.say("result", verdict.line)
    return Outcome(result, verdict, written, refused)
