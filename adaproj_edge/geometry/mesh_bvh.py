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
from typing import Any

import numpy as np
import warp as wp
from numpy.typing import NDArray

from adaproj_edge.arrays import FloatArray
from adaproj_edge.geometry.ray_triangle import (
    MIN_DET,
    MIN_T,
    intersect_brute_force,
    triangle_edges,
)

log = logging.getLogger(__name__)

SIDESTEP = 1e-6
"""How far (relative to the origin's coordinates) a missed ray is shifted to look again."""
ON_EDGE = 1e-9
"""Barycentric slack: a ray this close outside a triangle's edge still hits it."""

MISS, HIT, BRUTE = 0, 1, 2
"""What the kernel says of each ray: no hit; ``t`` is the hit; cast it by brute force."""

# no gradients (half the compile time); no fused multiply-add: the float64 arithmetic
# is then numpy's, operation for operation (ray_triangle.ray_triangle)
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.func  # type: ignore[untyped-decorator]  # warp is Any to mypy (pyproject)
def _sidestep(o: wp.vec3d, d: wp.vec3d, step: wp.float64) -> wp.vec3d:
    """``o`` moved by ``step`` (relative to its size) at right angles to ``d``."""
    ax = wp.abs(d[0])
    ay = wp.abs(d[1])
    az = wp.abs(d[2])
    axis = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(1.0))
    if ax <= ay and ax <= az:
        axis = wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0))
    elif ay <= az:
        axis = wp.vec3d(wp.float64(0.0), wp.float64(1.0), wp.float64(0.0))
    side = wp.cross(d, axis)
    size = wp.max(wp.max(wp.abs(o[0]), wp.abs(o[1])), wp.abs(o[2]))
    return o + side * (step * (wp.float64(1.0) + size) / wp.length(side))


@wp.kernel  # type: ignore[untyped-decorator]
def _nearest_hits(
    mesh: wp.uint64,
    origins: wp.array[wp.vec3d],
    dirs: wp.array[wp.vec3d],
    v0: wp.array[wp.vec3d],
    e1: wp.array[wp.vec3d],
    e2: wp.array[wp.vec3d],
    sidestep: wp.float64,
    on_edge: wp.float64,
    min_det: wp.float64,
    min_t: wp.float64,
    t_out: wp.array[wp.float64],
    what: wp.array[wp.int32],
) -> None:
    i = wp.tid()
    o = origins[i]
    d = dirs[i]
    what[i] = MISS
    face = wp.int32(-1)
    second = False
    hit = wp.mesh_query_ray(mesh, wp.vec3(o), wp.vec3(d), 3.0e38)
    if hit.result:
        face = hit.face
    else:
        # a ray through a vertex can slip past the float32 boxes: look again a hair
        # to the side, and keep the triangle only if the ray itself meets it (float64)
        again = wp.mesh_query_ray(mesh, wp.vec3(_sidestep(o, d, sidestep)), wp.vec3(d), 3.0e38)
        if again.result:
            face = again.face
            second = True
    if face >= 0:
        # Moller-Trumbore in float64 on that triangle, as ray_triangle.ray_triangle
        a = e1[face]
        b = e2[face]
        p = wp.cross(d, b)
        det = a[0] * p[0] + a[1] * p[1] + a[2] * p[2]
        inv = wp.float64(1.0) / det
        tv = o - v0[face]
        u = (tv[0] * p[0] + tv[1] * p[1] + tv[2] * p[2]) * inv
        q = wp.cross(tv, a)
        v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv
        t = (b[0] * q[0] + b[1] * q[1] + b[2] * q[2]) * inv
        inside = wp.min(wp.min(u, v), wp.float64(1.0) - u - v) >= -on_edge
        if second and not inside:
            return
        if wp.abs(det) > min_det and t > min_t:
            t_out[i] = t
            what[i] = HIT
        else:
            what[i] = BRUTE  # parallel in float64, or at/behind the origin


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
        self._v0, self._e1, self._e2 = (
            _vec3d(np.ascontiguousarray(a)) for a in triangle_edges(vertices, faces)
        )
        self._points = wp.array(vertices.astype(np.float32), dtype=wp.vec3, device="cpu")
        self._indices = wp.array(faces.astype(np.int32).ravel(), dtype=wp.int32, device="cpu")
        self._mesh = wp.Mesh(points=self._points, indices=self._indices, bvh_constructor="sah")

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
        out = np.full(len(dirs), np.nan)
        ok = np.isfinite(origins).all(axis=1) & np.isfinite(dirs).all(axis=1)
        ok &= (dirs != 0).any(axis=1)  # zero, infinite or NaN rays meet nothing
        idx = None if ok.all() else np.flatnonzero(ok)
        o = np.ascontiguousarray(origins if idx is None else origins[idx], np.float64)
        d = np.ascontiguousarray(dirs if idx is None else dirs[idx], np.float64)
        if len(d) == 0:
            return out
        t = wp.empty(len(d), dtype=wp.float64, device="cpu")
        what = wp.empty(len(d), dtype=wp.int32, device="cpu")
        inputs = [self._mesh.id, _vec3d(o), _vec3d(d), self._v0, self._e1, self._e2]
        inputs += [SIDESTEP, ON_EDGE, MIN_DET, MIN_T, t, what]
        wp.launch(_nearest_hits, dim=len(d), inputs=inputs, device="cpu")
        found = np.where(what.numpy() == HIT, t.numpy(), np.nan)
        brute = np.flatnonzero(what.numpy() == BRUTE)
        if len(brute):
            found[brute] = intersect_brute_force(self.vertices, self.faces, o[brute], d[brute])
        if idx is None:
            return found
        out[idx] = found
        return out


def _vec3d(a: FloatArray) -> Any:
    """A contiguous (N, 3) float64 array as a Warp array of vec3d (no copy on the CPU)."""
    return wp.array(a, dtype=wp.vec3d, device="cpu", copy=False)
