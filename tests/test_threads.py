"""The thread policy: what ``ADAPROJ_THREADS`` means, and that it reaches the libraries
already loaded (issue 12, item 1)."""

from __future__ import annotations

import logging

import cv2
import pytest
from hypothesis import given
from hypothesis import strategies as st
from threadpoolctl import threadpool_info, threadpool_limits

from adaproj_edge.threads import (
    LIBRARY_ENV,
    THREADS_ENV,
    apply_thread_policy,
    thread_count,
    thread_report,
)


@pytest.mark.parametrize(
    ("value", "want"),
    [(None, 1), ("", 1), (" 3 ", 3), ("1", 1), ("auto", None), ("AUTO", None)],
)
def test_thread_count(value: str | None, want: int | None) -> None:
    env = {} if value is None else {THREADS_ENV: value}
    assert thread_count(env) == want


@given(st.text(max_size=12))
def test_any_value_gives_a_positive_count_or_auto(text: str) -> None:
    n = thread_count({THREADS_ENV: text})
    assert n is None or n >= 1
    if n is None:
        assert text.strip().lower() == "auto"
    elif text.strip().isdecimal() and int(text.strip()) >= 1:
        assert n == int(text.strip())


@pytest.mark.parametrize("value", ["0", "-2", "many", "1.5"])
def test_an_unusable_value_is_logged_and_one_thread_used(
    value: str, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING, "adaproj_edge.threads"):
        assert thread_count({THREADS_ENV: value}) == 1
    assert THREADS_ENV in caplog.text and repr(value) in caplog.text


def test_policy_overwrites_the_callers_variables() -> None:
    env = {THREADS_ENV: "2", "OPENBLAS_NUM_THREADS": "8", "OMP_NUM_THREADS": "8"}
    with threadpool_limits():  # restores the limits of this test process afterwards
        assert apply_thread_policy(environ=env) == 2
    assert all(env[v] == "2" for v in LIBRARY_ENV)


def test_auto_changes_nothing() -> None:
    env = {THREADS_ENV: "auto", "OPENBLAS_NUM_THREADS": "8"}
    assert apply_thread_policy(environ=env) is None
    assert env == {THREADS_ENV: "auto", "OPENBLAS_NUM_THREADS": "8"}


def test_policy_reaches_libraries_already_loaded() -> None:
    import scipy.linalg  # noqa: F401  (its own OpenBLAS)

    before = cv2.getNumThreads()
    with threadpool_limits():
        threadpool_limits(limits=2)
        cv2.setNumThreads(2)
        env: dict[str, str] = {}
        assert apply_thread_policy(1, environ=env) == 1
        blas = [lib for lib in threadpool_info() if lib["user_api"] == "blas"]
        assert blas and all(lib["num_threads"] == 1 for lib in blas)
        assert cv2.getNumThreads() == 1
        report = thread_report()
        assert report["openblas"] == 1 and report["opencv"] == 1
    cv2.setNumThreads(before)


def test_a_thread_count_must_be_positive() -> None:
    with pytest.raises(ValueError, match="positive"):
        apply_thread_policy(0, environ={})
