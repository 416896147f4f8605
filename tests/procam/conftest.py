"""A solved calibration from the committed calibration session, shared by the tests."""

from __future__ import annotations

import pytest

from adaproj_edge.procam.result import CalibrationResult
from tests.procam.golden import replay


@pytest.fixture(scope="session")
def fixture_result() -> tuple[CalibrationResult, list[str]]:
    return replay()
