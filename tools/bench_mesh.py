#!/usr/bin/env python3
"""Benchmark simulating and replaying a session on a large triangle mesh, on one core.

    .venv/bin/python tools/bench_mesh.py                        # 100,000 triangles, 6 s
    .venv/bin/python tools/bench_mesh.py --triangles 1000000 --seconds 6
    PYTHON tools/bench_mesh.py --candidates                     # ray-casting libraries

Makes a bumpy room corner (two plastered walls meeting in a crease 2.2 m ahead, and
the floor, which reaches behind the device) as a PLY mesh of ``--triangles``
triangles, then runs, as a person would and pinned to one core,
``adaproj simulate-session --surface MESH.ply --seconds 6`` and ``adaproj replay``
on the session it wrote (the replay scores every content-aware frame against the
mesh: the ground-truth scorer casts the mesh too). Prints both wall times (target:
each under a minute) and the CPU time they used (the machine may be shared: wall
time then grows, CPU time does not). The BVH kernel is compiled before the timed
runs (once per machine; the time it took is printed).

Then one depth frame (640x400 rays) of a smaller mesh of the same scene
(``--small`` triangles) is cast by brute force (every ray against every triangle,
the caster without the ``sim`` extra; every ``--rows``-th row of the frame, scaled
to the whole frame) and through the BVH, in the same run: their ratio, and what
brute force would take per frame on the large mesh (it grows with the triangle
count).

``--candidates`` times the ray-casting libraries that are importable (NVIDIA Warp as
used here, Open3D's RaycastingScene, Embree through embreex, libigl's AABB tree):
building the structure and casting 1280x800 rays (the projector's) on the large
mesh, best of ``--repeat``, one core, with the largest difference from brute force
on a sample of rays. Run it with a Python that has them installed; it needs only
numpy, warp-lang and this checkout on the path.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core, as the target says; set before numpy loads (and children)

import argparse  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.arrays import FloatArray  # noqa: E402
from adaproj_edge.geometry.ray_triangle import intersect_brute_force  # noqa: E402

IntArray = NDArray[np.int64]  # triangle indices, as MeshSurface.faces


# ---------------------------------------------------------------- the scene
def _grid(
    n_u: int, n_v: int, point: Callable[[FloatArray, FloatArray], FloatArray]
) -> tuple[FloatArray, IntArray]:
    """A (n_u x n_v)-quad patch: vertices point(u, v) over [0, 1]^2, two triangles a quad."""
    u, v = np.meshgrid(np.linspace(0, 1, n_u + 1), np.linspace(0, 1, n_v + 1), indexing="ij")
    verts = point(u, v).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="ij")
    a = (i * (n_v + 1) + j).ravel()
    b, c = a + n_v + 1, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([c, b, b + 1], 1)])
    return verts, faces


def room_corner(triangles: int, seed: int = 0) -> tuple[FloatArray, IntArray]:
    """A concave wall corner and the floor, bumpy like plaster; about ``triangles``.

    Projector frame at the start of a session: x right, y down, z ahead (metres).
    The walls meet in a vertical crease at x = 0, z = 2.2 and run back at 45 degrees
    for 3 m; the floor is 0.9 m below the device, from 1 m behind it to the walls.
    """
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, size=(3, 4))
    c = np.sqrt(0.5)

    def plaster(k: int, a: FloatArray, b: FloatArray) -> FloatArray:
        """Bumps (cm) of four wavelengths (0.1-1 m), different on each piece."""
        waves = [(6.0, 5.0, 0.006), (13.0, 11.0, 0.003), (31.0, 29.0, 0.001), (60.0, 57.0, 5e-4)]
        return sum(  # type: ignore[return-value]
            amp * np.sin(fa * a + phase[k, w]) * np.cos(fb * b + phase[k, 3 - w])
            for w, (fa, fb, amp) in enumerate(waves)
        )

    def wall(k: int, sign: float) -> Callable[[FloatArray, FloatArray], FloatArray]:
        def point(u: FloatArray, v: FloatArray) -> FloatArray:
            s, y = 3.0 * u, -1.6 + 2.5 * v  # along the wall from the crease; height
            n = plaster(k, s, y)  # along the wall's normal (into the room)
            return np.stack([sign * c * (s - n), y, 2.2 - c * (s + n)], axis=-1)

        return point

    def floor(u: FloatArray, v: FloatArray) -> FloatArray:
        x, z = -2.6 + 5.2 * u, -1.0 + 3.3 * v
        return np.stack([x, 0.9 - plaster(2, x, z), z], axis=-1)

    q_wall = max(1, round(0.35 * triangles / 2))  # quads per wall
    q_floor = max(1, round(0.30 * triangles / 2))
    n_w = max(1, round(np.sqrt(q_wall * 3.0 / 2.5)))
    n_f = max(1, round(np.sqrt(q_floor * 5.2 / 3.3)))
    parts = [
        _grid(n_w, max(1, round(q_wall / n_w)), wall(0, -1.0)),
        _grid(n_w, max(1, round(q_wall / n_w)), wall(1, 1.0)),
        _grid(n_f, max(1, round(q_floor / n_f)), floor),
    ]
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    return np.concatenate(verts), np.concatenate(faces)


def pixel_rays(width: int, height: int, K: FloatArray) -> FloatArray:
    """Rays (height * width, 3) with z = 1 through every pixel centre."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    return np.stack([x, y, np.ones_like(x)], axis=-1).reshape(-1, 3)


def one_core() -> None:
    """Pin this process (and the processes it starts) to one core."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


# ---------------------------------------------------------------- the session
def _timed(cmd: list[str]) -> tuple[float, float]:
    """Run ``cmd``; its wall and CPU seconds. Its output goes to ours."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return wall, cpu


def _in_process(work: Callable[[], Any]) -> tuple[Any, tuple[float, float]]:
    """``work()`` and the wall and CPU seconds it took."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = work()
    return result, (time.perf_counter() - t0, time.process_time() - c0)


def bench_session(args: argparse.Namespace) -> None:
    from adaproj_edge.geometry.calibration import Calibration
    from adaproj_edge.geometry.mesh_surface import MeshSurface, ply_bytes
    from adaproj_edge.session.simulator import Scene

    adaproj = str(Path(sys.executable).with_name("adaproj"))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep) if args.keep else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        v, f = room_corner(args.triangles)
        mesh_path = out / "room-corner.ply"
        mesh_path.write_bytes(ply_bytes(MeshSurface("room-corner", v, f)))
        print(f"mesh: {len(f):,} triangles, {mesh_path.stat().st_size / 1e6:.1f} MB", flush=True)

        t0 = time.perf_counter()  # the kernel, compiled once per machine (cached after)
        MeshSurface("warm-up", np.eye(3), np.array([[0, 1, 2]])).intersect(
            np.zeros(3), np.array([0.0, 0.0, 1.0])
        )
        print(f"BVH kernel ready in {time.perf_counter() - t0:.1f} s", flush=True)

        session = out / "room-corner.mcap"
        print(f"simulating {args.seconds:g} s ...", flush=True)
        sim = _timed([adaproj, "simulate-session", "--surface", str(mesh_path),
                      "--seconds", str(args.seconds), "--out", str(session)])  # fmt: skip
        print("replaying (scored against the mesh) ...", flush=True)
        rep = _timed([adaproj, "replay", str(session), "--out", str(out / "replay")])

        cal = Calibration.default()
        d = cal.depth
        rays = pixel_rays(d.width, d.height, d.K)
        rows = rays.reshape(d.height, d.width, 3)[:: args.rows].reshape(-1, 3)
        origin = np.zeros((len(rows), 3))
        vs, fs = room_corner(args.small)
        small = MeshSurface("small", vs, fs)
        big = Scene(MeshSurface("big", v, f), {})
        small.intersect(origin[:1], rows[:1])  # build the BVHs outside the timing
        big.surface.intersect(origin[:1], rows[:1])
        print(f"one {d.width}x{d.height} depth frame by brute force on {len(fs):,} triangles "
              f"(every {args.rows}th row, scaled) ...", flush=True)  # fmt: skip
        brute, t_brute = _in_process(
            lambda: intersect_brute_force(small.vertices, small.faces, origin, rows)
        )
        bvh, t_small = _in_process(lambda: small.intersect(origin, rows))
        _, t_big = _in_process(
            lambda: big.points_seen(d.K, d.width, d.height, np.eye(3), np.zeros(3))
        )
        same = np.isclose(brute, bvh, rtol=1e-12, atol=0, equal_nan=True).mean()

    scale = len(rays) / len(rows)  # the sampled rows -> a whole frame
    t_brute = (t_brute[0] * scale, t_brute[1] * scale)
    t_small = (t_small[0] * scale, t_small[1] * scale)
    print()
    print(f"{args.seconds:g}-s session on {len(f):,} triangles, one core       wall s    CPU s")
    print(f"  adaproj simulate-session                 {sim[0]:8.1f} {sim[1]:8.1f}")
    print(f"  adaproj replay (scored on the mesh)      {rep[0]:8.1f} {rep[1]:8.1f}")
    print(f"one depth frame ({d.width}x{d.height} rays)              wall ms   CPU ms")
    for name, n, (wall, cpu) in (
        ("brute force", len(fs), t_brute),
        ("BVH", len(fs), t_small),
        ("BVH", len(f), t_big),
    ):
        print(f"  {name:12} {n:>9,} triangles  {1000 * wall:12.1f} {1000 * cpu:8.1f}")
    print(f"brute force / BVH on {len(fs):,} triangles: {t_brute[1] / t_small[1]:.0f}x (CPU), "
          f"same t on {100 * same:.3f} % of rays; brute force on {len(f):,} triangles: "
          f"~{t_brute[1] * len(f) / len(fs) / 60:.0f} CPU min a frame")  # fmt: skip


# ---------------------------------------------------------------- the libraries
def _warp(v: FloatArray, f: IntArray) -> Callable[[FloatArray, FloatArray], FloatArray]:
    from adaproj_edge.geometry.mesh_bvh import MeshBvh

    return MeshBvh(v, f).cast


def _open3d(v: FloatArray, f: IntArray) -> Callable[[FloatArray, FloatArray], FloatArray]:
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))

    def cast(o: FloatArray, d: FloatArray) -> FloatArray:
        r = o3d.core.Tensor(np.concatenate([o, d], axis=1).astype(np.float32))
        t = scene.cast_rays(r, nthreads=1)["t_hit"].numpy().astype(np.float64)
        return np.where(np.isfinite(t), t, np.nan)

    cast(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))  # Open3D builds on the first cast
    return cast


def _embreex(v: FloatArray, f: IntArray) -> Callable[[FloatArray, FloatArray], FloatArray]:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, v.astype(np.float32)[f])

    def cast(o: FloatArray, d: FloatArray) -> FloatArray:
        res = scene.run(o.astype(np.float32), d.astype(np.float32), output=1)
        return np.where(res["geomID"] >= 0, res["tfar"].astype(np.float64), np.nan)

    return cast


def _libigl(v: FloatArray, f: IntArray) -> Callable[[FloatArray, FloatArray], FloatArray]:
    import igl

    tree = igl.AABB()
    tree.init(v, f)

    def cast(o: FloatArray, d: FloatArray) -> FloatArray:
        face, t, _ = tree.intersect_ray_first(v, f, o, d)
        return np.where(face >= 0, t, np.nan)

    return cast


CANDIDATES: dict[str, Callable[[FloatArray, IntArray], Callable[..., Any]]] = {
    "warp-lang (this caster)": _warp,
    "open3d RaycastingScene": _open3d,
    "embreex (Embree)": _embreex,
    "libigl AABB": _libigl,
}


def bench_candidates(args: argparse.Namespace) -> None:
    v, f = room_corner(args.triangles)
    K = np.array([[1400.0, 0.0, 639.5], [0.0, 1400.0, 399.5], [0.0, 0.0, 1.0]])
    d = pixel_rays(1280, 800, K)
    o = np.zeros_like(d)
    sample = np.random.default_rng(0).choice(len(d), 100, replace=False)
    t0 = time.perf_counter()
    ref = intersect_brute_force(v, f, o[sample], d[sample])
    brute_s = (time.perf_counter() - t0) / len(sample) * len(d)
    print(f"{len(f):,} triangles, {len(d):,} rays, one core; best of {args.repeat}")
    print(f"{'':26} {'first ms':>9} {'build ms':>9} {'cast ms':>9}  max |t - brute|")
    print(f"{'brute force (numpy)':26} {'':>9} {'':>9} {1000 * brute_s:9.0f}  (from 100 rays)")
    for name, make in CANDIDATES.items():
        try:
            times = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                cast = make(v, f)
                t1 = time.perf_counter()
                t = cast(o, d)
                times.append((t1 - t0, time.perf_counter() - t1))
        except ImportError as e:
            print(f"{name:26} not installed ({e.name})")
            continue
        err = np.nanmax(np.abs(t[sample] - ref))
        agree = np.array_equal(np.isnan(t[sample]), np.isnan(ref))
        first = sum(times[0])
        build = min(b for b, _ in times)
        cast_s = min(c for _, c in times)
        print(f"{name:26} {1000 * first:9.0f} {1000 * build:9.1f} {1000 * cast_s:9.0f}  "
              f"{err:.1e}{'' if agree else ' (hit/miss differ)'}")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=100_000, help="size of the mesh")
    ap.add_argument("--seconds", type=float, default=6.0, help="length of the session")
    ap.add_argument("--small", type=int, default=2_000, help="mesh for the brute-force frame")
    ap.add_argument("--rows", type=int, default=4, help="brute force: every n-th row of a frame")
    ap.add_argument("--keep", default=None, help="keep the mesh, session and replay here")
    ap.add_argument("--candidates", action="store_true", help="time the ray-casting libraries")
    ap.add_argument("--repeat", type=int, default=3, help="runs per library (--candidates)")
    args = ap.parse_args()
    one_core()
    if args.candidates:
        bench_candidates(args)
    else:
        bench_session(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
