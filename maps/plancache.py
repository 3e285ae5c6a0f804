"""A cache on disk of planned trials: the design and plan of one set of inputs, read back instead of
recomputed when the same command is run again.

The key is a SHA-256 digest of everything the plan is computed from: the loaded ship profile, the
map file's resolved path and bytes, the lattice options, the design options (criterion, mean subtraction, trial
length, seed, parameter prior), counts, scenario, start, goal, vessel name, and the code version
(:func:`code_version`: every source and data file of the project's packages, the versions of
Python and of the numerical libraries (:data:`LIBRARIES`), ``SHIPTRIAL_KERNEL``). A change to any of them is
another key, so a stale entry is never read; entries beyond :data:`KEEP` are removed, oldest first.

An entry is one pickled dict: ``plan`` and ``design`` as :func:`maps.planner.plan_with_design`
returned them (the Plan and its TrialDesign or None), and whatever else the caller keeps with them
(``shiptrial plan``: the loaded sea map and the export chart, with the route and sea room the
plan holds for them: one pickle keeps the identities those memos check), behind a header with
the payload's digest: a truncated, corrupted or unreadable
entry is ignored (the plan is computed again) and never raises. The entries are the user's own
files in the user's cache directory (:func:`default_dir`), read by the user's own commands, as
numba's and matplotlib's caches are.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
import time
from functools import lru_cache
from pathlib import Path
from typing import Any

ENV_DIR = "SHIPTRIAL_CACHE_DIR"  # the cache directory; set to "" to use no cache
MAGIC = b"shiptrial-plan-cache 1\n"
KEEP = 32  # entries kept (about 0.5 MB each for the bundled example)
ROOT = Path(__file__).resolve().parent.parent
# cli too: the entry holds the export chart built by cli.plan_cmd.export_chart, and the command's glue decides the inputs
PACKAGES = ("primitives", "expdesign", "maps", "identify", "diagnose", "cli")
SUFFIXES = (".py", ".toml", ".geojson", ".json")
# the numerical libraries a plan is computed with: the design's conic solvers too (cvxpy, Clarabel and SCS solve
# the E, robust and constrained designs, expdesign.dopt)
LIBRARIES = ("numpy", "scipy", "shapely", "pyproj", "numba", "cvxpy", "clarabel", "scs")


def default_dir() -> Path | None:
    """``$SHIPTRIAL_CACHE_DIR`` (None when set to an empty string: no cache), else
    ``$XDG_CACHE_HOME/shiptrial/plans`` (``~/.cache/shiptrial/plans`` by default)."""
    given = os.environ.get(ENV_DIR)
    if given is not None:
        return Path(given).expanduser() if given.strip() else None
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        home = os.path.expanduser("~")
        if home == "~":  # no HOME and no password entry: no user cache rather than a './~' directory
            return None
        base = os.path.join(home, ".cache")
    return Path(base) / "shiptrial" / "plans"


@lru_cache(maxsize=1)
def code_version() -> str:
    """Digest of the code a plan is computed with: the project's source and data files (path and
    bytes), the versions of Python and of the numerical libraries, and the kernel choice."""
    from importlib.metadata import PackageNotFoundError, version

    h = hashlib.sha256(sys.version.encode())
    for pkg in PACKAGES:
        for p in sorted((ROOT / pkg).rglob("*")):
            if p.suffix in SUFFIXES and "__pycache__" not in p.parts:
                h.update(str(p.relative_to(ROOT)).encode() + b"\0" + p.read_bytes() + b"\0")
    for lib in LIBRARIES:
        try:
            h.update(f"{lib}={version(lib)}\0".encode())
        except PackageNotFoundError:
            h.update(f"{lib}=none\0".encode())
    h.update(os.environ.get("SHIPTRIAL_KERNEL", "").encode())
    return h.hexdigest()


def plan_key(profile: Any, map_file: Path, **inputs: Any) -> str:
    """The cache key of a plan: ``profile`` (the loaded ShipProfile), the map file's resolved path
    and bytes (the path too: the planner's defaults depend on whether the map is the bundled
    example, and the plan's messages and the export chart name and read the file) and every other input of :func:`maps.planner.plan_with_design` by name (options, design options,
    counts, scenario, start, goal, vessel name). Two calls give the same key only for equal inputs
    (pickle writes each value's content); unequal objects of equal content may give two keys,
    which only costs a recomputation."""
    h = hashlib.sha256(code_version().encode())
    h.update(str(Path(map_file).resolve()).encode() + b"\0")
    h.update(hashlib.sha256(Path(map_file).read_bytes()).digest())
    h.update(pickle.dumps((profile, sorted(inputs.items())), protocol=pickle.HIGHEST_PROTOCOL))
    return h.hexdigest()


def _entry(directory: Path, key: str) -> Path:
    return Path(directory) / f"{key}.plan"


def load(directory: Path | None, key: str) -> dict[str, Any] | None:
    """The entry under ``key`` (a dict with at least ``plan``, a Plan); None when there is none or it
    cannot be read (missing, truncated, corrupted, written by other code): the caller plans afresh."""
    if directory is None:
        return None
    path = _entry(directory, key)
    try:
        data = path.read_bytes()
    except OSError:
        return None
    head = len(MAGIC) + 64
    if not data.startswith(MAGIC) or hashlib.sha256(data[head:]).hexdigest().encode() != data[len(MAGIC) : head]:
        return None
    try:
        entry = pickle.loads(data[head:])
    except Exception:  # noqa: BLE001 - an entry this code cannot read is no entry
        return None
    from maps.plan import Plan

    if not isinstance(entry, dict) or not isinstance(entry.get("plan"), Plan):
        return None
    try:
        os.utime(path)  # recently used: pruned last
    except OSError:
        pass
    return entry


def store(directory: Path | None, key: str, entry: dict[str, Any]) -> None:
    """Write ``entry`` (a dict holding ``plan``) under ``key`` (temporary file and rename: a reader never sees half an
    entry) and remove the oldest entries beyond :data:`KEEP`. An entry that cannot be pickled, or a
    cache that cannot be written (read-only, full disk), is skipped without a word: the command's outputs do not depend on it."""
    if directory is None:
        return
    try:
        payload = pickle.dumps(entry, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - a plan holding something pickle cannot write (a local function) is not kept
        return
    try:
        from primitives.io import atomic_write_bytes

        atomic_write_bytes(_entry(directory, key), MAGIC + hashlib.sha256(payload).hexdigest().encode() + payload)
        _prune(Path(directory))
    except OSError:
        pass


def _prune(directory: Path) -> None:
    entries = sorted(directory.glob("*.plan"), key=lambda p: p.stat().st_mtime_ns, reverse=True)
    for old in entries[KEEP:]:
        old.unlink(missing_ok=True)
    # a writer killed outright (SIGKILL, power loss) leaves its temporary file (atomic_write_bytes: .KEY.plan.XXXX);
    # one an hour old is no write in progress
    for tmp in directory.glob(".*.plan.*"):
        if time.time() - tmp.stat().st_mtime > 3600:
            tmp.unlink(missing_ok=True)
