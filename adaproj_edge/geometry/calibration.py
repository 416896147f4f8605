"""Device calibration: projector intrinsics, depth camera model, depth -> projector and
IMU -> projector transforms.

The file format (``hw/calibration/<board>.toml``, and the JSON attachment
``calibration.json`` of every session) holds the same fields::

    format = "adaproj-calibration/1"
    [projector]            # frame P, OpenCV convention, pixel centres at integers
    width = 1280
    height = 800
    K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    distortion = [k1, k2, p1, p2, k3]   # optional: lens distortion, OpenCV's model and
                                        # order; absent (all zero) for a pinhole
    vignetting = [a1, a2]   # optional: the lens's relative illumination
                            # 1 + a1 r^2 + a2 r^4 (r: normalised radius, the tangent of
                            # the angle off the axis); absent (all zero): none
    [depth]                # frame D, the depth-aligned OAK-D camera (read from the
    width = 640            # device on the board; stored in sessions)
    height = 400
    K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    baseline_m = 0.075     # stereo baseline, sets the depth noise model
    [extrinsics]
    T_P_D = [[...], [...], [...], [0, 0, 0, 1]]   # 4x4, maps points in D to P, metres
    R_P_I = [[...], [...], [...]]                 # 3x3, rotates IMU vectors into P
    [imu]                  # optional: written by `adaproj calibrate`
    accel_offset = [bx, by, bz]   # the accelerometer's zero-g offset in frame I, m/s^2
                                  # (subtracted from every reading); absent: zero
    [quality]              # optional: written by `adaproj calibrate` (how good the
    rms_px = 0.31          # solve was; a file without it is a nominal guess)
    verdict = "good"
    ...

Files without ``distortion``, ``vignetting``, ``[imu]`` or ``[quality]`` (every nominal
file) load as before; :meth:`Calibration.to_toml` writes the file, :meth:`Calibration.to_dict`
the JSON of session attachments (``distortion``, ``vignetting`` and ``[imu]`` only when not
zero, ``quality`` only when set).
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from adaproj_edge import checks
from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import read_input
from adaproj_edge.geometry.irradiance import MAX_COEFFICIENT, Vignetting
from adaproj_edge.geometry.projector import Projector

FORMAT = "adaproj-calibration/1"
MAX_SIDE = 16384
"""Pixels a side of the projector's or the depth camera's image, at most."""
BASELINE = (0.0, 1.0)
"""The stereo baseline's range, metres (above 0)."""
ACCEL_OFFSET = (-2.0, 2.0)
"""The accelerometer offset's range per axis, m/s^2 (an LSM6DSOX's is within 0.2)."""


@dataclass(frozen=True)
class DepthCameraModel:
    """Pinhole model of the depth camera D.

    Parameters
    ----------
    K : (3, 3) float array
        Intrinsics at ``width`` x ``height``.
    width, height : int
        Depth image size in pixels.
    baseline_m : float
        Stereo baseline in metres (sets the disparity <-> depth relation).
    """

    K: FloatArray
    width: int = 640
    height: int = 400
    baseline_m: float = 0.075

    def __post_init__(self) -> None:
        K = _matrix(self.K, (3, 3), "depth K")
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError("depth intrinsics must have positive focal lengths")
        checks.integer(self.width, "depth width", 2, MAX_SIDE)
        checks.integer(self.height, "depth height", 2, MAX_SIDE)
        checks.number(self.baseline_m, "depth baseline_m", *BASELINE, above=True)
        object.__setattr__(self, "K", K)

    @classmethod
    def oak_d(cls, width: int = 640, height: int = 400) -> DepthCameraModel:
        """Nominal OAK-D mono camera (OV9282, ~72 deg horizontal FOV, 7.5 cm baseline)."""
        f = 0.689 * width
        K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
        return cls(K=K, width=width, height=height, baseline_m=0.075)

    @property
    def focal(self) -> float:
        """Focal length fx in pixels."""
        return float(self.K[0, 0])

    def intrinsics_at(self, width: int, height: int) -> FloatArray:
        """Intrinsics (3, 3) of the camera depth is aligned to, at ``width`` x ``height``:
        the same optical centre with pixels scaled (pixel centres at integers in both)."""
        sx, sy = width / self.width, height / self.height
        K = self.K
        out = np.eye(3)
        out[0, 0], out[0, 1], out[1, 1] = K[0, 0] * sx, K[0, 1] * sx, K[1, 1] * sy
        out[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        out[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        return out


@dataclass(frozen=True)
class Calibration:
    """Everything needed to turn a depth frame into a Surface in frame P.

    Parameters
    ----------
    projector : Projector
    depth : DepthCameraModel
    T_P_D : (4, 4) float array
        Rigid transform mapping points in D to P.
    R_P_I : (3, 3) float array
        Rotation taking IMU-frame vectors to P.
    distortion : (5,) float array, optional
        The projector lens's distortion (k1, k2, p1, p2, k3); zeros: a pinhole.
    quality : dict, optional
        How the calibration was solved (``adaproj calibrate``): RMS, verdict, ...;
        None for a nominal file.
    vignetting : Vignetting, optional
        The projector lens's relative illumination; the default: none.
    accel_offset : (3,) float array, optional
        The accelerometer's zero-g offset in frame I, m/s^2: what it reads beyond the
        specific force (subtracted from every reading); zeros when not measured.
    """

    projector: Projector
    depth: DepthCameraModel
    T_P_D: FloatArray
    R_P_I: FloatArray
    distortion: FloatArray = field(default_factory=lambda: np.zeros(5))
    quality: dict[str, Any] | None = None
    vignetting: Vignetting = field(default_factory=Vignetting)
    accel_offset: FloatArray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        b = np.asarray(self.accel_offset, dtype=np.float64).ravel()
        if b.size != 3:
            raise InputError(f"[imu] accel_offset must be 3 numbers, got {b.size}")
        for k, x in enumerate(b.tolist()):
            checks.number(x, f"[imu] accel_offset[{k}]", *ACCEL_OFFSET)
        object.__setattr__(self, "accel_offset", b)
        dist = np.zeros(5)
        d = np.asarray(self.distortion, dtype=np.float64).ravel()
        if d.size > 5 or not np.all(np.isfinite(d)) or np.any(np.abs(d) > 10):
            raise InputError("projector distortion must be up to 5 finite coefficients")
        dist[: d.size] = d
        object.__setattr__(self, "distortion", dist)
        T = _matrix(self.T_P_D, (4, 4), "T_P_D")
        if not np.allclose(T[3], [0, 0, 0, 1]) or not _is_rotation(T[:3, :3]):
            raise InputError("T_P_D must be a rigid 4x4 transform (rotation + translation)")
        R = _matrix(self.R_P_I, (3, 3), "R_P_I")
        if not _is_rotation(R):
            raise InputError("R_P_I must be a rotation matrix")
        object.__setattr__(self, "T_P_D", T)
        object.__setattr__(self, "R_P_I", R)
        self.vignetting.check(self.projector)

    @classmethod
    def default(cls) -> Calibration:
        """The reference board: OAK-D 4 cm above the projector lens, axes parallel."""
        T = np.eye(4)
        T[:3, 3] = [0.012, -0.04, 0.005]
        return cls(Projector.default(), DepthCameraModel.oak_d(), T, np.eye(3))

    def with_depth(self, depth: DepthCameraModel) -> Calibration:
        """A copy whose depth model is ``depth`` (e.g. read from the camera itself)."""
        return replace(self, depth=depth)

    # ------------------------------------------------------------------ formats
    def to_dict(self) -> dict[str, Any]:
        """The calibration as the JSON object of session attachments (``distortion`` and
        ``imu`` only when not zero, ``quality`` only when set).
        """
        p, d = self.projector, self.depth
        projector: dict[str, Any] = {"width": p.width, "height": p.height, "K": p.K.tolist()}
        if np.any(self.distortion):
            projector["distortion"] = self.distortion.tolist()
        if not self.vignetting.none:
            projector["vignetting"] = list(self.vignetting.coefficients)
        out: dict[str, Any] = {
            "format": FORMAT,
            "projector": projector,
            "depth": {
                "width": d.width,
                "height": d.height,
                "K": d.K.tolist(),
                "baseline_m": d.baseline_m,
            },
            "extrinsics": {"T_P_D": self.T_P_D.tolist(), "R_P_I": self.R_P_I.tolist()},
        }
        if np.any(self.accel_offset):
            out["imu"] = {"accel_offset": self.accel_offset.tolist()}
        if self.quality is not None:
            out["quality"] = dict(self.quality)
        return out

    def to_toml(self, comment: str = "") -> str:
        """The calibration as a TOML file (the format above); ``comment`` lines first."""
        lines = [f"# {c}".rstrip() for c in comment.splitlines()]
        data = self.to_dict()
        lines.append(f"format = {_toml_value(data.pop('format'))}")
        for table, values in data.items():
            lines += ["", f"[{table}]"]
            lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()]
        return "\n".join(lines) + "\n"

    def to_json(self) -> str:
        """The calibration as JSON text (:meth:`to_dict`)."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, data: dict[str, Any], what: str = "calibration") -> Calibration:
        """Validate and build; every problem is an :class:`InputError` naming ``what``."""
        if data.get("format") != FORMAT:
            raise InputError(f"{what}: format must be {FORMAT!r}, got {data.get('format')!r}")
        with field_errors(what):
            known = {"format", "projector", "depth", "extrinsics", "imu", "quality"}
            unknown = set(data) - known
            if unknown:
                raise InputError(f"unknown keys {sorted(map(str, unknown))}")
            pj, ex = _table(data, "projector"), _table(data, "extrinsics")
            projector = Projector(
                np.asarray(pj["K"], float),
                checks.integer(pj["width"], "[projector] width", 2, MAX_SIDE),
                checks.integer(pj["height"], "[projector] height", 2, MAX_SIDE),
            )
            if "depth" in data:
                dp = _table(data, "depth")
                depth = DepthCameraModel(
                    np.asarray(dp["K"], float),
                    checks.integer(dp["width"], "[depth] width", 2, MAX_SIDE),
                    checks.integer(dp["height"], "[depth] height", 2, MAX_SIDE),
                    checks.number(
                        dp.get("baseline_m", 0.075), "[depth] baseline_m", *BASELINE, above=True
                    ),
                )
            else:
                depth = DepthCameraModel.oak_d()
            T, R = np.asarray(ex["T_P_D"], float), np.asarray(ex["R_P_I"], float)
            dist = np.asarray(pj.get("distortion", np.zeros(5)), float)
            quality = data.get("quality")
            if quality is not None and not isinstance(quality, dict):
                raise InputError("[quality] must be a table")
            vignetting = Vignetting(
                checks.number_list(
                    pj.get("vignetting", []),
                    "[projector] vignetting",
                    -MAX_COEFFICIENT,
                    MAX_COEFFICIENT,
                    2,
                )
            )
            offset = np.zeros(3)
            if "imu" in data:
                imu = _table(data, "imu")
                extra = set(imu) - {"accel_offset"}
                if extra:
                    raise InputError(f"[imu]: unknown keys {sorted(map(str, extra))}")
                offset = _offset(imu.get("accel_offset", [0.0, 0.0, 0.0]))
            return cls(projector, depth, T, R, dist, quality, vignetting, offset)

    @classmethod
    def from_json(cls, text: str | bytes, what: str = "calibration") -> Calibration:
        """Parse JSON text into a calibration; every problem is an :class:`InputError` naming
        ``what``.
        """
        try:
            data = json.loads(text)
        except (ValueError, UnicodeDecodeError) as e:
            raise InputError(f"{what} is not valid JSON: {e}") from None
        except RecursionError:
            raise InputError(f"{what}: values nested too deeply") from None
        if not isinstance(data, dict):
            raise InputError(f"{what} must be a JSON object")
        return cls.from_dict(data, what)

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration TOML (``hw/calibration/*.toml``) or JSON file."""
        path = Path(path)
        raw = read_input(path, "calibration file")
        if path.suffix == ".json":
            return cls.from_json(raw, str(path))
        try:
            data = tomllib.loads(raw.decode("utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise InputError(f"calibration file {path} is not valid TOML: {e}") from None
        except RecursionError:
            raise InputError(f"calibration file {path}: values nested too deeply") from None
        return cls.from_dict(data, str(path))


def _offset(value: Any) -> FloatArray:
    """``[imu] accel_offset``: a list of three numbers in :data:`ACCEL_OFFSET`."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise InputError(f"[imu] accel_offset must be a list of 3 numbers, got {value!r:.40}")
    return np.array(
        [checks.number(x, f"[imu] accel_offset[{k}]", *ACCEL_OFFSET) for k, x in enumerate(value)]
    )


def _table(data: dict[str, Any], name: str) -> dict[str, Any]:
    table = data[name]
    if not isinstance(table, dict):
        raise InputError(f"[{name}] must be a table, got {type(table).__name__}")
    return table


@contextmanager
def field_errors(what: str) -> Iterator[None]:
    """Turn a missing key or malformed value while parsing ``what`` into an InputError."""
    try:
        yield
    except KeyError as e:
        raise InputError(f"{what}: missing field {e.args[0]!r}") from None
    except (TypeError, ValueError) as e:
        raise InputError(f"{what}: malformed value ({e})") from None
    except RecursionError:
        raise InputError(f"{what}: values nested too deeply") from None
    except InputError as e:
        raise InputError(f"{what}: {e}") from None


def _toml_value(v: Any) -> str:
    """A TOML value: strings, booleans, finite numbers and (nested) lists of them."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, int | float | np.integer | np.floating):
        x = float(v) if isinstance(v, float | np.floating) else int(v)
        if isinstance(x, float) and not np.isfinite(x):
            raise InputError(f"cannot write {x} to a calibration file")
        return repr(x)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise InputError(f"cannot write {type(v).__name__} to a calibration file")


def _matrix(a: Any, shape: tuple[int, int], what: str) -> FloatArray:
    m = np.asarray(a, dtype=np.float64)
    if m.shape != shape or not np.all(np.isfinite(m)):
        raise InputError(f"{what} must be a finite {shape[0]}x{shape[1]} matrix, got {m.shape}")
    return m


def _is_rotation(R: FloatArray) -> bool:
    return bool(np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0)
