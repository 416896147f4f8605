"""``adaproj replay``: the device runtime on a recorded session, on a virtual clock."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from adaproj_edge.commands._outputs import check_output_dir
from adaproj_edge.resources import default_session

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    p = sub.add_parser(
        "replay",
        help="replay a session through the device runtime; write frames and a summary",
        description="Feed a recorded session (.mcap) through the same runtime the device "
        "runs, on a virtual clock (as fast as it computes, same result every time). "
        "Writes a sample of the projected frames (every frame with --all-frames), "
        "summary.json (events, states, warps computed, cache hits, stage timings, "
        "motion-to-frame latency, distortion against the ground truth when the session "
        "has one) and contact_sheet.png.",
    )
    p.add_argument(
        "session",
        nargs="?",
        default=str(default_session()),
        help="session file (.mcap); default: the committed cylinder recording",
    )
    p.add_argument("--out", default=None, help="output directory (default: none written)")
    p.add_argument("--all-frames", action="store_true", help="write every projected frame")
    p.add_argument("--no-cache", action="store_true", help="turn the per-pose warp cache off")
    p.add_argument("--no-warm-start", action="store_true", help="refine from scratch each time")
    p.add_argument("--no-score", action="store_true", help="skip the ground-truth scoring")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.out is not None:
        check_output_dir(args.out, "output folder")

    from adaproj_edge.app.replay import ReplayOptions, replay_session
    from adaproj_edge.app.settings import AppSettings

    settings = replace(AppSettings(), caching=not args.no_cache, warm_start=not args.no_warm_start)
    options = ReplayOptions(settings, all_frames=args.all_frames, score=not args.no_score)
    s = replay_session(args.session, args.out, options)
    c = s["counters"]
    print(
        f"{s['session']}: {s['duration_s']:.1f} s, states "
        + " -> ".join(st for _, st in s["states"])
        + f"; warps: {c['content_free']} content-free, {c['content_aware']} content-aware, "
        f"{c['cache_hits']} cache hits; {c['frames_shown']} frames shown"
    )
    link = s["link"]
    if link["rx_bytes"]:
        dropped = sum(link["dropped_frames"].values())
        print(
            f"  serial link: {link['requests']} requests ({link['refused']} refused, "
            f"{dropped} bad frames dropped), {link['content_activations']} content "
            f"activations, {link['tx_mismatches']} replies differ from the recording"
        )
    for d in s["distortion"]:
        print(
            f"  t={d['t_s']:.2f}s angle error shown {d['shown_angle_error']:.4f} "
            f"(warp from the true surface {d['truth_angle_error']:.4f}, "
            f"plain projector {d['plain_angle_error']:.4f})"
        )
    damage = s["session_file"]["damage"]
    if damage is not None:
        print(f"adaproj replay: warning: {Path(args.session).name}: {damage}", file=sys.stderr)
    if args.out:
        print(f"wrote {args.out}/summary.json, {args.out}/contact_sheet.png, {args.out}/frames/")
    else:
        log.debug("%s", json.dumps(s["counters"]))
    return 0
