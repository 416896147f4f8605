#!/usr/bin/env python3
"""The geometric photometry's figures: flat mid-grey content on a wall corner and on
concave domes, as a viewer off to the side sees it, plain and compensated; and what
the gain costs, per pose and per displayed frame, at 1280x800 on one core.

For each surface (``--surfaces``; the built-in ``corner``, a 90-degree wall corner, and
the concave dome ``sphere-concave`` and dish ``bowl``): the content warped as on the
device (``--mode``), the gain map made from the surface the projector measures, and
what the viewer at ``--viewer`` (default 0.8 m to the right of the projector) sees,
from the test's own ray cast of the analytic surface
(``tests/render/photometry_oracle.py``, the figures ``tests/render/test_photometry.py``
asserts at 640x400): max/min of the brightness over the picture (goal <= 1.10), mean
after / before (goal >= 0.7) and the largest change of brightness per degree of the
viewer's visual angle over a 1-degree baseline (goal: under the cited 2 %), before and
after. Beside them the module's own prediction and the gain's own largest change per
degree (it jumps at a crease on purpose: the brightness does not). Then the same
surfaces through the device's own path (``--device-frames``, "device"): simulated
OAK-D depth frames of the device held still, the runtime's surface source (the warp
grid's lattice, averaged, walls snapped) and warp source (its content-free warp and
gain at the runtime's settings, 1/4 of the frame), judged by the same ray cast.

The cost: CPU time (``time.process_time``) of making the gain map (once per pose) and
of applying it to a 1280x800 BGR frame (every displayed frame), median and 95th
percentile of ``--frames`` runs.

The surface's own colour (``--colour N``: N cases drawn at random from ``--seed``; 0:
none): a surface (plane, tilted, corner, cylinder, dome, bowl), a texture (bricks,
blotches, stripes, wallpaper, or the ``--albedo`` pictures given) of contrast up to 0.5
with a random tint, room light 0-10 % of the projector's white and a content image
(the built-in poster, a text card, a photo-like landscape, colour bars and ramps, the
documentation's screenshot). The simulated grey camera's captures (black, white, the
three primaries) give the measured response; the per-frame gain is applied in 8 bits;
what a viewer sees (``L = albedo (E p + ambient)``, Lambertian: the same from every
direction) is judged against the content on a uniform white surface after one global
gain and one uniform room light, by PSNR and SSIM (``tests/render/image_quality.py``),
plain and compensated in the same run (goal: >= 25 dB and >= 0.85 compensated). Then
the cost of measuring (once per calibration) and the frames the captures take.

    .venv/bin/python tools/bench_photometric.py [--surfaces corner,sphere-concave,bowl]
        [--scale 2] [--frames 300] [--colour 24 --seed 0 --size 640x400]
        [--albedo a.png,b.png] [--lift 0.8] [--device-frames 3]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _gain_gradient(light: object, deg_per_px: float) -> float:
    """The gain's own largest relative change per degree (forward differences)."""
    import numpy as np

    lg = np.log(np.asarray(light, dtype=np.float64))
    g = np.hypot(np.diff(lg, axis=1)[:-1, :], np.diff(lg, axis=0)[:, :-1])
    return math.expm1(float(g.max()) / deg_per_px)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--surfaces", default="corner,sphere-concave,bowl")
    p.add_argument("--mode", default="content", choices=("content", "conformal"))
    p.add_argument(
        "--scale", type=int, default=None, help="the gain map's 1/scale (default: the module's)"
    )
    p.add_argument("--viewer", default="0.8,-0.15,0.1", help="X,Y,Z metres, projector frame")
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--colour", type=int, default=24, help="coloured surfaces drawn (0: none)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", default="640x400", help="the frame for the colour figures")
    p.add_argument("--albedo", default="", help="albedo pictures to score, comma-separated")
    p.add_argument("--no-geometric", action="store_true", help="only the colour figures")
    p.add_argument(
        "--device-frames",
        type=int,
        default=3,
        help="also the figures through the device's path: this many simulated OAK-D depth "
        "frames, the runtime's surface and warp source, its gain (0: not)",
    )
    p.add_argument(
        "--lift",
        type=float,
        default=None,
        help="also score an 8-bit lift map added after the colour gain, made exact for "
        "content of this value (0-1; the room's light evened out to a uniform black)",
    )
    args = p.parse_args()

    from adaproj_edge.threads import apply_thread_policy

    apply_thread_policy()

    import numpy as np

    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.geometry.projector import Projector
    from adaproj_edge.render.photometry import (
        PhotometrySettings,
        degrees_per_pixel,
        gain_map,
    )
    from tests.render.photometry_oracle import device_grey_case, grey_case

    settings = PhotometrySettings() if args.scale is None else PhotometrySettings(scale=args.scale)
    if args.colour > 0 or args.albedo:
        colour_figures(args)
    if args.no_geometric:
        return
    eye = tuple(float(x) for x in args.viewer.split(","))
    assert len(eye) == 3
    projector = Projector.default()
    print(
        f"{projector.width}x{projector.height}, viewer at {eye} m, gain at 1/{settings.scale}, "
        f"mode {args.mode}, gradient bound {settings.gradient_per_deg:.0%}/deg "
        f"(projector angles), evenness {settings.evenness}, budget {settings.budget}"
    )
    head = (
        f"{'surface':23} {'max/min before':>14} {'after':>7} {'mean after/before':>17} "
        f"{'grad/deg before':>15} {'after':>7} | {'predicted':>9} {'gain grad/deg':>13}"
    )
    print(head)
    cases = [(n, "", False) for n in args.surfaces.split(",")]
    if args.device_frames > 0:  # the device's own surface, warp and gain (scale 1/4)
        cases += [(n, "device", True) for n in args.surfaces.split(",")]
    for name, tag, device in cases:
        if device:
            case = device_grey_case(name, eye, frames=args.device_frames)
        else:
            case = grey_case(name, projector, eye, settings, mode=args.mode)
        b, a, gm = case.before, case.after, case.gain
        deg = degrees_per_pixel(projector) * projector.width / gm.light.shape[1]
        label = f"{name} ({tag})" if tag else name
        print(
            f"{label:23} {b.ratio():14.3f} {a.ratio():7.3f} {a.mean() / b.mean():17.3f} "
            f"{b.gradient_per_deg():15.4f} {a.gradient_per_deg():7.4f} | "
            f"{gm.ratio_after:9.3f} {_gain_gradient(gm.light, deg):13.3f}"
            + (f"  ({gm.reason})" if gm.reason else "")
        )

    surface = simulate_surface("corner", projector)
    made = []
    for _ in range(5):
        t = time.process_time()
        gm = gain_map(surface, None, settings)
        gm.pixels(3)
        made.append(time.process_time() - t)
    frame = np.full((projector.height, projector.width, 3), 128, np.uint8)
    ms = apply_ms(frame, gm, args.frames)
    print(
        f"cost: gain map per pose median {np.median(made) * 1e3:.0f} ms (corner, 5 runs); "
        f"per displayed frame median {np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms "
        f"({args.frames} frames, 1280x800 BGR, one core)"
    )


SURFACES = ("plane", "tilted", "corner", "cylinder-concave", "sphere-concave", "bowl")
TEXTURES = ("bricks", "blotches", "stripes", "wallpaper")
CONTENTS = ("poster", "text", "landscape", "bars", "screenshot")


def apply_ms(frame: Any, gain: Any, frames: int) -> Any:
    """CPU ms of each of ``frames`` applications of ``gain`` to ``frame`` (after one
    untimed warm-up), as the display loop applies it."""
    import numpy as np

    from adaproj_edge.render.photometry import apply_gain

    out = np.empty_like(frame)
    apply_gain(frame, gain, out)
    times = []
    for _ in range(frames):
        t = time.process_time()
        apply_gain(frame, gain, out)
        times.append(time.process_time() - t)
    return np.array(times) * 1e3


def texture(kind: str, shape: tuple[int, int], rng: Any) -> Any:
    """A texture (h, w) in [0, 1] of ``kind``, its scale and phase drawn from ``rng``."""
    import cv2
    import numpy as np

    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    k = w / 640.0  # sizes in pixels of a 640-wide frame
    if kind == "bricks":
        bh = rng.uniform(12, 30) * k
        row = (y // bh).astype(int)
        bw = 2.2 * bh
        bx = ((x + (row % 2) * bw / 2) // bw).astype(int)
        t = 0.6 * ((row * 7 + bx * 13) % 5) / 4.0
        mortar = ((y % bh) < 0.15 * bh) | (((x + (row % 2) * bw / 2) % bw) < 0.15 * bh)
        t = np.where(mortar, 1.0, t)
    elif kind == "blotches":
        t = cv2.GaussianBlur(rng.uniform(0, 1, (h, w)), (0, 0), rng.uniform(2, 12) * k)
    elif kind == "stripes":
        period = rng.uniform(8, 60) * k
        t = (np.sin(2 * np.pi * (x * np.cos(rng.uniform(0, 3)) + y) / period) > 0) * 1.0
    else:
        f = rng.uniform(20, 60) * k
        t = np.sin(x / f * 6) * np.sin(y / f * 6) + 0.5 * np.sin((x + y) / f * 17)
    t = np.asarray(t, np.float64)
    return (t - t.min()) / max(float(np.ptp(t)), 1e-9)


def content_image(kind: str, size: tuple[int, int], rng: Any) -> Any:
    """A content image (h, w, 3) BGR uint8 of ``kind`` at ``size`` (w, h)."""
    import cv2
    import numpy as np

    from adaproj_edge.content.builtin import poster

    w, h = size
    if kind == "poster":
        return poster(size)
    if kind == "screenshot":
        img = cv2.imread(str(Path(__file__).resolve().parents[1] / "docs" / "demo.jpg"))
        return cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    y, x = np.mgrid[0:h, 0:w] / max(w, h)
    if kind == "text":
        img = np.full((h, w, 3), 245, np.uint8)
        for i in range(8):
            line = "".join(rng.choice(list("abcdefghij klmnopqrstuvwxyz")) for _ in range(30))
            cv2.putText(
                img, line, (int(0.05 * w), int((i + 1) * h / 9)), cv2.FONT_HERSHEY_SIMPLEX,
                w / 900, (20, 20, 20), max(1, w // 640), cv2.LINE_AA,
            )  # fmt: skip
        return img
    if kind == "bars":
        bits = np.array([7, 6, 3, 2, 5, 4, 1, 0])  # white, yellow, cyan, ... black (BGR)
        bars = 255.0 * np.stack([(bits >> 2) & 1, (bits >> 1) & 1, bits & 1], -1)
        idx = np.minimum((x * max(w, h) / w * 8).astype(int), 7)
        ramp = (x * max(w, h) / w)[..., None]
        return np.where(
            (y * max(w, h) / h)[..., None] < 0.6, bars[idx], 255 * ramp * np.ones(3)
        ).astype(np.uint8)
    # a landscape: a sky gradient, hills of blotchy green, a sun
    sky = np.stack([230 - 80 * y, 200 - 60 * y, 140 + 0 * y], -1) * np.ones((h, w, 1))
    hill = y * max(w, h) / h > 0.55 + 0.1 * np.sin(x * 9 + rng.uniform(0, 6))
    grass = cv2.GaussianBlur(rng.uniform(0, 1, (h, w)), (0, 0), 2)[..., None]
    ground = np.array([40.0, 140.0, 60.0]) * (0.6 + 0.8 * grass)
    img = np.where(hill[..., None], ground, sky)
    cv2.circle(img, (int(0.75 * w), int(0.2 * h)), int(0.06 * w), (80, 220, 255), -1)
    return np.clip(img, 0, 255).astype(np.uint8)


def colour_figures(args: argparse.Namespace) -> None:
    """The PSNR / SSIM figures of textured, tinted surfaces in lit rooms."""
    import cv2
    import numpy as np

    from adaproj_edge.errors import CalibrationError
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.geometry.projector import Projector
    from adaproj_edge.render.photometry import apply_gain, gain_map
    from adaproj_edge.render.reflectance import colour_gain, measure, plan
    from adaproj_edge.render.surface_light import scaled_irradiance, simulated_captures
    from tests.render.image_quality import scores

    w, h = (int(v) for v in args.size.lower().split("x"))
    projector = Projector.default(w, h)
    rng = np.random.default_rng(args.seed)
    cases: list[tuple[str, str, Any]] = []
    for i in range(args.colour):
        cases.append((SURFACES[i % len(SURFACES)], str(rng.choice(TEXTURES)), None))
    for path in filter(None, args.albedo.split(",")):
        cases.append(("plane", Path(path).name, cv2.imread(path)))
    lin = (np.arange(256) / 255.0) ** 2.2
    print(
        f"\nsurface colour at {w}x{h}: PSNR (dB) / SSIM against the content on uniform "
        "white (one global gain and room light), plain -> compensated"
    )
    print(
        f"{'surface':17} {'texture':10} {'contr':>5} {'tint b,g,r':>14} {'room':>5} "
        f"{'content':10} {'PSNR plain':>10} {'comp':>6} {'SSIM plain':>10} {'comp':>6} "
        f"{'kept':>5}"
    )
    got: list[tuple[float, float, float, float]] = []
    lifted_scores: list[tuple[float, float]] = []
    measure_s = []
    for surface_name, kind, picture in cases:
        surface = simulate_surface(surface_name, projector)
        e = scaled_irradiance(surface)
        if picture is None:
            contrast = float(rng.uniform(0.1, 0.5))
            tint = rng.uniform(0.6, 1.0, 3)
            tint /= tint.max()
            t = texture(kind, e.shape, rng)
            albedo = (tint * (1.0 - contrast * t)[..., None]).astype(np.float32)
        else:
            albedo = cv2.resize(picture, (w, h), interpolation=cv2.INTER_AREA) / 255.0
            contrast = float(1.0 - albedo.min() / max(albedo.max(), 1e-9))
            tint = albedo.reshape(-1, 3).mean(axis=0)
        ambient = float(rng.uniform(0.0, 0.1))
        content_kind = str(rng.choice(CONTENTS))
        content = content_image(content_kind, (w, h), rng)
        t0 = time.process_time()
        caps = simulated_captures(albedo, e, ambient, rng)
        t1 = time.process_time()
        try:
            response = measure(caps["black"], caps["white"], [caps[c] for c in PRIMARIES])
            comp = plan(response, lift=False)
            gain = colour_gain(response, comp, (w, h))
            kept = f"{comp.kept:5.2f}"
            if args.lift is not None:
                up = plan(response, lift=True)
                lifted = apply_gain(content, colour_gain(response, up, (w, h)))
                lifted = cv2.add(lifted, lift_map(response, up, (w, h), args.lift))
                seen = albedo * (lin[lifted] * e[..., None] + ambient)
                lifted_scores.append(scores(seen, content, e > 0))
                kept += " lifted {:.1f} dB {:.3f}".format(*lifted_scores[-1])
        except CalibrationError as err:  # as on the device: the geometric gain alone
            gain, kept = gain_map(surface), f"refused: {err}"
        measure_s.append(time.process_time() - t1)
        del t0
        shown = apply_gain(content, gain)
        where = e > 0
        plain = albedo * (lin[content] * e[..., None] + ambient)
        after = albedo * (lin[shown] * e[..., None] + ambient)
        p0, s0 = scores(plain, content, where)
        p1, s1 = scores(after, content, where)
        got.append((p0, p1, s0, s1))
        tint_s = ",".join(f"{v:.2f}" for v in tint)
        print(
            f"{surface_name:17} {kind[:10]:10} {contrast:5.2f} {tint_s:>14} {ambient:5.1%} "
            f"{content_kind:10} {p0:10.1f} {p1:6.1f} {s0:10.3f} {s1:6.3f} {kept}"
        )
    a = np.array(got)
    print(
        f"{'all':17} min PSNR plain {a[:, 0].min():.1f} compensated {a[:, 1].min():.1f} dB "
        f"(median {np.median(a[:, 0]):.1f} -> {np.median(a[:, 1]):.1f}); min SSIM plain "
        f"{a[:, 2].min():.3f} compensated {a[:, 3].min():.3f} (median "
        f"{np.median(a[:, 2]):.3f} -> {np.median(a[:, 3]):.3f})"
    )
    if lifted_scores:
        lf = np.array(lifted_scores)
        print(
            f"{'lifted':17} (an 8-bit lift map exact at content value {args.lift}): min PSNR "
            f"{lf[:, 0].min():.1f} dB, min SSIM {lf[:, 1].min():.3f} (median "
            f"{np.median(lf[:, 1]):.3f}), {int(np.sum(lf[:, 1] < 0.85))} under 0.85 (without "
            f"the lift: {int(np.sum(a[:, 3] < 0.85))})"
        )
    big = Projector.default()
    e = scaled_irradiance(simulate_surface("corner", big))
    albedo = (0.5 + 0.5 * texture("bricks", e.shape, rng)[..., None] * np.ones(3)).astype(
        np.float32
    )
    caps = simulated_captures(albedo, e, 0.05, rng)
    response = measure(caps["black"], caps["white"], [caps[c] for c in PRIMARIES])
    gain = colour_gain(response, plan(response, lift=False), (big.width, big.height))
    frame = content_image("poster", (big.width, big.height), rng)
    ms = apply_ms(frame, gain, args.frames)
    print(
        f"colour gain per displayed frame ({big.width}x{big.height} BGR, one core): median "
        f"{np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms ({args.frames} frames)"
    )
    print(
        f"measuring (captures to the per-frame gain, {w // 2}x{h // 2} response): median "
        f"{np.nanmedian(measure_s) * 1e3:.0f} ms CPU; the captures are {len(PRIMARIES) + 2} "
        "frames (black and white are the Gray-code sequence's own)"
    )


PRIMARIES = ("blue", "green", "red")


def lift_map(response: Any, comp: Any, size: tuple[int, int], value: float) -> Any:
    """An 8-bit lift (H, W, 3) to add to a frame after the colour gain of ``comp`` (a
    plan with its lift): the pixel values that raise each pixel's light by
    ``M^-1 (lift - ambient)`` where the content's value is ``value`` (0-1): the room's
    light evened out to the uniform black exactly for content of that value (darker
    content is lifted too little, brighter too much: the frame is in 8 bits, not in
    light). ``size`` (width, height) is the frame's."""
    import cv2
    import numpy as np

    from adaproj_edge.render.reflectance import colour_gain

    inv = np.linalg.pinv(response.mix.astype(np.float64))
    room = np.einsum("...ij,...j->...i", inv, comp.lift - response.ambient.astype(np.float64))
    gain = colour_gain(response, comp, size).light.astype(np.float64)
    base = gain * float(np.clip(value, 0.0, 1.0)) ** 2.2
    up = np.clip(base + np.clip(room, 0.0, 1.0), 0.0, 1.0) ** (1 / 2.2) - base ** (1 / 2.2)
    small = np.clip(np.rint(255.0 * up), 0, 255).astype(np.uint8)
    return cv2.resize(small, size, interpolation=cv2.INTER_LINEAR)


if __name__ == "__main__":
    main()
