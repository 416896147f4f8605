#!/usr/bin/env python3
"""The hand-held figures, on simulated sessions, on one core.

    .venv/bin/python tools/bench_handheld.py              # every figure
    .venv/bin/python tools/bench_handheld.py --seconds 4  # shorter sessions (quicker)
    .venv/bin/python tools/bench_handheld.py --only jitter latency

Simulates sessions (``simulate_session``, fixed seeds) and replays each twice in the
same run: with stabilisation (the product) and with ``--no-stabilise`` (today: every
refresh shows the rendered frame as it is, no margin), then prints

- ``jitter``: RMS frame-to-frame motion of content points on the true surface at the
  refreshes while the user holds still, on a wall at 1.5 m (``plane``), a column
  (``cylinder-convex``) and a wall corner (``corner``), hand tremor ``--tremor`` degrees
  RMS; the ratio on/off (target <= 0.2);
- ``drift``: how far content points move over 10 s while the hand holds still
  (target < 2 mm);
- ``upright``: the largest angle between the content's vertical and gravity on the
  wall while held still, device rolled 0, 10 and 20 degrees (target <= 1 degree);
- ``latency``: IMU sample -> corrected frame handed to the display, median and p95
  (compute measured, refresh wait modelled; target p95 <= 20 ms), next to today's
  motion-to-frame latency (IMU sees the motion -> the depth-driven frame);
- ``step``: the display loop's time per refresh on one core (CPU time: the filter and
  prediction, ``stabilise``; the homography warp, ``reproject``), bilinear and nearest
  (target <= 3 ms), and the alternatives measured on one frame;
- ``sweep``: tremor (``--tremors``, degrees RMS), roll (``--rolls``) and ``--seeds``
  seeds per setting. The content's up is scored on every seed without the warp
  pipeline (:mod:`adaproj_edge.app.upright_score`: the runtime's IMU chain on the
  simulator's IMU stream, walls at ``--yaws``; fast); ``--full N`` also simulates and
  replays the first N seeds of each setting over a wall at a yaw (a mesh), the
  ``corner`` and a ``cylinder-convex`` (upright, jitter ratio, motion-to-photon). Prints
  the worst case of each figure with its seed. A deliberate roll of 20 degrees is
  scored the same way (``roll-follow``: seconds after the roll's start until the up
  is within a degree, the worst seed). The full sweep:

      tools/bench_handheld.py --only sweep --seeds 10 --full 10

  a reduced one (the default): ``--seeds 10 --full 0``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adaproj_edge.app.replay import ReplayOptions, replay_session  # noqa: E402
from adaproj_edge.app.settings import AppSettings  # noqa: E402
from adaproj_edge.geometry.calibration import Calibration  # noqa: E402
from adaproj_edge.session.hand import HandMotion  # noqa: E402
from adaproj_edge.session.simulator import Scene, SimulationSettings, simulate_session  # noqa: E402
from adaproj_edge.threads import apply_thread_policy  # noqa: E402

SCENES = {"wall 1.5 m": "plane", "column": "cylinder-convex", "corner": "corner"}
FIGURES = ("jitter", "drift", "upright", "latency", "step", "sweep")
FULL_SCENES = {"wall (yaw 35)": "wall-yaw", "corner": "corner", "curved": "cylinder-convex"}


def simulate(out: Path, surface: str, hand: HandMotion, seed: int) -> Path:
    """A simulated session of ``hand`` in front of ``surface``."""
    settings = SimulationSettings(seconds=hand.seconds, depth_fps=15.0, seed=seed, motion=hand)
    simulate_session(Scene.load(surface), out, Calibration.default(), settings)
    return out


def replay(
    path: Path, stabilise: bool, settings: AppSettings | None = None, quiet: bool = False
) -> dict[str, Any]:
    """The replay's summary (handheld section and timings; ``quiet``: the hand-held
    figures only, no distortion scores, and no line of its own)."""
    options = ReplayOptions(settings or AppSettings(), stabilise=stabilise, distortion=not quiet)
    t = time.perf_counter()
    s = replay_session(path, None, options)
    if not quiet:
        took = time.perf_counter() - t
        print(f"    ({path.name}, stabilise={stabilise}: {took:.0f} s)", flush=True)
    return s


def jitter(tmp: Path, seconds: float, tremor: float) -> None:
    print(f"jitter (tremor {tremor} deg RMS, {seconds:.0f} s sessions; target on/off <= 0.2)")
    rows = []
    for k, (label, surface) in enumerate(SCENES.items()):
        hand = HandMotion(seconds, seed=30 + k, tremor_deg=tremor)
        path = simulate(tmp / f"jitter-{surface}.mcap", surface, hand, 30 + k)
        on = replay(path, True)["handheld"]
        off = replay(path, False)["handheld"]
        rows.append((label, on["jitter_mm_rms"], off["jitter_mm_rms"]))
    for label, a, b in rows:
        ratio = a / b if a is not None and b else float("nan")
        print(f"  {label:11s} on {a} mm RMS, off (today) {b} mm RMS, ratio {ratio:.3f}")


def drift(tmp: Path, tremor: float) -> None:
    print("drift (held still 12 s on the wall at 1.5 m; target < 2 mm over 10 s)")
    hand = HandMotion(12.0, seed=40, tremor_deg=tremor, hold_after=0)
    path = simulate(tmp / "drift.mcap", "plane", hand, 40)
    on = replay(path, True)["handheld"]
    off = replay(path, False)["handheld"]
    print(f"  on {on['drift_mm_10s']} mm, off (today) {off['drift_mm_10s']} mm")


def upright(tmp: Path, seconds: float, tremor: float) -> None:
    print("upright (wall at 1.5 m, device rolled; target <= 1 deg while held still)")
    for k, roll in enumerate((0.0, 10.0, 20.0)):
        hand = HandMotion(seconds, seed=50 + k, tremor_deg=tremor, roll_deg=roll)
        path = simulate(tmp / f"roll-{roll:.0f}.mcap", "plane", hand, 50 + k)
        h = replay(path, True)["handheld"]
        print(
            f"  roll {roll:4.1f} deg: max {h['upright_error_deg_max']} deg, "
            f"median {h['upright_error_deg_median']} deg"
        )


def latency(tmp: Path, seconds: float, tremor: float) -> None:
    print("latency (IMU sample -> corrected frame handed to the display; target p95 <= 20 ms)")
    hand = HandMotion(seconds, seed=60, tremor_deg=tremor)
    path = simulate(tmp / "latency.mcap", "corner", hand, 60)
    for interp in ("nearest", "linear"):
        s = AppSettings()
        s = replace(s, display=replace(s.display, interpolation=interp))
        on = replay(path, True, s)
        h = on["handheld"]
        m = h["motion_to_photon_ms"]
        t = on["timings_ms"]
        print(
            f"  {interp:7s}: median {m['median']} ms, p95 {m['p95']} ms "
            f"({h['missed']} of {h['refreshes']} refreshes late); "
            f"step CPU per refresh median {t['refresh_cpu']['median_ms']} ms, "
            f"p95 {t['refresh_cpu']['p95_ms']} ms"
        )
    today = on["motion_to_frame_ms"]
    print(
        f"  today (IMU sees the motion -> depth-driven frame): median {today['median']} ms, "
        f"p95 {today['p95']} ms"
    )


def step() -> None:
    """The warp alternatives on one 1280x800 BGRX frame (CPU time, median of 50)."""
    import cv2

    from adaproj_edge.motion.prediction import PredictionSettings
    from adaproj_edge.motion.stabiliser import Stabiliser, StabiliserSettings
    from adaproj_edge.render.reproject import reproject, rotation_homography

    print("step (one refresh's work on a 1280x800 BGRX frame, CPU ms; target <= 3 ms)")
    cal = Calibration.default()
    K = cal.projector.K
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (cal.projector.height, cal.projector.width, 4), np.uint8)
    out = np.empty_like(frame)
    th = np.deg2rad(0.3)
    C = cv2.Rodrigues(np.array([th, 0.5 * th, 0.2 * th]))[0]
    H = rotation_homography(K, C)

    def cpu(fn: Any, n: int = 50) -> float:
        ts = []
        for _ in range(n):
            c = time.thread_time()
            fn()
            ts.append(time.thread_time() - c)
        return float(np.median(ts) * 1e3)

    def filt(method: str) -> float:
        """One refresh of the filter and prediction: the 7 gyro samples a refresh gets at
        416 Hz (a tremor of 0.15 degrees RMS, noise), then one step."""
        settings = StabiliserSettings(prediction=PredictionSettings(method=method))  # type: ignore[arg-type]
        stab = Stabiliser(K, (cal.projector.width, cal.projector.height), settings)
        t_ns = [0]
        f = np.array([9.7, 10.3, 9.1])
        ph = np.array([0.0, 1.0, 2.0])
        noise = np.random.default_rng(1)

        def one() -> None:
            for _ in range(7):
                t_ns[0] += 2_403_846
                s = t_ns[0] * 1e-9
                w = 0.16 * np.sin(2 * np.pi * f * s + ph) + noise.normal(0.0, 0.002, 3)
                stab.add_gyro(t_ns[0], w)
            stab.step(t_ns[0] + 10_000_000)

        for _ in range(120):  # a full prediction window first
            one()
        return cpu(one, 200)

    filters = {method: filt(method) for method in ("ar", "constant")}
    for method, ms in filters.items():
        print(f"  filter + prediction {method!r} (7 samples, one step): {ms:.3f} ms")
    print(f"  warpPerspective bilinear:  {cpu(lambda: reproject(frame, H, out, 'linear')):.3f} ms")
    nearest = cpu(lambda: reproject(frame, H, out, "nearest"))
    print(f"  warpPerspective nearest:   {nearest:.3f} ms")
    print(f"  the step (filter 'ar' + nearest warp): {filters['ar'] + nearest:.3f} ms")
    A = (H / H[2, 2])[:2]
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    print(
        f"  warpAffine bilinear (approximation): "
        f"{cpu(lambda: cv2.warpAffine(frame, A, frame.shape[1::-1], dst=out, flags=flags)):.3f} ms"
    )
    mx, my = np.meshgrid(np.arange(frame.shape[1], dtype=np.float32), np.arange(frame.shape[0]))
    m1, m2 = cv2.convertMaps(mx, my.astype(np.float32), cv2.CV_16SC2)
    print(
        "  remap with fixed-point maps (the fold into the display maps): "
        f"{cpu(lambda: cv2.remap(frame, m1, m2, cv2.INTER_LINEAR, dst=out)):.3f} ms "
        "(+ re-composing the maps with H every refresh)"
    )
    print(f"  frame copy (the floor): {cpu(lambda: np.copyto(out, frame)):.3f} ms")


def _wall_mesh(tmp: Path, yaw_deg: float) -> str:
    """A plane wall 1.5 m ahead turned ``yaw_deg`` about the vertical, as a mesh file."""
    from adaproj_edge.geometry.mesh_surface import MeshSurface, ply_bytes

    y = np.radians(yaw_deg)
    c, s = np.cos(y), np.sin(y)
    corners = [(-3.0, -2.0), (3.0, -2.0), (3.0, 2.0), (-3.0, 2.0)]
    v = np.array([[x * c, yy, 1.5 + x * s] for x, yy in corners])
    mesh = MeshSurface("wall-yaw", v, np.array([[0, 1, 2], [0, 2, 3]]))
    path = tmp / f"wall-yaw-{yaw_deg:g}.ply"
    path.write_bytes(ply_bytes(mesh))
    return str(path)


def sweep(
    offset: float,
    calibrated: bool,
    tmp: Path,
    seconds: float,
    tremors: list[float],
    rolls: list[float],
    seeds: int,
    yaws: list[float],
    full: int,
) -> None:
    from adaproj_edge.app.upright_score import trace_upright, wall_normal
    from adaproj_edge.session.simulator import ImuNoise

    noise = ImuNoise(accel_bias_sigma=offset)

    print(
        f"sweep: tremor {tremors} deg RMS, roll {rolls} deg, {seeds} seeds per setting, "
        f"{seconds:g} s sessions (targets: upright <= 1 deg on walls, <= 1.5 deg on corners, "
        "jitter ratio <= 0.2, motion-to-photon p95 <= 20 ms)"
    )
    print(
        f"  up alone (no warps), walls at yaw {yaws}, accelerometer offset {offset} m/s^2 "
        f"RMS ({'calibrated' if calibrated else 'not calibrated'}): worst / median of the "
        "seeds' max"
    )
    cpu = time.process_time()
    overall: tuple[float, str] = (0.0, "")
    for tremor in tremors:
        for roll in rolls:
            worst: tuple[float, str] = (0.0, "")
            maxima = []
            for seed in range(seeds):
                hand = HandMotion(seconds, seed=seed, tremor_deg=tremor, roll_deg=roll)
                trace = trace_upright(hand, seed, noise, calibrated=calibrated)
                for yaw in yaws:
                    err = float(trace.error_deg(wall_normal(yaw))[trace.still].max())
                    maxima.append(err)
                    worst = max(worst, (err, f"seed {seed}, yaw {yaw:g}"))
            overall = max(overall, (worst[0], f"tremor {tremor}, roll {roll}, {worst[1]}"))
            print(
                f"    tremor {tremor:4.2f} roll {roll:4.1f}: worst {worst[0]:.2f} deg "
                f"({worst[1]}), median {np.median(maxima):.2f} deg"
            )
    print(f"  worst upright (up alone): {overall[0]:.2f} deg at {overall[1]}")
    follow: tuple[float, str] = (0.0, "")
    for tremor in tremors:
        for seed in range(seeds):
            hand = HandMotion(
                5.0, seed=seed, tremor_deg=tremor, move_rad=0.0, move_m=0.0,
                roll_move_deg=20.0, roll_move_at_s=2.5, roll_move_s=0.4,
            )  # fmt: skip
            trace = trace_upright(hand, seed, noise, every=1, from_s=2.5, calibrated=calibrated)
            err = trace.error_deg(wall_normal(0.0))
            late = trace.t[err > 1.0]
            took = float(late.max() - 2.5) if late.size else 0.0
            follow = max(follow, (took, f"tremor {tremor}, seed {seed}"))
    print(f"  roll-follow (20 deg in 0.4 s): within 1 deg after {follow[0]:.2f} s at {follow[1]}")
    print(f"  ({time.process_time() - cpu:.0f} s CPU)")
    if full <= 0:
        return
    print(f"  full pipeline, first {full} seeds of each setting:")
    worst_f: dict[str, tuple[float, str]] = {}
    for tremor in tremors:
        for roll in rolls:
            for seed in range(full):
                for label, surface in FULL_SCENES.items():
                    name = _wall_mesh(tmp, 35.0) if surface == "wall-yaw" else surface
                    hand = HandMotion(seconds, seed=seed, tremor_deg=tremor, roll_deg=roll)
                    path = simulate(tmp / "sweep.mcap", name, hand, seed)
                    on = replay(path, True, quiet=True)["handheld"]
                    where = f"{label}, tremor {tremor}, roll {roll}, seed {seed}"
                    figures = {
                        f"upright max, {label}": on["upright_error_deg_max"],
                        f"jitter ratio, {label}": on["jitter_ratio"],
                        "motion-to-photon p95 ms": on["motion_to_photon_ms"]["p95"],
                    }
                    line = ", ".join(f"{k} {v}" for k, v in figures.items())
                    print(f"      {where}: {line}", flush=True)
                    for k, v in figures.items():
                        if v is not None and v >= worst_f.get(k, (-1.0, ""))[0]:
                            worst_f[k] = (float(v), where)
    for k, (v, where) in sorted(worst_f.items()):
        print(f"    worst {k}: {v:.3f} ({where})")


def main() -> int:
    apply_thread_policy()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0, help="length of each session")
    ap.add_argument("--tremor", type=float, default=0.15, help="hand tremor, degrees RMS")
    ap.add_argument("--only", nargs="+", choices=FIGURES, default=list(FIGURES[:-1]))
    ap.add_argument("--tremors", type=float, nargs="+", default=[0.05, 0.15, 0.3, 0.5])
    ap.add_argument("--rolls", type=float, nargs="+", default=[0.0, 12.0, 30.0])
    ap.add_argument("--yaws", type=float, nargs="+", default=[0.0, 35.0])
    ap.add_argument(
        "--offset",
        type=float,
        default=0.1,
        help="accelerometer zero-g offset, m/s^2 RMS per axis, for the up alone (sweep; "
        "0.1: as the session simulator)",
    )
    ap.add_argument(
        "--uncalibrated",
        action="store_true",
        help="the up alone without the calibration's accelerometer offset (sweep)",
    )
    ap.add_argument("--seeds", type=int, default=10, help="seeds per setting (sweep)")
    ap.add_argument(
        "--full", type=int, default=0, help="seeds per setting also replayed in full (sweep)"
    )
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-handheld-") as d:
        tmp = Path(d)
        if "step" in args.only:
            step()
        if "jitter" in args.only:
            jitter(tmp, args.seconds, args.tremor)
        if "drift" in args.only:
            drift(tmp, args.tremor)
        if "upright" in args.only:
            upright(tmp, args.seconds, args.tremor)
        if "latency" in args.only:
            latency(tmp, args.seconds, args.tremor)
        if "sweep" in args.only:
            sweep(
                args.offset,
                not args.uncalibrated,
                tmp,
                args.seconds,
                args.tremors,
                args.rolls,
                args.seeds,
                args.yaws,
                args.full,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
