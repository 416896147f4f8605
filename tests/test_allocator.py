"""The allocator policy: glibc keeps freed memory for the next arrays, so the same
arrays are not faulted in again on every update."""

from __future__ import annotations

import logging
import os
import platform
import subprocess
import sys
import textwrap

import pytest

from adaproj_edge.allocator import (
    M_MMAP_THRESHOLD,
    M_TOP_PAD,
    M_TRIM_THRESHOLD,
    MALLOC_ENV,
    MMAP_THRESHOLD,
    TOP_PAD,
    TRIM_THRESHOLD,
    apply_allocator_policy,
)


class FakeMallopt:
    def __init__(self, refuse: int | None = None) -> None:
        self.calls: list[tuple[int, int]] = []
        self.refuse = refuse

    def __call__(self, param: int, value: int) -> int:
        self.calls.append((param, value))
        return 0 if param == self.refuse else 1


def test_the_three_settings_are_made() -> None:
    fake = FakeMallopt()
    assert apply_allocator_policy({}, fake)
    want = [
        (M_MMAP_THRESHOLD, MMAP_THRESHOLD),
        (M_TRIM_THRESHOLD, TRIM_THRESHOLD),
        (M_TOP_PAD, TOP_PAD),
    ]
    assert sorted(fake.calls) == sorted(want)


def test_default_leaves_the_allocator_alone() -> None:
    fake = FakeMallopt()
    assert not apply_allocator_policy({MALLOC_ENV: " Default "}, fake)
    assert fake.calls == []


def test_a_refused_setting_is_logged_and_the_others_are_made(
    caplog: pytest.LogCaptureFixture,
) -> None:
    fake = FakeMallopt(refuse=M_TOP_PAD)
    with caplog.at_level(logging.WARNING, logger="adaproj_edge.allocator"):
        assert not apply_allocator_policy({}, fake)
    assert len(fake.calls) == 3
    assert "refused" in caplog.text


@pytest.mark.skipif(
    platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
    reason="mallopt's parameters are glibc's",
)
def test_glibc_accepts_the_policy() -> None:
    assert apply_allocator_policy({})


FAULTS = textwrap.dedent(
    """
    import resource
    from adaproj_edge.threads import apply_thread_policy
    apply_thread_policy()
    import numpy as np
    for _ in range(5):  # warm up the allocator
        a = np.ones(300_000); del a
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(100):  # the warp's kind of temporaries: 2.4 MB made and dropped
        a = np.ones(300_000); b = a * 2; del a, b
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
    """
)


def minor_faults(malloc: str) -> int:
    env = dict(os.environ, **{MALLOC_ENV: malloc})
    out = subprocess.run(
        [sys.executable, "-c", FAULTS], env=env, capture_output=True, text=True, check=True
    )
    return int(out.stdout.strip())


@pytest.mark.skipif(
    platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
    reason="mallopt's parameters are glibc's",
)
def test_arrays_made_and_dropped_again_do_not_fault_their_pages_in_again() -> None:
    """With the allocator's defaults each 2.4-MB array is mapped afresh (about 600 page
    faults per pair); with the policy the heap keeps them."""
    default = minor_faults("default")
    policy = minor_faults("")
    assert default > 10_000, default
    assert policy < 0.05 * default, (policy, default)
