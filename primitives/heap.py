"""Keep freed large arrays in the process for reuse (glibc's malloc), instead of handing them back to
the operating system and faulting fresh zeroed pages in on the next allocation.

A vectorised Monte Carlo over a long record allocates and frees arrays of tens of megabytes many
times (``detect``'s 400 no-change records of a 500 s recording: 16 MB per signal and temporary,
about a hundred per recording). glibc serves such blocks with mmap, or trims the heap's free top
back to the system, so every new array is page-faulted in again: 40 recordings in one ``detect``
call spent 20.9 of 68.8 s CPU in the kernel (stop 40). With the mmap threshold fixed at 32 MiB and
the trim threshold at 1 GiB the process keeps its peak heap (a few hundred MB for ``detect``) and
reuses it (mallopt(3); the same as the environment variables MALLOC_MMAP_THRESHOLD_ and
MALLOC_TRIM_THRESHOLD_).
"""

from __future__ import annotations

import ctypes
import sys

# mallopt(3) parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 1024 * 1024  # glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit)
TRIM_THRESHOLD = 1024 * 1024 * 1024
_done: bool | None = None


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds once per process (a no-op elsewhere: other C libraries,
    other systems). True when set."""
    global _done
    if _done is None:
        _done = False
        if sys.platform.startswith("linux"):
            try:
                mallopt = ctypes.CDLL("libc.so.6").mallopt
            except (OSError, AttributeError):  # musl or another C library: nothing to tune
                return False
            mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
            _done = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return _done
