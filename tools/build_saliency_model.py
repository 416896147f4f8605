#!/usr/bin/env python3
"""Build the default saliency model, ``models/gbvs_saliency.onnx``, from GBVSParams.

The graph computes the quantities of the numpy reference ``adaproj_edge.content.gbvs.saliency``
in float32 with the constant arrays of ``adaproj_edge.content.gbvs.constants``; the
features node for node, the two graph stages with the same sums in a cheaper order
(the reference stays the readable definition; the test suite holds the two within
1e-3):

- activation: ``sum_j |x_i - x_j| F_ij = 2 sum_j max(x_i, x_j) F_ij - x_i sum_j F_ij -
  (F x)_i``: one broadcast ``Max`` and a batched matrix-vector product instead of
  ``Sub``, ``Abs``, ``Mul`` and ``ReduceSum`` over the (maps, n, n) array; ``x`` is
  shifted to a minimum of 0 per map first (the differences do not change, and the
  terms stay no larger than the map's range);
- every product with a falloff (``F x``, ``A F_norm``) as its two separable factors
  (``gbvs.falloff_factors``).

The output is byte-for-byte repeatable: the same parameters give the same file (the test
suite checks the committed model).

Usage::

    .venv/bin/python tools/build_saliency_model.py [--out models/gbvs_saliency.onnx]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from adaproj_edge.content import gbvs
from adaproj_edge.content.model import CONTRACT, CONTRACT_KEY, INPUT_NAME, OUTPUT_NAME
from adaproj_edge.threads import apply_thread_policy

OPSET = 17
IR_VERSION = 8  # readable by onnxruntime >= 1.14
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "models" / "gbvs_saliency.onnx"


class _Graph:
    """Accumulates nodes and initialisers with deterministic names."""

    def __init__(self) -> None:
        self.nodes: list[onnx.NodeProto] = []
        self.inits: list[onnx.TensorProto] = []
        self._n = 0

    def const(self, name: str, value: Any, dtype: type = np.float32) -> str:
        self.inits.append(numpy_helper.from_array(np.asarray(value, dtype=dtype), name))
        return name

    def op(self, op_type: str, inputs: list[str], n_out: int = 1, **attrs: Any) -> list[str]:
        self._n += 1
        stem = f"{op_type.lower()}_{self._n}"
        outs = [stem + (f"_{i}" if n_out > 1 else "") for i in range(n_out)]
        self.nodes.append(helper.make_node(op_type, inputs, outs, name=f"n{self._n}", **attrs))
        return outs

    def one(self, op_type: str, inputs: list[str], **attrs: Any) -> str:
        return self.op(op_type, inputs, 1, **attrs)[0]


def _pad4(pad: int) -> list[int]:
    return [0, 0, pad, pad, 0, 0, pad, pad]


def _level_features(g: _Graph, rgb: str, params: gbvs.GBVSParams) -> str:
    """(1, 3, h, w) -> (1, F, h, w), F features per level, as ``gbvs.level_features``."""
    r, gr, b = g.op("Split", [rgb], 3, axis=1)
    intensity = g.one("Div", [g.one("Add", [g.one("Add", [r, gr]), b]), "three"])
    denom = g.one("Max", [g.one("ReduceMax", [rgb], axes=[1], keepdims=1), "colour_floor"])
    y = g.one("Min", [r, gr])
    colour = [
        g.one("Div", [g.one("Relu", [g.one("Sub", [p, q])]), denom])
        for p, q in ((r, gr), (gr, r), (b, y), (y, b))
    ]
    padded = g.one("Pad", [intensity, "pad_gabor"], mode="reflect")
    resp = g.one("Conv", [padded, "gabor"])
    even = g.one("Slice", [resp, "zero", "k_orient", "one"])
    odd = g.one("Slice", [resp, "k_orient", "two_k_orient", "one"])
    energy = g.one("Sqrt", [g.one("Add", [g.one("Mul", [even, even]), g.one("Mul", [odd, odd])])])
    return g.one("Concat", [intensity, *colour, energy], axis=1)


def _separable(g: _Graph, maps: str, falloff: str) -> str:
    """(m, n) -> (m, n): ``maps @ F`` for the falloff ``F = kron(rows, cols)`` named
    ``falloff`` (symmetric factors), as ``rows @ A @ cols`` on each map ``A``."""
    grid = g.one("Reshape", [maps, "grid_shape"])
    grid = g.one("MatMul", [grid, f"{falloff}_cols"])
    grid = g.one("MatMul", [f"{falloff}_rows", grid])
    return g.one("Reshape", [grid, "maps_shape"])


def build_model(params: gbvs.GBVSParams | None = None) -> onnx.ModelProto:
    """The ONNX graph of GBVS for ``params`` (default ``GBVSParams()``)."""
    params = params or gbvs.GBVSParams()
    c = gbvs.constants(params)
    rows, cols = params.map_size
    h, w = params.input_size
    k = len(params.orientations_deg)
    g = _Graph()
    g.const("blur_rgb", np.repeat(c.blur[None, None], 3, axis=0))
    g.const("blur_one", c.blur[None, None])
    g.const("gabor", c.gabor[:, None])
    g.const("f_act_columns", c.f_act[:, :, None])
    g.const("act_degree", c.f_act.sum(axis=1, dtype=np.float64))
    for name, frac in (("act", params.sigma_frac_act), ("norm", params.sigma_frac_norm)):
        f_rows, f_cols = gbvs.falloff_factors(params.map_size, frac, params.border_reflect)
        g.const(f"{name}_rows", f_rows)
        g.const(f"{name}_cols", f_cols)
    g.const("act_bias", c.act_bias)
    g.const("combine", c.combine)
    g.const("three", 3.0)
    g.const("colour_floor", params.colour_floor)
    g.const("log_eps", params.log_eps)
    g.const("pad_blur", _pad4(2), np.int64)
    g.const("pad_gabor", _pad4(params.gabor_size // 2), np.int64)
    g.const("zero", [0], np.int64)
    g.const("one", [1], np.int64)
    g.const("two", [2], np.int64)
    g.const("k_orient", [k], np.int64)
    g.const("two_k_orient", [2 * k], np.int64)
    g.const("maps_shape", [params.n_maps, params.n_nodes], np.int64)
    g.const("grid_shape", [params.n_maps, rows, cols], np.int64)
    g.const("out_shape", [1, 1, rows, cols], np.int64)

    top = max(params.levels)
    level = INPUT_NAME
    per_level = []
    for lev in range(1, top + 1):
        padded = g.one("Pad", [level, "pad_blur"], mode="reflect")
        level = g.one("Conv", [padded, "blur_rgb"], group=3, strides=[2, 2])
        if lev in params.levels:
            feats = _level_features(g, level, params)
            f = 2 ** (top - lev)
            if f > 1:
                feats = g.one("AveragePool", [feats], kernel_shape=[f, f], strides=[f, f])
            per_level.append(feats)
    maps = g.one("Reshape", [g.one("Concat", per_level, axis=1), "maps_shape"])

    # Activation: equilibrium of the symmetric dissimilarity chain = normalised degree,
    # sum_j |x_i - x_j| F_ij = 2 sum_j max(x_i, x_j) F_ij - x_i sum_j F_ij - (F x)_i.
    x = g.one("Log", [g.one("Add", [maps, "log_eps"])])
    x = g.one("Sub", [x, g.one("ReduceMin", [x], axes=[1], keepdims=1)])
    column = g.one("Unsqueeze", [g.one("Transpose", [x], perm=[1, 0]), "two"])  # (n, m, 1)
    row = g.one("Unsqueeze", [x, "zero"])  # (1, m, n)
    high = g.one("MatMul", [g.one("Max", [column, row]), "f_act_columns"])  # (n, m, 1)
    high = g.one("Transpose", [g.one("Squeeze", [high, "two"])], perm=[1, 0])
    low = g.one("Add", [g.one("Mul", [x, "act_degree"]), _separable(g, x, "act")])
    degree = g.one("Sub", [g.one("Add", [high, high]), low])
    degree = g.one("Add", [degree, "act_bias"])
    act = g.one("Div", [degree, g.one("ReduceSum", [degree, "one"], keepdims=1)])

    # Normalisation: detailed balance gives pi_i ~ A_i (A F_norm)_i.
    norm = act
    for _ in range(params.norm_iters):
        q = g.one("Mul", [norm, _separable(g, norm, "norm")])
        norm = g.one("Div", [q, g.one("ReduceSum", [q, "one"], keepdims=1)])

    # Combination, final blur, scale to max 1.
    total = g.one("Reshape", [g.one("MatMul", ["combine", norm]), "out_shape"])
    blurred = g.one("Conv", [g.one("Pad", [total, "pad_blur"], mode="reflect"), "blur_one"])
    peak = g.one("ReduceMax", [blurred], keepdims=1)
    g.nodes.append(helper.make_node("Div", [blurred, peak], [OUTPUT_NAME], name="out"))

    graph = helper.make_graph(
        g.nodes,
        "gbvs_saliency",
        [helper.make_tensor_value_info(INPUT_NAME, TensorProto.FLOAT, [1, 3, h, w])],
        [helper.make_tensor_value_info(OUTPUT_NAME, TensorProto.FLOAT, [1, 1, rows, cols])],
        g.inits,
    )
    model = helper.make_model(
        graph,
        opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name="adaproj-edge tools/build_saliency_model.py",
        doc_string="GBVS (Harel, Koch & Perona 2006); see models/gbvs_saliency.md",
    )
    model.ir_version = IR_VERSION
    helper.set_model_props(
        model,
        {
            CONTRACT_KEY: CONTRACT,
            "gbvs.params": json.dumps(dataclasses.asdict(params), sort_keys=True),
        },
    )
    onnx.checker.check_model(model)
    return model


def model_bytes(params: gbvs.GBVSParams | None = None) -> bytes:
    """Serialised model; the same parameters always give the same bytes."""
    return build_model(params).SerializeToString(deterministic=True)


def main(argv: list[str] | None = None) -> int:
    apply_thread_policy()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where to write the model")
    args = parser.parse_args(argv)
    data = model_bytes()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(data)
    print(f"wrote {args.out} ({len(data)} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
