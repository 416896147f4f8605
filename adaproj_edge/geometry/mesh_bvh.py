"""Nearest-hit ray casting through a BVH, on NVIDIA Warp's CPU backend (``warp-lang``).

(NVIDIA Warp, the ``warp`` package, is unrelated to :mod:`adaproj_edge.warp`, the
image warp.) Warp builds a SAH bounding-volume hierarchy over the triangles once
(:class:`MeshBvh`) and walks it per ray in a compiled kernel, serially on the
calling thread (one core). Warp works in float32: it finds which triangle each ray
hits first, and the hit's ray parameter is then recomputed in float64 on that
triangle (:func:`~adaproj_edge.geometry.ray_triangle.ray_triangle`), so the results
are those of the brute-force caster up to float64 rounding, except where a ray
grazes an edge or meets two triangles at the same distance within float32 reach
(either answer is right there). Rays the float64 test rejects on the chosen
triangle (parallel to it, or hitting at t <= 0: an origin on the surface) are cast
again by brute force, so "nearest hit with t > 0" holds; a ray that misses while
crossing the mesh's bounding box is looked at again from a hair to the side, since
one through a vertex can slip past the float32 boxes (a hole in a closed mesh).

This module imports ``warp`` (the ``sim`` extra): import it only through
:class:`~adaproj_edge.geometry.mesh_surface.MeshSurface`, which falls back to brute
force without it. The kernel is compiled on first use on a machine (about 10 s) and
cached by Warp in its kernel cache.
"""

import contextlib
import functools
import logging
import os
import sys
import tempfile
from collections.abc import Iterator

import numpy as np
import warp as wp
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.ray_triangle import (
    MIN_DET,
    MIN_T,
    intersect_brute_force,
    ray_triangle,
    triangle_edges,
)

log = logging.getLogger(__name__)

SIDESTEP = 1e-6
"""How far (relative to the origin's coordinates) a missed ray is shifted to look again."""
ON_EDGE = 1e-9
"""Barycentric slack: a ray this close outside a triangle's edge still hits it."""

wp.set_module_options({"enable_backward": False})  # no gradients: half the compile time


@wp.kernel  # type: ignore[untyped-decorator]  # warp is Any to mypy (pyproject)
def _nearest_hits(
    mesh: wp.uint64,
    origins: wp.array[wp.vec3],
    dirs: wp.array[wp.vec3],
    faces: wp.array[wp.int32],
) -> None:
    i = wp.tid()
    hit = wp.mesh_query_ray(mesh, origins[i], dirs[i], 3.0e38)
    if hit.result:
        faces[i] = hit.face
    else:
        faces[i] = -1


@contextlib.contextmanager
def _native_stderr_to_log() -> Iterator[None]:
    """Send what native code writes on fd 2 to the log (debug) instead of the terminal.

    Warp's native initialisation prints a CUDA warning on machines without an NVIDIA
    driver; the CPU backend is all this caster uses.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            text = tmp.read().decode("utf-8", errors="replace").strip()
            if text:
                log.debug("warp: %s", text)


@functools.cache
def _ready() -> None:
    """Initialise Warp quietly and load (first time on a machine: compile) the kernel."""
    wp.config.log_level = wp.LOG_WARNING
    with _native_stderr_to_log():
        wp.init()
    log.info("loading the mesh ray-casting kernel (compiled on first use on a machine, ~10 s)")
    wp.load_module(sys.modules[__name__], device="cpu")


class MeshBvh:
    """A triangle mesh with its BVH, ready to cast rays (build once, cast many).

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices.
    faces : (M, 3) int64
        Vertex indices of each triangle.
    """

    def __init__(self, vertices: FloatArray, faces: NDArray[np.int64]) -> None:
        _ready()
        self.vertices = vertices
        self.faces = faces
        self._v0, self._e1, self._e2 = triangle_edges(vertices, faces)
        self._points = wp.array(vertices.astype(np.float32), dtype=wp.vec3, device="cpu")
        self._indices = wp.array(faces.astype(np.int32).ravel(), dtype=wp.int32, device="cpu")
        self._mesh = wp.Mesh(points=self._points, indices=self._indices, bvh_constructor="sah")
        pad = 1e-6 * (1.0 + float(np.abs(vertices).max()))
        self._lower = vertices.min(axis=0) - pad
        self._upper = vertices.max(axis=0) + pad

    def cast(self, origins: FloatArray, dirs: FloatArray) -> FloatArray:
        """Ray parameter t (N,) of the nearest hit with t > 0 of each ray, NaN where none.

        Parameters
        ----------
        origins, dirs : (N, 3) float64
            Ray origins and directions (any length: t is in multiples of it).

        Returns
        -------
        (N,) float64
            t of the nearest hit (the point is ``origin + t * dir``), NaN for none.
        """
        ok = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(dirs), axis=1)
        ok &= np.any(dirs != 0, axis=1)
        face = np.full(len(dirs), -1, np.int64)
        face[ok] = self._faces_hit(origins[ok], dirs[ok])
        # A ray through a vertex can slip past Warp's float32 bounding boxes: look
        # again from a hair to the side, and keep what the ray itself hits in float64.
        again = np.flatnonzero(ok & (face < 0) & self._meets_bounds(origins, dirs))
        if len(again):
            o, d = origins[again], dirs[again]
            side = np.cross(d, np.eye(3)[np.argmin(np.abs(d), axis=1)])  # normal to d
            with np.errstate(all="ignore"):  # a tiny d: a NaN side, which misses
                step = SIDESTEP * (1.0 + np.abs(o).max(axis=1)) / np.linalg.norm(side, axis=1)
            f = self._faces_hit(o + side * step[:, None], d)
            _, u, v, _ = ray_triangle(o, d, self._v0[f], self._e1[f], self._e2[f])
            with np.errstate(invalid="ignore"):
                inside = np.minimum(np.minimum(u, v), 1 - u - v) >= -ON_EDGE
            face[again] = np.where((f >= 0) & inside, f, -1)
        return self._distances(origins, dirs, face)

    def _faces_hit(self, origins: FloatArray, dirs: FloatArray) -> NDArray[np.int64]:
        """Index of the triangle each ray hits first (Warp, float32), -1 for none."""
        n = len(dirs)
        if n == 0:
            return np.zeros(0, np.int64)
        o32 = wp.array(origins.astype(np.float32), dtype=wp.vec3, device="cpu")
        d32 = wp.array(dirs.astype(np.float32), dtype=wp.vec3, device="cpu")
        f32 = wp.empty(n, dtype=wp.int32, device="cpu")
        wp.launch(_nearest_hits, dim=n, inputs=[self._mesh.id, o32, d32, f32], device="cpu")
        return f32.numpy().astype(np.int64)  # type: ignore[no-any-return]

    def _meets_bounds(self, origins: FloatArray, dirs: FloatArray) -> NDArray[np.bool_]:
        """Which rays meet the mesh's bounding box (slightly grown), float64 slab test."""
        with np.errstate(all="ignore"):  # axis-parallel rays: +-inf or NaN, handled
            t0 = (self._lower - origins) / dirs
            t1 = (self._upper - origins) / dirs
            near = np.fmax.reduce(np.fmin(t0, t1), axis=1)
            far = np.fmin.reduce(np.fmax(t0, t1), axis=1)
            meets: NDArray[np.bool_] = far >= np.maximum(near, 0.0)
        return meets

    def _distances(
        self, origins: FloatArray, dirs: FloatArray, face: NDArray[np.int64]
    ) -> FloatArray:
        """Float64 t of each ray on its hit triangle (``face`` >= 0), NaN for none."""
        out = np.full(len(dirs), np.nan)
        hit = np.flatnonzero(face >= 0)
        f = face[hit]
        t, _, _, det = ray_triangle(origins[hit], dirs[hit], self._v0[f], self._e1[f], self._e2[f])
        good = (np.abs(det) > MIN_DET) & (t > MIN_T)
        out[hit[good]] = t[good]
        bad = hit[~good]  # parallel in float64, or at/behind the origin: by brute force
        if len(bad):
            out[bad] = intersect_brute_force(self.vertices, self.faces, origins[bad], dirs[bad])
        return out
