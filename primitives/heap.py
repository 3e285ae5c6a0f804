"""How a process that runs Monte Carlo batches keeps the memory one batch freed for the next (glibc):
the one module for it (the design engines' workers, ``shiptrial detect``).

glibc hands freed memory at the top of the heap back to the system once it exceeds a trim
threshold, and a process grows its heap again in its next batch: every page of it faulted in and
zeroed anew. A Monte Carlo batch frees its whole working set at its end, so with glibc's defaults
each batch of a long-lived process paid those faults again. Measured (`python
benchmarks/heap_faults.py`, 125-run batches of the random design, model ship, forked children,
load 30): 6,600 page faults on every batch after the first with glibc's defaults, 30-60 with freed
memory kept. The first batch of a new process still faults its working set in (about 10,000
faults a forked worker; a parent's gc.freeze before the fork does not change it, its malloc_trim
takes 2,000 off): the first-task extra of ``benchmarks/scaling_model.py``.

Only the engines' own processes keep freed memory (the fork and spawn pools' workers, Dask's),
never the caller's: mallopt is process-wide and cannot be undone (setting the trim threshold
turns glibc's adaptive threshold off for good), and a library caller would keep up to
KEEP_FREED_BYTES of every later job's freed memory too. Measured in a notebook-like process
(one inline Monte Carlo of 2,000 runs, then a numpy job of its own that allocates and frees
200 MB; load 15): RSS 195 MB after both with glibc's defaults, 384 MB with freed memory kept
(205 MB of it free heap), for 3.75 -> 3.39 s CPU on the inline call.

``shiptrial detect`` keeps freed memory in its own process (cli/detect_cmd.py, ``always``): its 400
no-change records of a 500 s recording are 16 MB per signal and temporary, about a hundred a
recording, and with glibc's defaults every one was faulted in afresh: 40 recordings in one call
spent 12.6 s of 73.4 s CPU in the kernel (738,659 minor faults, load 30, stop 41), 0.9 s with the
thresholds set (115,169 faults; max RSS 443 -> 604 MB; that pair also holds the compiled loops).
It keeps 1 GiB (DETECT_KEEP_BYTES), not KEEP_FREED_BYTES: one process screening 4 recordings
(review, load ~25) faulted 72,640 / 73,161 times with 256 MB kept, 28,566 / 90,689 with glibc's
defaults, 23,252 / 24,318 with 1 GiB (0.97-1.21, 0.33-1.60, 0.37-0.52 s system). The library's ``identify.detect.api.screen``
does not set them (a caller's process, above): a notebook or benchmark that screens many
recordings calls ``keep_freed_memory(always=True)`` itself.
"""

from __future__ import annotations

import ctypes
import os
import platform

# glibc's mallopt parameters: M_TRIM_THRESHOLD, M_MMAP_THRESHOLD
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
KEEP_FREED_BYTES = 256 << 20  # freed heap a process keeps for its next batch instead of returning it
DETECT_KEEP_BYTES = 1 << 30  # shiptrial detect's: its no-change records free more than 256 MB at a time (docstring)
# arrays below this come from the heap (reused), not from fresh mappings: glibc's own adaptive
# ceiling on 64-bit (DEFAULT_MMAP_THRESHOLD_MAX) and the largest value older glibc accepts (its
# mallopt refuses a threshold over HEAP_MAX_SIZE / 2; 2.36 here takes 64 MB, with the same effect)
MMAP_FROM_BYTES = 32 << 20
DASK_TRIM_THRESHOLD = "65536"  # Dask's default distributed.nanny.pre-spawn-environ value
_MALLOC_SET = False


def keep_freed_memory(always: bool = False, keep_bytes: int = KEEP_FREED_BYTES) -> bool:
    """Let this process reuse the memory its last batch freed; True when done. Dask's nanny starts
    workers with MALLOC_TRIM_THRESHOLD_=65536, which makes glibc return freed memory to the system
    at once and also turns off its adaptive mmap threshold: every array over 128 kB of every batch
    is then a fresh mapping, faulted in and zeroed page by page. Measured in one process with that
    variable (125-run batches of the random design, load 18): 2.8-3.1 ms CPU and ~240 page faults
    a run, 2.1-2.3 ms and none once set; the same peak memory. glibc's own defaults still trim
    between batches (module docstring: 40-50 faults a run). Cost: up to KEEP_FREED_BYTES of freed
    memory stays with the process between batches.

    Set with mallopt, on glibc only (elsewhere nothing is done), once per process: where
    MALLOC_TRIM_THRESHOLD_ holds Dask's default, or (``always``: the local pools' workers, processes
    the engine owns; never a caller's process, module docstring) where it is not set; another value
    is the user's choice and is kept. ``keep_bytes``: the freed heap kept (the trim threshold); the
    first call that sets it decides for the process."""
    global _MALLOC_SET
    env = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    if _MALLOC_SET or not (env == DASK_TRIM_THRESHOLD or (always and env is None)):
        return _MALLOC_SET
    libc = _glibc()
    if libc is None:
        return False
    try:
        mmap_ok = libc.mallopt(_M_MMAP_THRESHOLD, MMAP_FROM_BYTES) == 1
        trim_ok = libc.mallopt(_M_TRIM_THRESHOLD, keep_bytes) == 1
    except AttributeError:  # a glibc without mallopt
        return False
    _MALLOC_SET = mmap_ok and trim_ok
    return _MALLOC_SET


def release_freed_memory() -> bool:
    """Hand this process's free heap pages back to the system now (glibc's malloc_trim(0)); True when
    called. The fork pool's parent does this before it forks: a fork copies the page tables of every
    page the parent holds, kept free memory included (parent CPU per fork 7.3-7.8 ms on main,
    8.3-9.3 ms once the parent kept its freed heap, as the scaling benchmark's process does; 3 runs
    each at load 15-30), and a worker's first batch then faults fresh pages instead of copying the
    parent's (about 2,000 of 10,000 faults fewer, measured). The parent's next batch faults its
    working set in once again."""
    libc = _glibc()
    try:
        return libc is not None and libc.malloc_trim(0) in (0, 1)
    except AttributeError:  # a glibc without malloc_trim
        return False


def _glibc() -> ctypes.CDLL | None:
    """This process's C library where it is glibc (its malloc is the one tuned here), else None."""
    if platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:  # a glibc without the usual soname
        return None
