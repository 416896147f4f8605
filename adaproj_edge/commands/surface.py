"""``adaproj surface``: write a built-in analytic surface as a Surface file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from adaproj_edge.geometry.analytic import SURFACES, simulate_surface


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "surface",
        help="ray-cast a built-in analytic surface into a Surface file",
        description="Built-in surfaces: " + ", ".join(SURFACES),
    )
    p.add_argument("name", choices=sorted(SURFACES), metavar="NAME", help="surface name")
    p.add_argument("--out", type=Path, required=True, help="Surface file to write (.npz)")
    p.add_argument(
        "--step", type=int, default=1, help="sample every STEP-th projector pixel (default 1)"
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    surface = simulate_surface(args.name, step=max(1, args.step))
    surface.save(args.out)
    h, w = surface.shape
    print(f"wrote {args.out}: {args.name}, {w}x{h} points, {surface.valid_fraction:.0%} valid")
    return 0
