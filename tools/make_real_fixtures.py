#!/usr/bin/env python3
"""The depth PNGs of ``tests/fixtures/real/`` from their source files: each converted to
uint16 millimetres (0 = no depth) and nothing else (no crop, filter or fill).

The sources are the files Open3D redistributes (``examples/test_data/RGBD/other_formats/``
of ``isl-org/Open3D``, June 2020; see ``tests/fixtures/real/README.md``), read from a local
copy; nothing is downloaded. The JSON beside each frame (intrinsics, regions, source) is
written by hand.

    .venv/bin/python tools/make_real_fixtures.py --tum TUM_depth.png --nyu NYU_depth.pgm \\
        --sun SUN_depth.png [--out tests/fixtures/real]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

OUT = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "real"


def read16(path: Path) -> NDArray[np.uint16]:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint16 or img.ndim != 2:
        raise SystemExit(f"{path}: not a single-channel 16-bit image")
    return np.asarray(img, np.uint16)


def tum_mm(raw: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """TUM RGB-D: 5000 per metre."""
    return np.rint(raw.astype(np.float64) / 5.0).astype(np.uint16)


def nyu_mm(raw: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """NYU Depth V2 raw Kinect disparity (big-endian PGM; OpenCV reads it byte-swapped):
    metres = 351.3 / (1092.5 - d) (the NYU toolbox), d >= 1092 (2047: no return) -> 0."""
    d = raw.byteswap().astype(np.float64)
    ok = (d > 0) & (d < 1092)
    metres = np.where(ok, 351.3 / np.where(ok, 1092.5 - d, 1.0), 0.0)
    return np.rint(metres * 1e3).astype(np.uint16)


def sun3d_mm(raw: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """SUN3D: millimetres rotated by 3 bits."""
    return ((raw >> 3) | (raw << 13)).astype(np.uint16)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tum", type=Path, required=True, help="TUM_depth.png")
    ap.add_argument("--nyu", type=Path, required=True, help="NYU_depth.pgm")
    ap.add_argument("--sun", type=Path, required=True, help="SUN_depth.png")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    for name, path, convert in (
        ("tum_desk", args.tum, tum_mm),
        ("nyu_basement", args.nyu, nyu_mm),
        ("sun3d_corridor", args.sun, sun3d_mm),
    ):
        mm = convert(read16(path))
        cv2.imwrite(str(args.out / f"{name}.png"), mm)
        valid = mm[mm > 0]
        print(
            f"{name}: {mm.shape[1]}x{mm.shape[0]}, {100 * valid.size / mm.size:.1f} % valid, "
            f"median {np.median(valid):.0f} mm"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
