#!/usr/bin/env python3
"""Time the saliency model at the device's resolution, next to the numpy reference.

Everything runs on one core: onnxruntime with ``intra_op_num_threads=1``, numpy's BLAS
limited to one thread. The content is a 1280x800 photograph (the projector's
resolution); the model sees it at its input size (120x192 for the default model).

Usage::

    .venv/bin/python tools/bench_saliency.py [--model M.onnx] [--runs 50] [--sweep]

``--sweep`` also builds (in memory) and times the GBVS graph at other working
resolutions, the evidence for the default's choice.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from adaproj_edge.content import gbvs
from adaproj_edge.content.contentmap import content_map_for
from adaproj_edge.content.model import DEFAULT_MODEL_PATH, SaliencyModel, to_input
from adaproj_edge.threads import apply_thread_policy

DEVICE = (1280, 800)


def device_image() -> np.ndarray:
    """A photograph at the projector's resolution (scikit-image's coffee, or noise)."""
    try:
        import skimage.data

        rgb = skimage.data.coffee()
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
    except ImportError:
        bgr = np.random.default_rng(0).integers(0, 256, (400, 600, 3), dtype=np.uint8)
    return np.asarray(cv2.resize(bgr, DEVICE, interpolation=cv2.INTER_CUBIC), dtype=np.uint8)


def timed(fn: Callable[[], Any], runs: int) -> tuple[float, float, float]:
    """(min, median, 90th percentile) wall time of ``fn`` in ms, after two warm-ups."""
    fn()
    fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000.0)
    times.sort()
    return times[0], statistics.median(times), times[int(0.9 * (len(times) - 1))]


def row(label: str, stats: tuple[float, float, float]) -> None:
    lo, med, p90 = stats
    print(f"  {label:<50} min {lo:6.2f}  median {med:6.2f}  p90 {p90:6.2f} ms")


def sweep(image: np.ndarray, runs: int) -> None:
    path = Path(__file__).resolve().parent / "build_saliency_model.py"
    spec = importlib.util.spec_from_file_location("build_saliency_model", path)
    if spec is None or spec.loader is None:
        return
    builder = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(builder)
    print("working resolution sweep (GBVS graph built in memory, same parameters otherwise):")
    with tempfile.TemporaryDirectory() as tmp:
        for map_size in ((10, 16), (12, 20), (15, 24), (20, 32), (25, 40)):
            params = dataclasses.replace(gbvs.GBVSParams(), map_size=map_size)
            file = Path(tmp) / f"m{map_size[0]}.onnx"
            file.write_bytes(builder.model_bytes(params))
            m = SaliencyModel(file)
            x = to_input(image, m.input_size)
            h, w = params.input_size
            label = f"graph {map_size[1]}x{map_size[0]} (n={params.n_nodes}), input {w}x{h}"
            row(label, timed(lambda m=m, x=x: m.run(x), runs))


def main(argv: list[str] | None = None) -> int:
    apply_thread_policy(1)  # one thread: the figures are per core
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH)
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--sweep", action="store_true", help="time other working resolutions")
    args = parser.parse_args(argv)

    image = device_image()
    model = SaliencyModel(args.model, threads=1)
    x = to_input(image, model.input_size)
    h, w = model.input_size
    print(f"content {DEVICE[0]}x{DEVICE[1]}, model {args.model.name} input {w}x{h}, one thread")
    row("onnxruntime: model only", timed(lambda: model.run(x), args.runs))
    row("onnxruntime: resize + model + normalise", timed(lambda: model.predict(image), args.runs))
    cmap = timed(lambda: content_map_for(image, None, model), args.runs)
    row("content map (predict + coarse map)", cmap)
    if model.input_size == gbvs.GBVSParams().input_size:
        ref = max(3, args.runs // 10)
        row(f"numpy reference (same input, {ref} runs)", timed(lambda: gbvs.saliency(x[0]), ref))
    if args.sweep:
        sweep(image, args.runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
