"""What a replay writes: a sample of the projected frames, ``summary.json``, the
contact sheet and (simulated sessions) ``handheld.png``, the content's motion on the
surface with stabilisation on and off."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from adaproj_edge.app.telemetry import Telemetry
from adaproj_edge.arrays import Image
from adaproj_edge.render.sheet import row, stack, titled

SAMPLE_FRAMES = 12


class FrameSampler:
    """Frames the runtime showed: a checksum of each, and given an output directory
    ``out``, an evenly spaced sample (PNG in memory, bounded) and every frame written to
    ``out/frames`` on request."""

    def __init__(self, out: Path | None, all_frames: bool) -> None:
        self.out = out
        self.all = all_frames
        self.sample: list[tuple[int, int, bytes, Image, str]] = []
        self.stride = 1
        self.count = 0
        self.checksums: list[dict[str, Any]] = []
        self.t0 = 0
        self.side_views: list[tuple[list[Image], list[str]]] = []
        self.handheld_plot: Image | None = None

    def __call__(self, t_ns: int, frame: Image, info: dict[str, Any]) -> None:
        """Take the frame shown at ``t_ns``: a checksum of every frame (mean BGR) and, with
        an output directory, PNGs of an evenly spaced sample (its spacing doubles
        whenever it grows past twice ``SAMPLE_FRAMES``) and, when asked, every frame
        written to ``out/frames``."""
        self.count += 1
        faults = info["faults"]
        caption = f"{(t_ns - self.t0) / 1e9:.2f}s {info['kind']}"
        caption += " [" + ",".join(faults) + "]" if faults else ""
        mean = [round(float(x), 2) for x in cv2.mean(frame)[:3]]
        self.checksums.append(
            {"t_ns": t_ns, "kind": info["kind"], "mean_bgr": mean, "faults": faults}
        )
        if self.out is None:  # no outputs: a sample would never be written (and costs
            return  # ~11 MB of PNGs and thumbnails held, a PNG encoding now and then)
        if self.all:
            cv2.imwrite(str(self.out / "frames" / f"{self.count:05d}.png"), frame)
        if (self.count - 1) % self.stride:
            return
        _, png = cv2.imencode(".png", frame)
        small = cv2.resize(
            frame, (frame.shape[1] // 4, frame.shape[0] // 4), interpolation=cv2.INTER_AREA
        )
        self.sample.append(
            (self.count, t_ns, bytes(png.tobytes()), np.asarray(small, np.uint8), caption)
        )
        if len(self.sample) > 2 * SAMPLE_FRAMES:
            self.stride *= 2
            self.sample = [x for x in self.sample if (x[0] - 1) % self.stride == 0]

    def picked(self) -> list[tuple[int, int, bytes, Image, str]]:
        """At most ``SAMPLE_FRAMES`` of the sample, evenly spaced: (count, t_ns, PNG, quarter-size
        frame, caption) each."""
        n = len(self.sample)
        if n <= SAMPLE_FRAMES:
            return self.sample
        idx = np.unique(np.linspace(0, n - 1, SAMPLE_FRAMES).round().astype(int))
        return [self.sample[i] for i in idx]


def rel_s(t_ns: int, t0: int) -> float:
    """Seconds from ``t0`` to ``t_ns`` (both ns), rounded to 0.1 ms."""
    return round((t_ns - t0) / 1e9, 4)


def timed(items: Iterable[dict[str, Any]], t0: int) -> list[dict[str, Any]]:
    """``items`` with ``t_ns`` replaced by ``t_s``, seconds from the session start."""
    return [
        {"t_s": rel_s(x["t_ns"], t0), **{k: v for k, v in x.items() if k != "t_ns"}} for x in items
    ]


def summary(
    session: str,
    telemetry: Telemetry,
    now_ns: int,
    frames: FrameSampler,
    t0: int,
    **sections: Any,
) -> dict[str, Any]:
    """The replay's ``summary.json`` (times in seconds from the session start ``t0``):
    states, events, counters, updates, frame checksums, stage timings, motion-to-frame
    latency, then ``sections`` as given."""
    t = telemetry
    lat = np.asarray(t.latencies_ms)
    return {
        "session": session,
        "duration_s": rel_s(now_ns, t0),
        "states": [[rel_s(ns, t0), s] for ns, s in t.states],
        "events": timed(t.events, t0),
        "counters": dict(t.counters),
        "updates": timed(t.updates, t0),
        "frames": timed(frames.checksums, t0),
        "timings_ms": t.times.summary(),
        "motion_to_frame_ms": {
            "n": int(lat.size),
            "median": round(float(np.median(lat)), 2) if lat.size else None,
            "p95": round(float(np.percentile(lat, 95)), 2) if lat.size else None,
        },
        **sections,
    }


OUTPUTS = ("summary.json", "contact_sheet.png", "handheld.png")


def clear_outputs(out: Path) -> None:
    """Make ``out`` ready for a replay's outputs: the files an earlier replay wrote there
    (the summary, the contact sheet, ``frames/*.png``) are removed, nothing else."""
    frames = out / "frames"
    frames.mkdir(parents=True, exist_ok=True)
    for old in frames.glob("*.png"):
        old.unlink()
    for name in OUTPUTS:
        (out / name).unlink(missing_ok=True)


SHEET_LEGEND = (
    "Frames the device projected, by seconds from the start. plain: no pre-warp;",
    "content-free: warped for the surface alone; content-aware: refined for the content.",
)
SIDE_LEGEND = (
    "Below, seen by a viewer beside the projector: a plain projector | what adaproj showed.",
    "Grey: the surface where the frame is dark.",
)


def write_outputs(out: Path, summary: dict[str, Any], frames: FrameSampler) -> None:
    """Write ``summary.json``, the sampled frames (``frames/``) and
    ``contact_sheet.png`` into ``out``."""
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    picked = frames.picked()
    for n, t_ns, png, _, _ in picked:
        name = f"sample_{n:05d}_{(t_ns - frames.t0) / 1e9:07.3f}s.png"
        (out / "frames" / name).write_bytes(png)
    rows = [
        row([p[3] for p in picked[i : i + 4]], [p[4] for p in picked[i : i + 4]], 200)
        for i in range(0, len(picked), 4)
    ]
    side = [row(images, captions, 300) for images, captions in frames.side_views]
    legend = (SHEET_LEGEND if rows else ()) + (SIDE_LEGEND if side else ())
    if rows or side:
        cv2.imwrite(str(out / "contact_sheet.png"), titled(stack(rows + side), legend))
    if frames.handheld_plot is not None:
        cv2.imwrite(str(out / "handheld.png"), frames.handheld_plot)
