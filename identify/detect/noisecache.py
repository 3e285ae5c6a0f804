"""The no-change records' noise kept on disk per prior and recording length: what
:func:`identify.detect.nullsim.null_records` draws and filters the same way for every recording a
prior is tested on, read back by the next ``shiptrial detect`` instead of computed again.

With the pod yaw moment measured (``Deriver.linear``) a no-change record's inputs are the prior's
inputs of the clean signals plus those of the noise alone (:func:`identify.detect.nullsim.null_records`: the clean
share from ``_linear_inputs``, the noise's added in the yaw loop, ``simulate_r(extra=)``);
that noise's share, the yaw rate's noise and the misfit's block innovations depend on the seed, the
number of records, the recording's length and the prior's noise levels, sample time and input filter
only, not on the recording. Drawing and filtering them was 1.0 s of a 500 s recording's 1.8 s CPU in
the library call (s48-i25-detectspeed's report); read back memory-mapped they cost the digest check.

An entry is one file named by the SHA-256 of its key (:func:`key`: every number the arrays are
computed from, the code that computes them (:func:`code_version`) and which loop filtered them (compiled
or numpy, :mod:`primitives.zerophase`: equal to rounding only)), ``KEY.noise``: the magic line,
the SHA-256 of the payload, a header line (the inputs' names and the arrays' shapes) and the arrays'
float64 bytes: the yaw rate's noise (runs, n), each input's share stored (runs, n), the block
innovations (blocks, runs). It is written whole or not at all (temporary file and rename) and read
back memory-mapped and only when its digest matches, so a damaged entry is computed again, never read
and never an error, as :mod:`maps.plancache`'s plans are; the most recently used are kept within a byte
budget (:func:`budget`: 256 MiB, two entries of a 500 s recording; the newest whatever its size).
Only ``shiptrial detect`` uses it (:func:`used`): a library call outside that block touches no disk.
The entries are the user's own files in the user's cache directory (:func:`default_dir`), as numba's
and the planner's caches are.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import json
import mmap
import os
import sys
from collections.abc import Iterator
from functools import lru_cache
from pathlib import Path

import numpy as np

from primitives.io import atomic_write_bytes, hash_sources, prune_to_budget, remove_stale_temporaries, user_cache_dir

ENV_DIR = "SHIPTRIAL_DETECT_CACHE_DIR"  # this cache's directory; "" for none
ENV_PLANNER = "SHIPTRIAL_CACHE_DIR"  # the planner's cache directory (maps.plancache); "" turns this cache off too
ENV_MB = "SHIPTRIAL_DETECT_CACHE_MB"  # the byte budget in MB (a number >= 0), instead of BUDGET_BYTES
#: bytes of entries kept, the most recently used first (the newest whatever its size): an entry is 96.0 MB (91.6 MiB)
#: for 400 records of a 500 s recording at 10 Hz with five inputs, 113.6 MB (108.3 MiB) with the roll rate: two kept
#: (a user's second prior or length), not the 454 MB in the user's home that four would be, for about a second of CPU each
BUDGET_BYTES = 256 * 2**20
MAGIC = b"shiptrial-detect-noise 1\n"
SUFFIX = ".noise"
DIGEST = 64  # hex digits of a SHA-256
STALE_S = 3600.0  # a temporary file this old is no write in progress
#: the code an entry is computed with: the draws, the derivation, the input filters and what they call
PACKAGES = ("identify", "primitives")
ROOT = Path(__file__).resolve().parent.parent.parent
_ALIGN = 64  # the arrays start at a multiple of this in the file (the header line is padded)
_USED: contextvars.ContextVar[bool] = contextvars.ContextVar("detect_noise_cache", default=False)


@contextlib.contextmanager
def used() -> Iterator[None]:
    """Within the block, :func:`identify.detect.nullsim.null_records` reads and writes the cache
    (``shiptrial detect`` runs its job in one). Outside, a library call (a benchmark's thousands of
    screenings with new seeds, a notebook, the tests) touches no disk (a context variable, as
    :func:`primitives.jitloop.job`)."""
    token = _USED.set(True)
    try:
        yield
    finally:
        _USED.reset(token)


def default_dir() -> Path | None:
    """``$SHIPTRIAL_DETECT_CACHE_DIR`` (None when set to an empty string: no cache), else
    ``$XDG_CACHE_HOME/shiptrial/detect`` (``~/.cache/shiptrial/detect``); None too when
    ``$SHIPTRIAL_CACHE_DIR`` (the planner's) is set to an empty string and this one is not set, or
    no home directory is known."""
    if os.environ.get(ENV_DIR) is None and os.environ.get(ENV_PLANNER) == "":
        return None
    return user_cache_dir(ENV_DIR, "detect")


def _dir() -> Path | None:
    return default_dir() if _USED.get() else None


def active() -> bool:
    """Whether :func:`load` and :func:`store` read and write here (inside :func:`used`, a directory set):
    a library call outside computes no key (the code's digest reads every source file once)."""
    return _dir() is not None


@lru_cache(maxsize=1)
def code_version() -> str:
    """Digest of the code an entry is computed with: Python's and numpy's versions (the generator's
    draws) and every source of :data:`PACKAGES` (path and bytes)."""
    return hash_sources(hashlib.sha256(f"{sys.version}\0numpy={np.__version__}\0".encode()), ROOT, PACKAGES).hexdigest()


def key(*parts: object) -> str:
    """The entry's name: a digest of ``parts`` (their ``repr``: floats to the last bit) and :func:`code_version`."""
    return hashlib.sha256((code_version() + "\0" + repr(parts)).encode()).hexdigest()


def _shapes(names: tuple[str, ...], runs: int, n: int, blocks: int) -> list[tuple[int, int]]:
    return [(runs, n), *[(runs, n)] * len(names), (blocks, runs)]


def load(name: str, runs: int, n: int, blocks: int) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray] | None:
    """Entry ``name`` as (the yaw rate's noise (runs, n), each input's share (n, runs) by name, the
    innovations (blocks, runs)), read-only and memory-mapped; None when it is not there, not whole,
    not the bytes it was written with or of other shapes (the caller computes it), or outside :func:`used`."""
    d = _dir()
    if d is None:
        return None
    path = d / f"{name}{SUFFIX}"
    try:
        with open(path, "rb") as fh:
            view = memoryview(mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ))
        head = len(MAGIC) + DIGEST
        if view[: len(MAGIC)] != MAGIC or hashlib.sha256(view[head:]).hexdigest().encode() != view[len(MAGIC) : head]:
            return None
        payload = view[head:]
        end = bytes(payload[:4096]).index(b"\n") + 1
        meta = json.loads(bytes(payload[:end]))
        names = tuple(meta["inputs"])
        shapes = _shapes(names, runs, n, blocks)
        sizes = [r * c for r, c in shapes]
        if meta["shapes"] != [list(s) for s in shapes] or len(payload) != end + 8 * sum(sizes):
            return None
        offsets = end + 8 * np.cumsum([0, *sizes])
        arrays = [np.frombuffer(payload, "<f8", m, int(o)).reshape(s) for m, o, s in zip(sizes, offsets, shapes)]
    except (OSError, ValueError, KeyError, TypeError):  # ValueError: an empty file cannot be mapped
        return None
    with contextlib.suppress(OSError):  # another detect pruned it meanwhile: the mapped bytes are still whole
        os.utime(path)  # recently used: pruned last
    return arrays[0], {k: a.T for k, a in zip(names, arrays[1:-1])}, arrays[-1]


def store(name: str, r_noise: np.ndarray, inputs: dict[str, np.ndarray], blocks: np.ndarray) -> None:
    """Keep the yaw rate's noise ``r_noise`` (runs, n), each input's share of ``inputs`` (n, runs) and the
    innovations ``blocks`` under ``name``, whole or not at all (a full disk or an unwritable directory only
    means no cache), then keep the most recently used within :func:`budget` (:func:`prune`); nothing outside :func:`used`."""
    d = _dir()
    if d is None:
        return
    arrays = [r_noise, *(a.T for a in inputs.values()), blocks]  # a.T: the filters' (n, runs) F-order output, no copy
    line = json.dumps({"inputs": list(inputs), "shapes": [list(a.shape) for a in arrays]}).encode()
    line += b" " * (-(len(MAGIC) + DIGEST + len(line) + 1) % _ALIGN) + b"\n"
    parts = [line, *(memoryview(np.ascontiguousarray(a, "<f8").reshape(-1)).cast("B") for a in arrays)]
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    try:
        atomic_write_bytes(d / f"{name}{SUFFIX}", [MAGIC, h.hexdigest().encode(), *parts])
        prune(d)
    except OSError:
        pass


def budget() -> int:
    """Bytes of entries kept: ``$SHIPTRIAL_DETECT_CACHE_MB`` megabytes (2^20 bytes) when it is a number
    >= 0, else :data:`BUDGET_BYTES`."""
    try:
        mb = float(os.environ.get(ENV_MB, ""))
    except ValueError:
        return BUDGET_BYTES
    return int(mb * 2**20) if 0 <= mb < float("inf") else BUDGET_BYTES


def prune(directory: Path) -> None:
    """Keep the most recently used entries within :func:`budget` bytes (the newest whatever its size: the
    entry just written), and remove temporary files a writer killed outright left over an hour ago; a file
    another process removed meanwhile is skipped."""
    prune_to_budget(directory, SUFFIX, budget())
    remove_stale_temporaries(directory, (SUFFIX,), STALE_S)
