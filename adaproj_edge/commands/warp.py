"""``adaproj warp``: the pre-warp for one image on one surface."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from adaproj_edge.commands._inputs import content_map, grid_arg, load_maps, load_surface
from adaproj_edge.commands._outputs import check_image_file, check_output_file


def register(sub: argparse._SubParsersAction[Any]) -> None:
    from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD
    from adaproj_edge.warp.engine import ALTERNATIONS, MODES
    from adaproj_edge.warp.warpmap import Grid

    p = sub.add_parser(
        "warp",
        help="compute the pre-warp of an image for a surface",
        description=(
            "Compute the warp (grid_uv, image_xy and the per-pixel map_xy) that makes IMAGE "
            "look pasted onto the surface, and optionally the projector frame."
        ),
    )
    p.add_argument(
        "--surface",
        required=True,
        help="Surface file (.npz) or a built-in surface name (see `adaproj surface --help`)",
    )
    p.add_argument("--image", type=Path, required=True, help="the content (PNG or JPEG)")
    p.add_argument("--mask", type=Path, help="user mask: PNG, white = important")
    p.add_argument(
        "--content-map",
        type=Path,
        help="content map PNG (white = salient); default: the saliency model, max the mask",
    )
    p.add_argument("--mode", choices=MODES, default="content")
    p.add_argument(
        "--grid", type=grid_arg, default=Grid(), help="cells, e.g. 20x20 (default %(default)s)"
    )
    p.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD, help="T of eq. 5")
    p.add_argument(
        "--alternation",
        choices=ALTERNATIONS,
        default="ours",
        help="content-aware step: ours (default) or the paper's as written (for comparison)",
    )
    p.add_argument("--out", type=Path, required=True, help="warp file to write (.npz)")
    p.add_argument("--frame", type=Path, help="also write the projector frame (.png or .jpg)")
    p.add_argument(
        "--compensate",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="even out the projector's light over the picture: the frame carries a "
        "brightness gain made from the surface, and the report its figures (default: off)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_output_file(args.out, "warp file")
    if args.frame is not None:
        check_image_file(args.frame, "frame")

    from adaproj_edge.fileio import read_image, write_image
    from adaproj_edge.render.project import show
    from adaproj_edge.warp.engine import WarpSettings
    from adaproj_edge.warp.fallback import chain_of, keystone_surface
    from adaproj_edge.warp.planner import compute_warp
    from adaproj_edge.warp.quality import measure

    settings = WarpSettings(
        mode=args.mode, grid=args.grid, threshold=args.threshold, alternation=args.alternation
    )
    surface = load_surface(args.surface)
    image = read_image(args.image)
    mask, given = load_maps(image, args.mask, args.content_map)
    cmap = content_map(image, mask, given, args.threshold, saliency=args.mode == "content")
    h, w = image.shape[:2]
    t0 = time.perf_counter()
    warp = compute_warp(surface, (w, h), cmap, settings)
    seconds = time.perf_counter() - t0
    step, down = chain_of(warp)
    # a keystone is drawn through the plane it was made on, every other warp through
    # the surface's own points
    result = show(keystone_surface(surface) if step == "keystone" else surface, image, warp)
    result.warp.save(args.out)
    frame, photometry = result.frame, None
    if args.compensate:
        import numpy as np

        from adaproj_edge.render.photometry import apply_gain, gain_map

        gain = gain_map(surface, picture=np.isfinite(result.map_xy[..., 0]))
        frame, photometry = apply_gain(frame, gain), gain.summary()
    if args.frame is not None:
        write_image(args.frame, frame)
    overall, salient = measure(
        result.map_xy, surface, None if cmap is None else cmap.full_size() >= cmap.threshold
    )
    report: dict[str, Any] = {
        "mode": settings.mode,
        "grid": str(settings.grid),
        "iterations": result.warp.meta["iterations"],
        "time_s": round(seconds, 4),
        "distortion": overall.as_dict(),
    }
    if salient is not None:
        report["distortion_salient"] = salient.as_dict()
    # where the warp chain ended (as on the device): content-aware, content-free,
    # repaired or keystone, and the steps gone down from with their reasons
    report["step"] = step
    if down:
        report["down"] = [{"step": s, "reason": r} for s, r in down]
    if photometry is not None:
        # the light over the picture before and after, as the surface predicts it
        report["photometry"] = photometry
    print(json.dumps(report, indent=1))
    return 0
