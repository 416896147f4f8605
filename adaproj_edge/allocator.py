"""The process's allocator policy: keep the heap's freed memory for the next array.

The warp, depth and render stages make and drop arrays of a few hundred kB to a few MB
many times a second. glibc's malloc serves blocks above its mmap threshold (128 kB at
first, raised as such blocks are freed) with fresh ``mmap`` pages and returns the top of
the heap to the system whenever more than its trim threshold is free there, so the same
arrays fault their pages in again on every update. Measured on this project's machine
(a VM: a page fault costs about 2 us), setting up one 20x20 content-free system in a
replay took 5.0 ms with 2000 page faults and 1.3 ms with none; the device's
content-free solve and display maps got about a third and a half faster
(``tools/bench_app.py``; ``ADAPROJ_MALLOC=default`` gives the baseline; figures in
docs/engine.md).

:func:`apply_allocator_policy` therefore sets, through ``mallopt``:

- ``M_MMAP_THRESHOLD`` = :data:`MMAP_THRESHOLD`: blocks below it come from the heap
  (setting it also stops glibc from moving it);
- ``M_TRIM_THRESHOLD`` = :data:`TRIM_THRESHOLD`: free memory at the heap's top is kept
  up to this much;
- ``M_TOP_PAD`` = :data:`TOP_PAD`: the heap grows by this much more than asked.

The memory kept is bounded by these values (tens of MB against the 2-4 GB of the
board), but the runtime's budget is tighter (``tools/bench_memory.py``: 300 MB), so they
are the least that keep the faults away: the 60-s replay peaks at 292 MB with the policy
and 282 MB without, the 150-s one at 299 and 291 MB (plateaus 288 and 280). Keeping 32
MB with 8 MB of pad peaked at 302 MB there; keeping 8 MB brought the faults back (1650
per set-up); an mmap threshold of 2 or 4 MB made the replay's start reach 800 MB.
On a C library without ``mallopt`` (musl) nothing changes and that
is logged. ``ADAPROJ_MALLOC=default`` leaves the allocator's own defaults (for a
baseline).

:func:`~adaproj_edge.threads.apply_thread_policy`, which every entry point calls first,
calls this too. This module imports nothing heavy.
"""

from __future__ import annotations

import ctypes
import logging
import os
from collections.abc import Callable, Mapping

log = logging.getLogger(__name__)

MALLOC_ENV = "ADAPROJ_MALLOC"
"""``default`` leaves the C library's allocator settings alone."""

M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3
"""glibc's ``mallopt`` parameter numbers (``malloc.h``)."""

MMAP_THRESHOLD = 8 << 20
TRIM_THRESHOLD = 16 << 20
TOP_PAD = 4 << 20

Mallopt = Callable[[int, int], int]


def _glibc_mallopt() -> Mallopt | None:
    """``mallopt`` of the process's C library, or None where there is none (looked up in
    the process's own symbols: no ``ldconfig`` run as ``ctypes.util.find_library``
    would)."""
    try:
        func = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):
        return None
    func.argtypes = [ctypes.c_int, ctypes.c_int]
    func.restype = ctypes.c_int
    return func


def apply_allocator_policy(
    environ: Mapping[str, str] | None = None, mallopt: Mallopt | None = None
) -> bool:
    """Put the allocator policy in force for this process.

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default: ``os.environ``).
    mallopt : callable, optional
        The C library's ``mallopt`` (default: found with ``ctypes``; tests pass a fake).

    Returns
    -------
    bool
        True when every setting was accepted; False when the policy is ``default``, the C
        library has no ``mallopt`` or refused a setting (logged).
    """
    env = os.environ if environ is None else environ
    if env.get(MALLOC_ENV, "").strip().lower() == "default":
        return False
    func = _glibc_mallopt() if mallopt is None else mallopt
    if func is None:
        log.info("no mallopt in this C library: the allocator keeps its defaults")
        return False
    ok = True
    for param, value in (
        (M_MMAP_THRESHOLD, MMAP_THRESHOLD),
        (M_TRIM_THRESHOLD, TRIM_THRESHOLD),
        (M_TOP_PAD, TOP_PAD),
    ):
        if func(param, value) != 1:  # mallopt returns 1 on success
            log.warning("mallopt(%d, %d) was refused: that setting keeps its default", param, value)
            ok = False
    return ok
