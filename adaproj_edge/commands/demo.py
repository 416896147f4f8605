"""``adaproj demo``: the built-in poster corrected for built-in surfaces, with pictures."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from adaproj_edge.commands._inputs import content_map, surface_names
from adaproj_edge.commands._outputs import check_output_dir
from adaproj_edge.commands.simulate import simulate

DEMO_SURFACES = ("corner", "cylinder-convex", "sphere-concave", "bowl")


def register(sub: argparse._SubParsersAction[Any]) -> None:
    from adaproj_edge.geometry.analytic import SURFACES

    p = sub.add_parser(
        "demo",
        help="correct the built-in poster for built-in surfaces and write the pictures",
        description="Project the built-in poster onto built-in surfaces, plainly and "
        "corrected (content mode, the saliency model max the poster's subject mask), and "
        "show both as a viewer 0.8 m to the side sees them. Writes, in the folder, "
        "demo.png (input | standard projector | adaproj, a row per surface), the poster as "
        "input.png, per surface "
        "NAME.png, NAME-frame.png (the projector frame) and NAME-warp.npz, and "
        "summary.json (the distortion of both, overall and over the subject).",
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="folder (default: out/demo/)")
    p.add_argument(
        "--surfaces",
        default=",".join(DEMO_SURFACES),
        help=f"comma-separated, from: {', '.join(SURFACES)} (default %(default)s)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    names = surface_names(args.surfaces)
    check_output_dir(args.out, "output folder")

    from adaproj_edge.content.builtin import poster, poster_mask
    from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD
    from adaproj_edge.content.model import SaliencyModel
    from adaproj_edge.fileio import atomic_write_bytes, write_png
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.render.sheet import stack
    from adaproj_edge.render.viewer import DEFAULT_VIEWER
    from adaproj_edge.warp.engine import WarpSettings
    from adaproj_edge.warp.quality import measure

    image = poster()
    h, w = image.shape[:2]
    mask = poster_mask((w, h))
    cmap = content_map(image, mask, None, DEFAULT_THRESHOLD, model=SaliencyModel())
    assert cmap is not None
    salient = cmap.full_size() >= cmap.threshold
    write_png(args.out / "input.png", image)
    summary: dict[str, Any] = {}
    rows = []
    print(f"{'surface':18s} {'mode':9s} {'angle err':>10s} {'size incons.':>12s} {'salient':>9s}")
    for k, name in enumerate(names, 1):
        t0 = time.perf_counter()
        surface = simulate_surface(name)
        picture, plain, corrected = simulate(
            surface, image, cmap, WarpSettings(mode="content"), DEFAULT_VIEWER, name
        )
        write_png(args.out / f"{name}.png", picture)
        write_png(args.out / f"{name}-frame.png", corrected.frame)
        corrected.warp.save(args.out / f"{name}-warp.npz")
        rows.append(picture)
        summary[name] = {}
        for mode, proj in (("standard", plain), ("content", corrected)):
            overall, sal = measure(proj.map_xy, surface, salient)
            assert sal is not None
            summary[name][mode] = {"all": overall.as_dict(), "salient": sal.as_dict()}
            print(
                f"{name:18s} {mode:9s} {overall.angle_error:10.4f} "
                f"{overall.size_inconsistency:12.4f} {sal.size_inconsistency:9.4f}"
            )
        summary[name]["seconds"] = round(time.perf_counter() - t0, 2)
        print(f"  [{k}/{len(names)}] {name} done in {summary[name]['seconds']} s")
    write_png(args.out / "demo.png", stack(rows))
    atomic_write_bytes(args.out / "summary.json", json.dumps(summary, indent=1).encode())
    print(f"wrote {args.out / 'demo.png'} (input | standard | corrected, seen from the side)")
    return 0
