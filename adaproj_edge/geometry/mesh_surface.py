"""Triangle meshes as surfaces: OBJ/PLY reading and ray casting.

A :class:`MeshSurface` satisfies the ``AnalyticSurface`` protocol of
:mod:`adaproj_edge.geometry.analytic` (``intersect(origins, dirs)``), so a mesh can
stand wherever a built-in surface can; rays are cast through a BVH kept with the mesh
(a whole depth image is one call).
Mesh coordinates are metres in the frame the caller uses (the session simulator:
the projector frame at the start of the session).
"""

from __future__ import annotations

import logging
import os
import struct
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.extras import SIM, MissingExtraError
from adaproj_edge.fileio import read_input
from adaproj_edge.geometry.ray_triangle import intersect_brute_force

log = logging.getLogger(__name__)

MAX_TRIANGLES = 2_000_000

BRUTE_FORCE_PAIRS_PER_S = 2e6
"""Ray-triangle pairs the brute-force caster tests per second on one core (about)."""
MAX_BRUTE_FORCE_PAIRS = 20_000_000
"""The most rays x triangles one cast may test by brute force (about 10 s); a larger
cast without the BVH (the ``sim`` extra) is refused with a line naming the extra."""


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
        """Ray parameter t of the nearest hit with t > 0, NaN where none.

        Rays are cast through a BVH built on first use and kept with the mesh
        (:class:`~adaproj_edge.geometry.mesh_bvh.MeshBvh`, the ``sim`` extra); without
        it, every ray is tested against every triangle (the same results, slowly).

        Parameters
        ----------
        origins : (..., 3) float64
            Ray origins, broadcast against ``dirs``.
        dirs : (..., 3) float64
            Ray directions (any length: t is in multiples of it).

        Returns
        -------
        (...,) float64
            t of the nearest hit: the point is ``origin + t * dir``.
        """
        dirs = np.asarray(dirs, dtype=np.float64)
        shape = dirs.shape[:-1]
        o = np.ascontiguousarray(np.broadcast_to(origins, dirs.shape), np.float64).reshape(-1, 3)
        return self._cast(o, dirs.reshape(-1, 3)).reshape(shape)

    @cached_property
    def _cast(self) -> Callable[[FloatArray, FloatArray], FloatArray]:
        """The caster of this mesh: made once, on the first cast."""
        try:
            from adaproj_edge.geometry.mesh_bvh import MeshBvh

            return MeshBvh(self.vertices, self.faces).cast
        except Exception as e:  # no warp-lang, or it cannot run here: cast by brute force
            return _BruteForce(self, f"{type(e).__name__}: {e}")


class _BruteForce:
    """:func:`intersect_brute_force` on one mesh, for want of the BVH: a cast that would
    test more than :data:`MAX_BRUTE_FORCE_PAIRS` pairs is refused
    (:class:`MissingExtraError`, naming the ``sim`` extra); the first one done warns."""

    def __init__(self, mesh: MeshSurface, why: str) -> None:
        self.mesh = mesh
        self.why = why
        self.warned = False

    def __call__(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        faces = self.mesh.faces
        pairs = len(dirs) * len(faces)
        if pairs > MAX_BRUTE_FORCE_PAIRS:
            s = pairs / BRUTE_FORCE_PAIRS_PER_S
            took = (
                f"{s:.0f} s"
                if s < 120
                else f"{s / 60:.0f} min"
                if s < 7200
                else f"{s / 3600:.0f} h"
            )
            raise MissingExtraError(
                SIM,
                f"{len(dirs)} rays against {len(faces)} triangles by brute force would take "
                f"about {took}",
            )
        if not self.warned:
            self.warned = True
            log.warning(
                "mesh %s: no BVH ray caster (%s); testing every ray against all %d triangles "
                "instead, which is slow for large meshes: install the 'sim' extra "
                "(%s)",
                self.mesh.name,
                self.why,
                len(faces),
                SIM.install,
            )
        return intersect_brute_force(self.mesh.vertices, faces, origins, dirs)


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
    missing = [k for k in ("x", "y", "z") if k not in names]
    if missing:
        raise ValueError(
            f"its vertices have no {', '.join(missing)} (their properties: {', '.join(names)})"
        )
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
