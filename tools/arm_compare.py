"""Compare two `adaproj replay --out` folders made on different machines (tools/arm_check).

Decisions and figures must agree; only what measures the machine may differ:
- ``summary.json``: every field but the machine's speed (``timings_ms``, keys ending in
  ``_ms``, ``rss_mb``, the refreshes counted as missed) is compared: strings, booleans and integers
  exactly, floats to ``--rel`` relative (the JSON rounds them to 4-5 digits; two CPUs
  round the last bit of a sum differently, which can move a printed digit by one);
- every frame PNG: the same size, and pixels differing by at most ``--grey`` levels on
  at most ``--pixels`` of the frame (interpolation weights rounded differently move a
  pixel on an edge by a level or two).

Exit 0 when both agree, 1 with one line per difference otherwise, 2 on bad input.

Usage: python tools/arm_compare.py HERE_DIR THERE_DIR
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

# what measures the machine, not what the app decided: stage times, memory, and the
# display refreshes a replay counts as missed (a refresh whose measured computation
# overran its lead: an emulated CPU misses them all)
TIMING_KEYS = {"timings_ms", "rss_mb", "motion_to_frame_ms", "refresh_misses", "missed"}


def is_timing(key: str) -> bool:
    return key in TIMING_KEYS or key.endswith("_ms")


def compare_json(a: Any, b: Any, path: str, rel: float, out: list[str]) -> int:
    """Append a line per difference between ``a`` and ``b`` to ``out``; the count of
    values compared."""
    if isinstance(a, dict) and isinstance(b, dict):
        n = 0
        for key in sorted(set(a) | set(b)):
            if is_timing(key):
                continue
            if key not in a or key not in b:
                out.append(f"{path}/{key}: only in {'the second' if key not in a else 'the first'}")
                continue
            n += compare_json(a[key], b[key], f"{path}/{key}", rel, out)
        return n
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: {len(a)} items against {len(b)}")
            return 1
        return sum(
            compare_json(x, y, f"{path}[{i}]", rel, out)
            for i, (x, y) in enumerate(zip(a, b, strict=True))
        )
    if isinstance(a, float) or isinstance(b, float):
        if not (isinstance(a, (int, float)) and isinstance(b, (int, float))):
            out.append(f"{path}: {a!r} against {b!r}")
        elif not math.isclose(a, b, rel_tol=rel, abs_tol=rel * 1e-3):
            out.append(f"{path}: {a!r} against {b!r}")
        return 1
    if a != b:
        out.append(f"{path}: {a!r} against {b!r}")
    return 1


def compare_frames(here: Path, there: Path, grey: int, pixels: float, out: list[str]) -> int:
    """Append a line per frame that differs beyond the tolerance; the count compared."""
    names = sorted(p.relative_to(here) for p in here.rglob("*.png"))
    others = sorted(p.relative_to(there) for p in there.rglob("*.png"))
    if names != others:
        out.append(f"frames: {len(names)} pictures against {len(others)} (names differ)")
        return 0
    for name in names:
        a = cv2.imread(str(here / name), cv2.IMREAD_UNCHANGED)
        b = cv2.imread(str(there / name), cv2.IMREAD_UNCHANGED)
        if a is None or b is None or a.shape != b.shape:
            out.append(f"{name}: unreadable or of another size")
            continue
        diff = np.abs(a.astype(np.int16) - b.astype(np.int16))
        frac = float(np.mean(np.any(diff > 0, axis=-1) if diff.ndim == 3 else diff > 0))
        worst = int(diff.max())
        line = f"{name}: {100 * frac:.4f} % of pixels differ, by at most {worst} levels"
        print(f"  {line}")
        if worst > grey or frac > pixels:
            out.append(line)
    return len(names)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("here", type=Path)
    p.add_argument("there", type=Path)
    p.add_argument("--rel", type=float, default=2e-3, help="floats' relative tolerance")
    p.add_argument("--grey", type=int, default=8, help="most grey levels a pixel may move")
    p.add_argument("--pixels", type=float, default=1e-3, help="most fraction of pixels moved")
    args = p.parse_args()
    try:
        a = json.loads((args.here / "summary.json").read_text())
        b = json.loads((args.there / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        print(f"arm_compare: cannot read both summaries: {exc}", file=sys.stderr)
        return 2
    out: list[str] = []
    n = compare_json(a, b, "summary", args.rel, out)
    f = compare_frames(args.here, args.there, args.grey, args.pixels, out)
    print(f"summary.json: {n} non-timing values compared; {f} pictures compared")
    for line in out:
        print(f"DIFFERS {line}")
    print("the same results" if not out else f"{len(out)} differences")
    return 0 if not out else 1


if __name__ == "__main__":
    sys.exit(main())
