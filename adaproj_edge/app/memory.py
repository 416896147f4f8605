"""Memory over a long run: keep the resident set flat, and read it.

Every update allocates and frees arrays of a few MB (maps, frames). glibc serves
those from the heap once its dynamic mmap threshold has grown, and a fragmented heap
is not given back, so the resident set creeps up by tens of MB. Pinning the threshold
at 1 MB makes such arrays their own mappings, returned to the system when freed (the
same as ``MALLOC_MMAP_THRESHOLD_=1048576`` in the environment).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import resource

log = logging.getLogger(__name__)

M_MMAP_THRESHOLD = -3
THRESHOLD = 1 << 20


def pin_mmap_threshold(threshold: int = THRESHOLD) -> bool:
    """Set glibc's mmap threshold; False where there is no glibc ``mallopt``."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        ok = bool(libc.mallopt(M_MMAP_THRESHOLD, threshold))
    except (OSError, AttributeError):
        return False
    log.debug("mmap threshold %d: %s", threshold, ok)
    return ok


def rss_mb() -> float:
    """Current resident set size (Linux ``/proc/self/statm``; else the peak), in MB."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
