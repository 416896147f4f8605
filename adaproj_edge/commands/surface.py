"""``adaproj surface``: write a built-in analytic surface as a Surface file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from adaproj_edge.commands._outputs import check_output_file
from adaproj_edge.errors import InputError


def register(sub: argparse._SubParsersAction[Any]) -> None:
    from adaproj_edge.geometry.analytic import SURFACES

    p = sub.add_parser(
        "surface",
        help="ray-cast a built-in analytic surface into a Surface file",
        description="Built-in surfaces: " + ", ".join(SURFACES),
    )
    p.add_argument("name", choices=list(SURFACES), metavar="NAME", help="surface name")
    p.add_argument("--out", type=Path, required=True, help="Surface file to write (.npz)")
    p.add_argument(
        "--step", type=int, default=1, help="sample every STEP-th projector pixel (default 1)"
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from adaproj_edge.geometry.analytic import simulate_surface
    from adaproj_edge.geometry.projector import Projector

    p = Projector.default()
    most = min(p.width, p.height) - 1  # at least 2 x 2 points
    if not 1 <= args.step <= most:
        raise InputError(
            f"--step must be between 1 and {most} (the frame is {p.width}x{p.height} "
            f"pixels), got {args.step}"
        )
    check_output_file(args.out, "surface file")
    surface = simulate_surface(args.name, p, step=args.step)
    surface.save(args.out)
    h, w = surface.shape
    print(f"wrote {args.out}: {args.name}, {w}x{h} points, {surface.valid_fraction:.0%} valid")
    return 0
