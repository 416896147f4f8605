"""Triangle meshes as surfaces: OBJ/PLY reading, ray casting and depth rasterising.

A :class:`MeshSurface` satisfies the ``AnalyticSurface`` protocol of
:mod:`adaproj_edge.geometry.analytic` (``intersect(origins, dirs)``), so a mesh can
stand wherever a built-in surface can; :func:`rasterize_depth` renders a whole depth
image from a pinhole camera much faster than casting each ray.
Mesh coordinates are metres in the frame the caller uses (the session simulator:
the projector frame at the start of the session).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.fileio import read_input

MAX_TRIANGLES = 2_000_000


@dataclass(frozen=True)
class MeshSurface:
    """A triangle mesh: ``vertices`` (N, 3) float64 and ``faces`` (M, 3) int indices."""

    name: str
    vertices: FloatArray
    faces: NDArray[np.int64]
    developable: bool = False

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=np.float64)
        f = np.asarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise InputError(f"mesh {self.name}: vertices must be finite (N, 3)")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise InputError(f"mesh {self.name}: needs at least one triangle")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError(f"mesh {self.name}: a face refers to a vertex that does not exist")
        if len(f) > MAX_TRIANGLES:
            raise InputError(f"mesh {self.name}: more than {MAX_TRIANGLES} triangles")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (...,) of the nearest hit with t > 0, NaN where none.

        Moller-Trumbore against every triangle, a few rays at a time: fine for a
        few thousand rays (a warp grid), use :func:`rasterize_depth` for images.
        """
        shape = dirs.shape[:-1]
        o = np.broadcast_to(origins, dirs.shape).reshape(-1, 3)
        d = dirs.reshape(-1, 3)
        tri = self.vertices[self.faces]  # (M, 3, 3)
        v0 = tri[:, 0]
        e1 = tri[:, 1] - v0
        e2 = tri[:, 2] - v0
        out = np.full(len(d), np.nan)
        chunk = max(1, 500_000 // len(tri))
        for s in range(0, len(d), chunk):
            oo, dd = o[s : s + chunk, None, :], d[s : s + chunk, None, :]
            p = np.cross(dd, e2)
            det = np.sum(e1 * p, axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / det
                tv = oo - v0
                u = np.sum(tv * p, axis=-1) * inv
                q = np.cross(tv, e1)
                v = np.sum(dd * q, axis=-1) * inv
                t = np.sum(e2 * q, axis=-1) * inv
                ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
            t = np.where(ok, t, np.inf)
            best = t.min(axis=1)
            out[s : s + chunk] = np.where(np.isfinite(best), best, np.nan)
        return out.reshape(shape)


def rasterize_depth(
    mesh: MeshSurface, K: FloatArray, width: int, height: int, R_W_C: FloatArray, t_W_C: FloatArray
) -> FloatArray:
    """Z-buffer depth image (height, width) of ``mesh`` from a pinhole camera; NaN = none.

    The camera has intrinsics ``K`` (3, 3) and pose ``R_W_C`` (3, 3), ``t_W_C`` (3,)
    (camera -> mesh frame). Depth is exact for planar triangles: 1/z is affine in
    image coordinates, so it is interpolated as such.
    """
    pts = (mesh.vertices - t_W_C) @ R_W_C  # mesh frame -> camera frame
    z = pts[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (pts @ K.T)[:, :2] / z[:, None]
    zbuf = np.full((height, width), np.inf)
    near = 1e-3
    for f in mesh.faces:
        if np.any(z[f] <= near):
            continue  # triangles crossing the camera plane: not seen by a real camera
        p = uv[f]
        x0, y0 = np.maximum(np.floor(p.min(axis=0)).astype(int), 0)
        x1 = min(int(np.ceil(p[:, 0].max())), width - 1)
        y1 = min(int(np.ceil(p[:, 1].max())), height - 1)
        if x0 > x1 or y0 > y1:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
        (a, b), (c, d) = p[1] - p[0], p[2] - p[0]
        den = a * d - b * c
        if abs(den) < 1e-12:
            continue
        px, py = xs - p[0, 0], ys - p[0, 1]
        l1 = (px * d - py * c) / den
        l2 = (a * py - b * px) / den
        inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 <= 1)
        if not inside.any():
            continue
        iz = (1 - l1 - l2) / z[f[0]] + l1 / z[f[1]] + l2 / z[f[2]]
        depth = np.where(inside, 1.0 / iz, np.inf)
        win = zbuf[y0 : y1 + 1, x0 : x1 + 1]
        np.minimum(win, depth, out=win)
    zbuf[~np.isfinite(zbuf)] = np.nan
    return zbuf


# ---------------------------------------------------------------------------- files
def load_mesh(path: str | os.PathLike[str]) -> MeshSurface:
    """Read a triangle mesh from ``.obj`` or ``.ply`` (ASCII or binary little-endian)."""
    path = Path(path)
    raw = read_input(path, "mesh file")
    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            v, f = _parse_obj(raw.decode("utf-8", errors="replace"))
        elif suffix == ".ply":
            v, f = _parse_ply(raw)
        else:
            raise InputError(f"mesh {path}: only .obj and .ply files are read")
    except (ValueError, IndexError, struct.error) as e:
        raise InputError(f"mesh {path} is malformed: {e}") from None
    return MeshSurface(path.stem, v, f)


def _fan(poly: list[int]) -> list[tuple[int, int, int]]:
    return [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]


def _parse_obj(text: str) -> tuple[FloatArray, NDArray[np.int64]]:
    verts: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    for line in text.splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]  # OBJ: 1-based, or relative
            faces += _fan(idx)
    return np.asarray(verts, float).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3)


_PLY_TYPES = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
    "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
    "float": "f", "float32": "f", "double": "d", "float64": "d",
}  # fmt: skip


def _parse_ply(raw: bytes) -> tuple[FloatArray, NDArray[np.int64]]:
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise ValueError("no PLY header")
    body_start = raw.index(b"\n", end) + 1
    header = raw[:end].decode("ascii").splitlines()
    fmt = ""
    elements: list[tuple[str, int, list[list[str]]]] = []
    for line in header:
        p = line.split()
        if not p:
            continue
        if p[0] == "format":
            fmt = p[1]
        elif p[0] == "element":
            elements.append((p[1], int(p[2]), []))
        elif p[0] == "property" and elements:
            elements[-1][2].append(p[1:])
    if fmt not in ("ascii", "binary_little_endian"):
        raise ValueError(f"PLY format {fmt!r} is not read (ascii, binary_little_endian)")
    verts: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    if fmt == "ascii":
        tokens = raw[body_start:].decode("ascii").split()
        pos = 0
        for name, count, props in elements:
            for _ in range(count):
                values: list[float] = []
                for prop in props:
                    if prop[0] == "list":
                        n = int(tokens[pos])
                        values.extend(float(t) for t in tokens[pos + 1 : pos + 1 + n])
                        pos += 1 + n
                        if name == "face":
                            faces += _fan([int(x) for x in values[-n:]])
                    else:
                        values.append(float(tokens[pos]))
                        pos += 1
                if name == "vertex":
                    verts.append(_xyz(props, values))
    else:
        pos = body_start
        for name, count, props in elements:
            for _ in range(count):
                values = []
                for prop in props:
                    if prop[0] == "list":
                        (n,) = struct.unpack_from("<" + _PLY_TYPES[prop[1]], raw, pos)
                        pos += struct.calcsize(_PLY_TYPES[prop[1]])
                        item = "<" + _PLY_TYPES[prop[2]] * n
                        idx = struct.unpack_from(item, raw, pos)
                        pos += struct.calcsize(item)
                        if name == "face":
                            faces += _fan([int(x) for x in idx])
                    else:
                        (val,) = struct.unpack_from("<" + _PLY_TYPES[prop[0]], raw, pos)
                        pos += struct.calcsize(_PLY_TYPES[prop[0]])
                        values.append(float(val))
                if name == "vertex":
                    verts.append(_xyz(props, values))
    return np.asarray(verts, float).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3)


def _xyz(props: list[list[str]], values: list[float]) -> list[float]:
    names = [p[-1] for p in props if p[0] != "list"]
    return [values[names.index(k)] for k in ("x", "y", "z")]


def ply_bytes(mesh: MeshSurface) -> bytes:
    """``mesh`` as a binary little-endian PLY file."""
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(mesh.vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(mesh.faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    body = mesh.vertices.astype("<f4").tobytes()
    faces = np.empty(len(mesh.faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    faces["n"] = 3
    faces["i"] = mesh.faces
    return head + body + faces.tobytes()


def uv_sphere(
    centre: tuple[float, float, float], radius: float, n_lat: int = 24, n_lon: int = 48
) -> MeshSurface:
    """A closed UV-sphere mesh (for tests and example meshes)."""
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    v = np.stack([np.sin(la) * np.cos(lo), np.cos(la), np.sin(la) * np.sin(lo)], axis=-1)
    v = v.reshape(-1, 3) * radius + np.asarray(centre)
    faces = []
    for i in range(n_lat):
        for j in range(n_lon):
            a, b = i * n_lon + j, i * n_lon + (j + 1) % n_lon
            c, d = a + n_lon, b + n_lon
            faces += [(a, c, b), (b, c, d)]
    return MeshSurface("uv-sphere", v, np.asarray(faces))
