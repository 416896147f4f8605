"""The process's thread policy: how many threads the numeric libraries may use.

Every entry point (the ``adaproj`` command, ``python -m adaproj_edge``, the tools, the
test run) calls :func:`apply_thread_policy` first. The warp's solves are small dense
and banded systems, where a BLAS thread pool only adds hand-offs: on a machine whose
other cores are busy, the default pools (one thread per core, spinning) made the same
``adaproj warp`` 2.5-3x slower and a replay up to 9x slower. So the default is one
thread, whatever the caller's environment says (``OPENBLAS_NUM_THREADS`` and the like
are overwritten); ``ADAPROJ_THREADS=N`` asks for N, ``ADAPROJ_THREADS=auto`` leaves
the libraries' own defaults.

The policy reaches every library, whether it is loaded yet or not: the environment
variables the BLAS builds, OpenMP and OpenCV read when they load (and that child
processes inherit), ``threadpoolctl`` for BLAS/OpenMP libraries already loaded, and
``cv2.setNumThreads`` when OpenCV is. onnxruntime sessions are made with one intra- and
one inter-op thread by :class:`~adaproj_edge.content.model.SaliencyModel`.

The same call puts the allocator policy in force (:mod:`adaproj_edge.allocator`: freed
memory is kept for the next arrays instead of being faulted in again).

This module imports nothing heavy: it runs before numpy loads.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Mapping, MutableMapping
from typing import Any

log = logging.getLogger(__name__)

THREADS_ENV = "ADAPROJ_THREADS"
"""The environment variable that sets the policy: a positive integer, or ``auto``."""

DEFAULT_THREADS = 1

LIBRARY_ENV = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "OPENCV_FOR_THREADS_NUM",
)
"""Variables read by the BLAS builds, OpenMP, numexpr and OpenCV when they load."""


def thread_count(environ: Mapping[str, str] | None = None) -> int | None:
    """The number of threads the policy allows, from ``ADAPROJ_THREADS``.

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default: ``os.environ``).

    Returns
    -------
    int or None
        A positive thread count (1 when the variable is unset, empty or unusable: an
        unusable value is logged); None for ``auto`` (the libraries' own defaults).
    """
    text = (os.environ if environ is None else environ).get(THREADS_ENV, "").strip()
    if not text:
        return DEFAULT_THREADS
    if text.lower() == "auto":
        return None
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        log.warning(
            "%s=%r is neither a positive integer nor 'auto'; using %d thread",
            THREADS_ENV,
            text,
            DEFAULT_THREADS,
        )
        return DEFAULT_THREADS
    return n


def apply_thread_policy(
    threads: int | None = None,
    *,
    environ: MutableMapping[str, str] | None = None,
) -> int | None:
    """Put the thread policy in force for this process and the processes it starts.

    Call it first in an entry point; calling it later (numpy, scipy or OpenCV already
    loaded) works too, through ``threadpoolctl`` and ``cv2.setNumThreads``.

    Parameters
    ----------
    threads : int, optional
        Threads to allow; default: :func:`thread_count` of the environment.
    environ : mutable mapping, optional
        The environment to read and update (default: ``os.environ``).

    Returns
    -------
    int or None
        The thread count now in force; None when the policy is ``auto`` (nothing is
        changed).
    """
    env = os.environ if environ is None else environ
    if environ is None:  # the process's own environment: its allocator too
        from adaproj_edge.allocator import apply_allocator_policy

        apply_allocator_policy(env)
    n = thread_count(env) if threads is None else threads
    if n is None:
        return None
    if n < 1:
        raise ValueError(f"threads must be positive, got {n}")
    for name in LIBRARY_ENV:
        env[name] = str(n)
    if "numpy" in sys.modules:  # BLAS / OpenMP libraries may be loaded: limit them now
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=n)
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        cv2.setNumThreads(n)
    return n


def thread_report() -> dict[str, Any]:
    """The thread pools in force now, for a log line or a test.

    Returns
    -------
    dict
        ``policy`` (the ``ADAPROJ_THREADS`` value in force, None for ``auto``), one entry
        per loaded BLAS/OpenMP library (``"openblas"``, ``"openmp"``...: the largest
        ``num_threads`` among the copies loaded), and ``"opencv"`` when OpenCV is loaded.
    """
    from threadpoolctl import threadpool_info

    report: dict[str, Any] = {"policy": thread_count()}
    for lib in threadpool_info():
        key = str(lib.get("internal_api"))
        report[key] = max(int(lib["num_threads"]), int(report.get(key, 0)))
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        report["opencv"] = int(cv2.getNumThreads())
    return report
