"""A saliency model run with onnxruntime, behind one documented contract.

The contract (also in ``models/gbvs_saliency.md``) that any model must meet to replace
the default:

- **input**: exactly one, float32, shape ``(1, 3, H, W)``: RGB, values in [0, 1], the
  whole content resized (aspect not kept) to ``H × W``. ``H`` and ``W`` are read from the
  model; a model with symbolic sizes gets ``default_input_size``.
- **output**: the first output, float32, ``(1, 1, h, w)``, ``(1, h, w)`` or ``(h, w)``,
  any finite values, larger = more salient, covering the whole input.
- optional metadata ``adaproj.contract = saliency-v1``.

The caller never sees the raw output: :meth:`SaliencyModel.predict` rescales it to
[0, 1] (min to 0, max to 1; a constant map becomes all zeros).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from adaproj_edge.errors import ModelError
from adaproj_edge.resources import default_model

INPUT_NAME = "image"
OUTPUT_NAME = "saliency"
CONTRACT_KEY = "adaproj.contract"
CONTRACT = "saliency-v1"

DEFAULT_MODEL_PATH = default_model()
"""The default model (``models/gbvs_saliency.onnx``, shipped in the package)."""

DEFAULT_INPUT_SIZE = (120, 192)
"""(H, W) given to a model whose input size is symbolic."""

WARM_RUNS = 2
"""Runs :meth:`SaliencyModel.warm` makes (onnxruntime's first two are the slow ones)."""


def to_input(image_bgr: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.float32]:
    """A BGR (or gray) uint8 image -> the model input ``(1, 3, H, W)`` RGB in [0, 1].

    Parameters
    ----------
    image_bgr : (h, w, 3) or (h, w) uint8
    size : (H, W)
    """
    img = image_bgr if image_bgr.ndim == 3 else cv2.cvtColor(image_bgr, cv2.COLOR_GRAY2BGR)
    k = min(img.shape[0] // size[0], img.shape[1] // size[1])
    if k >= 2:  # OpenCV's integer-factor area average is much faster than a general one
        img = cv2.resize(img, None, fx=1.0 / k, fy=1.0 / k, interpolation=cv2.INTER_AREA)
    small = cv2.resize(img, (size[1], size[0]), interpolation=cv2.INTER_AREA)
    rgb = small[:, :, ::-1].transpose(2, 0, 1).astype(np.float32) / np.float32(255.0)
    return np.ascontiguousarray(rgb[None])


FLAT = 1e-3
"""A map whose range is below ``FLAT`` times its largest magnitude counts as constant."""


def normalise(raw: NDArray[Any]) -> NDArray[np.float32]:
    """Rescale a raw saliency map to [0, 1]; (nearly) constant maps give zeros.

    Non-finite values count as 0. "Nearly constant" (range below :data:`FLAT` of the
    largest magnitude) covers a flat image, whose map differs from a constant only by
    float rounding: stretching that to [0, 1] would show noise as saliency.
    """
    m = np.nan_to_num(np.asarray(raw, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    lo, hi = float(m.min()), float(m.max())
    if hi - lo <= FLAT * max(abs(lo), abs(hi)) or hi - lo < 1e-12:
        return np.zeros_like(m)
    return ((m - lo) / np.float32(hi - lo)).astype(np.float32)


class SaliencyModel:
    """An ONNX saliency model meeting the contract, run on one CPU thread by default.

    Parameters
    ----------
    path : path-like
        The ``.onnx`` file.
    threads : int
        onnxruntime ``intra_op_num_threads``.
    default_input_size : (H, W)
        Used when the model's input size is symbolic.

    Raises
    ------
    ModelError
        The file is missing, not an ONNX model, or does not meet the contract.
    """

    def __init__(
        self,
        path: str | os.PathLike[str] = DEFAULT_MODEL_PATH,
        *,
        threads: int = 1,
        default_input_size: tuple[int, int] = DEFAULT_INPUT_SIZE,
    ) -> None:
        import onnxruntime as ort

        self.path = Path(path)
        if not self.path.is_file():
            raise ModelError(f"saliency model not found: {self.path}")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = 1
        opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        opts.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(
                str(self.path), sess_options=opts, providers=["CPUExecutionProvider"]
            )
        except Exception as e:  # onnxruntime raises its own untyped exceptions
            raise ModelError(f"{self.path} is not a loadable ONNX model: {e}") from None
        self.input_size = self._check_input(default_input_size)
        self._output = self.session.get_outputs()[0].name
        self._warm = False

    def _check_input(self, default: tuple[int, int]) -> tuple[int, int]:
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise ModelError(f"{self.path}: a saliency model takes one input, not {len(inputs)}")
        inp = inputs[0]
        self._input = inp.name
        if inp.type != "tensor(float)" or len(inp.shape) != 4:
            raise ModelError(
                f"{self.path}: input must be float32 (1, 3, H, W), got {inp.type} {inp.shape}"
            )
        n, c, h, w = inp.shape
        batch_ok = n == 1 or n is None or isinstance(n, str)
        if not batch_ok or c != 3:
            raise ModelError(f"{self.path}: input must be (1, 3, H, W), got {inp.shape}")
        if isinstance(h, int) and isinstance(w, int):
            return h, w
        return default

    @property
    def contract(self) -> str | None:
        """The model's declared contract, None when it declares none."""
        value = self.session.get_modelmeta().custom_metadata_map.get(CONTRACT_KEY)
        return None if value is None else str(value)

    def run(self, tensor: NDArray[np.float32]) -> NDArray[np.float32]:
        """The raw output for a prepared input ``(1, 3, H, W)``, as ``(h, w)`` float32."""
        out = self.session.run([self._output], {self._input: tensor})[0]
        arr = np.asarray(out, dtype=np.float32)
        while arr.ndim > 2 and arr.shape[0] == 1:
            arr = arr[0]
        if arr.ndim != 2 or arr.shape[0] < 2 or arr.shape[1] < 2:
            raise ModelError(f"{self.path}: output must be a (1, 1, h, w) map, got {out.shape}")
        return arr

    def warm(self) -> None:
        """Run the session on a blank input until its first runs are behind it.

        onnxruntime spends its first two runs of a session setting itself up (here
        33 and 20 ms against 5 ms after); a clip's first frames must not pay that.
        Once per model; later calls do nothing.
        """
        if self._warm:
            return
        blank = np.zeros((1, 3, *self.input_size), np.float32)
        for _ in range(WARM_RUNS):
            self.run(blank)
        self._warm = True

    def predict(self, image_bgr: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Saliency of a whole image, ``(h, w)`` float32 in [0, 1] at the model's output size.

        Parameters
        ----------
        image_bgr : (H, W, 3) or (H, W) uint8
        """
        return normalise(self.run(to_input(image_bgr, self.input_size)))
