"""The part of a replay summary compared with the committed goldens, and how.

Decisions (states, events, counters, which update did what) must match exactly;
outputs (warp vertices, frame means) within tolerances that hold across machines.
Written only by ``tools/make_app_goldens.py``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from adaproj_edge.session.reader import Scan, iter_records

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
SESSIONS = FIXTURES / "sessions"
APP = FIXTURES / "app"
GOLDEN = APP / "golden.json"
FAULTS_SESSION = APP / "faults.mcap"
PUSH_SESSION = APP / "push.mcap"
PUSH_CLIP_SESSION = APP / "push-clip.mcap"
COUNTERS = (
    "content_free",
    "content_aware",
    "cache_hits",
    "cache_misses",
    "estimates",
    "skipped_frames",
    "frames_shown",
)
CLIP = ("clip_frames", "clip_skipped", "clip_late", "clip_errors")
LINK = ("requests", "refused", "ignored", "content_activations", "replies", "tx_mismatches")
PROBE_TOL_PX = 0.5
ITERATION_TOL = 1
MEAN_TOL = 1.0


def session_paths() -> dict[str, Path]:
    """Every committed session the app is replayed on."""
    out = {p.stem: p for p in sorted(SESSIONS.glob("*.mcap"))}
    out["faults"] = FAULTS_SESSION
    out["push"] = PUSH_SESSION
    out["push-clip"] = PUSH_CLIP_SESSION
    return out


def golden_view(summary: dict[str, Any]) -> dict[str, Any]:
    return {
        "states": summary["states"],
        "events": [{k: v for k, v in e.items() if k != "message"} for e in summary["events"]],
        "counters": {k: summary["counters"][k] for k in COUNTERS},
        "updates": [
            {k: u[k] for k in ("t_s", "reason", "kind", "cache_hit", "iterations", "probes")}
            for u in summary["updates"]
        ],
        "frames": [
            {k: f[k] for k in ("t_s", "kind", "faults", "mean_bgr")} for f in summary["frames"]
        ],
        "link": {k: summary["link"][k] for k in LINK},
        "clip": {k: summary["counters"].get(k, 0) for k in CLIP},
    }


def differences(got: dict[str, Any], want: dict[str, Any]) -> list[str]:
    """Field-by-field differences beyond tolerance (empty: the same)."""
    out: list[str] = []
    for key in ("states", "events", "counters"):
        if got[key] != want[key]:
            out.append(f"{key}: {got[key]} != {want[key]}")
    if "link" in want and got["link"] != want["link"]:  # goldens older than the link replay
        out.append(f"link: {got['link']} != {want['link']}")
    if "clip" in want and got["clip"] != want["clip"]:  # goldens older than clip playback
        out.append(f"clip: {got['clip']} != {want['clip']}")
    if len(got["updates"]) != len(want["updates"]):
        out.append(f"updates: {len(got['updates'])} != {len(want['updates'])}")
    for i, (g, w) in enumerate(zip(got["updates"], want["updates"], strict=False)):
        for k in ("t_s", "reason", "kind", "cache_hit"):
            if g[k] != w[k]:
                out.append(f"updates[{i}].{k}: {g[k]} != {w[k]}")
        if abs(g["iterations"] - w["iterations"]) > ITERATION_TOL:
            out.append(f"updates[{i}].iterations: {g['iterations']} != {w['iterations']}")
        for j, (a, b) in enumerate(zip(g["probes"], w["probes"], strict=True)):
            if (a is None) != (b is None) or (
                a is not None
                and b is not None
                and max(abs(a[0] - b[0]), abs(a[1] - b[1])) > PROBE_TOL_PX
            ):
                out.append(f"updates[{i}].probes[{j}]: {a} != {b}")
    if len(got["frames"]) != len(want["frames"]):
        out.append(f"frames: {len(got['frames'])} != {len(want['frames'])}")
    for i, (g, w) in enumerate(zip(got["frames"], want["frames"], strict=False)):
        for k in ("t_s", "kind", "faults"):
            if g[k] != w[k]:
                out.append(f"frames[{i}].{k}: {g[k]} != {w[k]}")
        if max(abs(a - b) for a, b in zip(g["mean_bgr"], w["mean_bgr"], strict=True)) > MEAN_TOL:
            out.append(f"frames[{i}].mean_bgr: {g['mean_bgr']} != {w['mean_bgr']}")
    return out


def push_meta(path: Path) -> dict[str, Any]:
    """What a push session's metadata says was pushed (``push``: name, bytes, time...)."""
    scan = Scan()
    for _ in iter_records(path, topics=set(), scan=scan):
        pass
    meta: dict[str, Any] = json.loads(scan.metadata["session"]["push"])
    return meta
