"""Fixtures of the content tests: one model session, the model builder tool."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

from adaproj_edge.content.model import SaliencyModel

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def model() -> SaliencyModel:
    """The committed default model, one session for the whole run."""
    return SaliencyModel()


@pytest.fixture(scope="session")
def builder() -> ModuleType:
    """``tools/build_saliency_model.py`` as a module."""
    path = REPO / "tools" / "build_saliency_model.py"
    spec = importlib.util.spec_from_file_location("build_saliency_model", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
