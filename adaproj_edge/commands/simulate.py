"""``adaproj simulate``: see what a viewer off to the side sees, plain vs corrected."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from adaproj_edge.commands._inputs import (
    content_map,
    grid_arg,
    load_maps,
    load_surface,
    vector_arg,
)
from adaproj_edge.content.builtin import poster, poster_mask
from adaproj_edge.content.contentmap import DEFAULT_THRESHOLD, ContentMap
from adaproj_edge.fileio import read_image, write_png
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.render.project import Projection, project
from adaproj_edge.render.sheet import row
from adaproj_edge.render.viewer import DEFAULT_VIEWER, view, viewer_for
from adaproj_edge.warp.engine import MODES, WarpSettings
from adaproj_edge.warp.warpmap import Grid


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "simulate",
        help="picture of the input, the plain and the corrected projection as a viewer sees them",
    )
    p.add_argument(
        "--surface", required=True, help="Surface file (.npz) or a built-in surface name"
    )
    p.add_argument("--image", type=Path, help="the content (default: the built-in poster)")
    p.add_argument("--mask", type=Path, help="user mask: PNG, white = important")
    p.add_argument("--content-map", type=Path, help="content map PNG (default: saliency)")
    p.add_argument("--mode", choices=MODES, default="content", help="the corrected projection")
    p.add_argument("--grid", type=grid_arg, default=Grid())
    p.add_argument(
        "--viewer",
        type=vector_arg,
        default=DEFAULT_VIEWER,
        help="viewer position X,Y,Z in metres, projector frame (default %(default)s)",
    )
    p.add_argument("--out", type=Path, required=True, help="picture to write (PNG)")
    p.set_defaults(run=run)


def simulate(
    surface: Surface,
    image: NDArray[np.uint8],
    cmap: ContentMap | None,
    settings: WarpSettings,
    eye: tuple[float, float, float],
) -> tuple[NDArray[np.uint8], Projection, Projection]:
    """The picture input | standard | corrected, and the two projections."""
    plain = project(surface, image, None, WarpSettings(mode="standard", grid=settings.grid))
    corrected = project(surface, image, cmap, settings)
    viewer = viewer_for(surface, eye)
    picture = row(
        [image, view(surface, plain.frame, viewer), view(surface, corrected.frame, viewer)],
        ["input", "standard projector", f"adaproj ({settings.mode})"],
    )
    return picture, plain, corrected


def run(args: argparse.Namespace) -> int:
    surface = load_surface(args.surface)
    image = poster() if args.image is None else read_image(args.image)
    mask, given = load_maps(image, args.mask, args.content_map)
    if args.image is None and mask is None:
        mask = poster_mask((image.shape[1], image.shape[0]))
    cmap = content_map(image, mask, given, DEFAULT_THRESHOLD, saliency=args.mode == "content")
    settings = WarpSettings(mode=args.mode, grid=args.grid)
    picture, _, _ = simulate(surface, image, cmap, settings, args.viewer)
    write_png(args.out, picture)
    print(f"wrote {args.out}")
    return 0
