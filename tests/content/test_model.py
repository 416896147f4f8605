"""The ONNX model: same as the reference, repeatable build, the contract."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import cv2
import numpy as np
import onnx
import pytest
import skimage.data
from onnx import TensorProto, helper

from adaproj_edge.content import gbvs
from adaproj_edge.content.model import (
    CONTRACT,
    DEFAULT_MODEL_PATH,
    SaliencyModel,
    normalise,
    to_input,
)
from adaproj_edge.errors import ModelError
from tests.content.displays import colour_popout, intensity_popout, orientation_popout


def _images() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    out: dict[str, np.ndarray] = {}
    for name in ("astronaut", "chelsea", "coffee", "rocket", "camera", "coins"):
        img = getattr(skimage.data, name)()
        out[name] = np.ascontiguousarray(img[:, :, ::-1]) if img.ndim == 3 else img
    out["noise"] = rng.integers(0, 256, (300, 500, 3), dtype=np.uint8)
    out["black"] = np.zeros((50, 80, 3), np.uint8)
    out["white"] = np.full((50, 80, 3), 255, np.uint8)
    out["gradient"] = np.tile(np.linspace(0, 255, 640, dtype=np.uint8), (400, 1))
    out["tiny"] = rng.integers(0, 256, (3, 5, 3), dtype=np.uint8)
    out["tall"] = cv2.resize(out["coffee"], (200, 900))
    for make in (colour_popout, orientation_popout, intensity_popout):
        out[make.__name__] = make(5)[0]
    return out


IMAGES = _images()


@pytest.mark.parametrize("name", sorted(IMAGES))
def test_onnx_matches_numpy_reference(model: SaliencyModel, name: str) -> None:
    x = to_input(IMAGES[name], model.input_size)
    onnx_map = normalise(model.run(x))
    ref_map = normalise(gbvs.saliency(x[0]))
    assert np.abs(onnx_map - ref_map).max() <= 1e-3


def test_committed_model_is_a_fresh_build(builder: ModuleType) -> None:
    assert DEFAULT_MODEL_PATH.read_bytes() == builder.model_bytes(), (
        "models/gbvs_saliency.onnx is stale: run tools/build_saliency_model.py"
    )


def test_default_model_declares_the_contract(model: SaliencyModel) -> None:
    assert model.contract == CONTRACT
    assert model.input_size == gbvs.GBVSParams().input_size


def _write(model: onnx.ModelProto, path: Path) -> Path:
    onnx.save(model, str(path))
    return path


def _tiny_model(inputs: list[onnx.ValueInfoProto], node: onnx.NodeProto) -> onnx.ModelProto:
    out = helper.make_tensor_value_info("s", TensorProto.FLOAT, None)
    graph = helper.make_graph([node], "t", inputs, [out])
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    return m


def test_another_model_meeting_the_contract_replaces_the_default(tmp_path: Path) -> None:
    # "Brightness is saliency", at a symbolic input size: any model of the contract works.
    inp = helper.make_tensor_value_info("rgb", TensorProto.FLOAT, [1, 3, "h", "w"])
    node = helper.make_node("ReduceMean", ["rgb"], ["s"], axes=[1], keepdims=1)
    path = _write(_tiny_model([inp], node), tmp_path / "bright.onnx")
    m = SaliencyModel(path, default_input_size=(40, 64))
    img = np.zeros((80, 128, 3), np.uint8)
    img[10:30, 90:120] = 255
    s = m.predict(img)
    assert s.shape == (40, 64) and s.min() == 0.0 and s.max() == 1.0
    assert s[10, 50] == 1.0 and s[30, 10] == 0.0
    assert m.contract is None


def test_models_breaking_the_contract_are_refused(tmp_path: Path) -> None:
    two = [helper.make_tensor_value_info(n, TensorProto.FLOAT, [1, 3, 8, 8]) for n in ("a", "b")]
    path = _write(_tiny_model(two, helper.make_node("Add", ["a", "b"], ["s"])), tmp_path / "2.onnx")
    with pytest.raises(ModelError, match="one input"):
        SaliencyModel(path)
    gray = [helper.make_tensor_value_info("a", TensorProto.FLOAT, [1, 1, 8, 8])]
    path = _write(_tiny_model(gray, helper.make_node("Relu", ["a"], ["s"])), tmp_path / "g.onnx")
    with pytest.raises(ModelError, match=r"\(1, 3, H, W\)"):
        SaliencyModel(path)
    with pytest.raises(ModelError, match="not found"):
        SaliencyModel(tmp_path / "missing.onnx")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(ModelError, match="not a loadable ONNX model"):
        SaliencyModel(junk)


def test_normalise_handles_constant_and_nonfinite_maps() -> None:
    assert not normalise(np.full((3, 4), 7.0)).any()
    out = normalise(np.array([[np.nan, 1.0], [3.0, np.inf]]))
    assert out.min() == 0.0 and out.max() == 1.0 and np.isfinite(out).all()


def test_warm_runs_the_session_twice_once_and_changes_no_result() -> None:
    """``warm`` makes the session's first runs on a blank input, once per model."""
    model = SaliencyModel()
    img = _images()["chelsea"]
    cold = SaliencyModel().predict(img)
    runs: list[tuple[int, ...]] = []
    run = model.run

    def counted(tensor: np.ndarray) -> np.ndarray:
        runs.append(tensor.shape)
        return run(tensor)

    model.run = counted  # type: ignore[method-assign]
    model.warm()
    model.warm()
    assert runs == [(1, 3, *model.input_size)] * 2
    np.testing.assert_array_equal(model.predict(img), cold)
