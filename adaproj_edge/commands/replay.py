"""``adaproj replay``: the device runtime on a recorded session, on a virtual clock."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adaproj_edge.commands._outputs import check_output_dir
from adaproj_edge.resources import default_session

if TYPE_CHECKING:
    from adaproj_edge.app.settings import AppSettings

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
        "has one, the handheld section: jitter, drift, upright, motion-to-photon) and "
        "contact_sheet.png; simulated sessions also get handheld.png, the content's "
        "motion on the surface with stabilisation on and off.",
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
    p.add_argument(
        "--no-stabilise",
        action="store_true",
        help="show each rendered frame as it is at every refresh (no stabilisation margin, "
        "no correction for the hand's motion)",
    )
    p.add_argument(
        "--compensate",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="even out the projector's light over the picture (a gain made from each "
        "pose's surface; each update in summary.json gets its figures; default: off)",
    )
    p.add_argument(
        "--calibration",
        default=None,
        metavar="FILE.toml",
        help="replay with this calibration instead of the session's (e.g. one solved by "
        "`adaproj calibrate`)",
    )
    p.set_defaults(run=run)


def replay_settings(args: argparse.Namespace) -> AppSettings:
    """The runtime's settings the options ask for (cache, warm starts, the gain)."""
    from adaproj_edge.app.settings import AppSettings
    from adaproj_edge.render.photometry import PhotometrySettings

    settings = replace(AppSettings(), caching=not args.no_cache, warm_start=not args.no_warm_start)
    if args.compensate:
        settings = replace(settings, photometry=PhotometrySettings(scale=settings.map_scale))
    return settings


def run(args: argparse.Namespace) -> int:
    if args.out is not None:
        check_output_dir(args.out, "output folder")

    from adaproj_edge.app.replay import ReplayOptions, replay_session
    from adaproj_edge.geometry.calibration import Calibration

    settings = replay_settings(args)
    cal = Calibration.load(args.calibration) if args.calibration else None
    options = ReplayOptions(
        settings,
        all_frames=args.all_frames,
        score=not args.no_score,
        stabilise=not args.no_stabilise,
        calibration=cal,
    )
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
    if c.get("clip_frames"):
        print(
            f"  clip: {c['clip_frames']} frames shown, {c['clip_skipped']} skipped, "
            f"{c['clip_late']} late, {c['clip_errors']} did not decode"
        )
    for d in s["distortion"]:
        print(
            f"  t={d['t_s']:.2f}s angle error shown {d['shown_angle_error']:.4f} "
            f"(warp from the true surface {d['truth_angle_error']:.4f}, "
            f"plain projector {d['plain_angle_error']:.4f})"
        )
    h = s["handheld"]
    mtp = h["motion_to_photon_ms"]
    line = f"  display: {h['refreshes']} refreshes ({h['missed']} late)"
    if mtp["n"]:
        line += f", IMU sample -> display {mtp['median']} ms median, {mtp['p95']} ms p95"
    print(line)
    if h.get("jitter_mm_rms") is not None:
        print(
            f"  on the surface: jitter {h['jitter_mm_rms']} mm RMS (not stabilised "
            f"{h['jitter_off_mm_rms']} mm), upright within {h['upright_error_deg_max']} deg"
            + (f", drift {h['drift_mm_10s']} mm over 10 s" if h.get("drift_mm_10s") else "")
        )
    damage = s["session_file"]["damage"]
    if damage is not None:  # (replay_session logs it at debug level only: said once, here)
        print(f"adaproj replay: warning: {Path(args.session).name}: {damage}", file=sys.stderr)
    if args.out:
        out = Path(args.out)
        written = ["summary.json", "contact_sheet.png", "handheld.png", "frames"]
        there = [str(out / name) for name in written if (out / name).exists()]
        print(f"wrote {', '.join(there)}")
    else:
        log.debug("%s", json.dumps(s["counters"]))
    return 0
