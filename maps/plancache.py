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

Beside the plans, the files a command wrote from a plan can be kept (:func:`outputs_key`,
:func:`store_outputs`, :func:`load_outputs`: one entry per plan entry and start time, and one of the figures no
start time changes per plan entry (:mod:`cli.plan_cache`), the same header, :data:`KEEP_OUTPUTS` kept in all),
keyed on the plan's key, the plan entry's digest, the start time and :func:`drawing_version`.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from primitives.io import hash_sources, newest_first, prune_to_budget, remove_stale_temporaries, user_cache_dir

ENV_DIR = "SHIPTRIAL_CACHE_DIR"  # the cache directory; set to "" to use no cache
MAGIC = b"shiptrial-plan-cache 1\n"
KEEP = 32  # entries kept (about 0.5 MB each for the bundled example)
ROOT = Path(__file__).resolve().parent.parent
# cli too: the entry holds the export chart built by cli.plan_outputs.export_chart, and the command's glue decides the inputs
PACKAGES = ("primitives", "expdesign", "maps", "identify", "diagnose", "cli")
SUFFIXES = (".py", ".toml", ".geojson", ".json")
# the numerical libraries a plan is computed with: the design's conic solvers too (cvxpy, Clarabel and SCS solve
# the E, robust and constrained designs, expdesign.dopt)
LIBRARIES = ("numpy", "scipy", "shapely", "pyproj", "numba", "cvxpy", "clarabel", "scs")


def default_dir() -> Path | None:
    """``$SHIPTRIAL_CACHE_DIR`` (None when set to an empty string: no cache), else
    ``$XDG_CACHE_HOME/shiptrial/plans`` (``~/.cache/shiptrial/plans`` by default); None without a home directory."""
    return user_cache_dir(ENV_DIR, "plans")


@lru_cache(maxsize=1)
def code_version() -> str:
    """Digest of the code a plan is computed with: the project's source and data files (path and
    bytes), the versions of Python and of the numerical libraries, and the kernel choice."""
    h = hash_sources(hashlib.sha256(sys.version.encode()), ROOT, PACKAGES, SUFFIXES)
    h.update(_versions(LIBRARIES))
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
    h.update(map_digest(map_file))
    # the profile's fields, not the object: its cached properties (the compiled model) fill in as it plans
    h.update(pickle.dumps((fields_of(profile), sorted(inputs.items())), protocol=pickle.HIGHEST_PROTOCOL))
    return h.hexdigest()


def fields_of(obj: Any) -> list[tuple[str, Any]]:
    """A dataclass's fields by name (not what its cached properties hold: they depend on what ran before)."""
    return [(f.name, getattr(obj, f.name)) for f in fields(obj)]


def _pickled(value: Any) -> bytes:
    return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)


def fields_digest(obj: Any, dump: Callable[[Any], bytes] = _pickled) -> str:
    """SHA-256 of a dataclass's fields (:func:`fields_of`; any other object whole), each written by ``dump``
    on its own and framed by its name and length. An object and its copy read back from a pickle give the
    same digest, their whole pickles not always: pickle's memo writes a string shared by two fields once,
    and a fresh object shares other strings than one read back. Raises what ``dump`` raises."""
    h = hashlib.sha256()
    parts = fields_of(obj) if is_dataclass(obj) and not isinstance(obj, type) else [("", obj)]
    for name, value in parts:
        data = dump(value)
        h.update(name.encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    return h.hexdigest()


def map_digest(map_file: Path) -> bytes:
    """SHA-256 of the map file's bytes, as the plan and map caches key them (OSError when it cannot be read)."""
    return hashlib.sha256(Path(map_file).read_bytes()).digest()


# the libraries the exports and figures are written with (drawing, fonts, PDF, images, XML)
DRAWING = ("matplotlib", "fpdf2", "pillow", "fonttools", "contourpy", "kiwisolver", "pyparsing", "cycler", "lxml", "defusedxml")
KEEP_OUTPUTS = 8  # output sets kept, a plan's figures set among them (about 2.8 MB a set for the bundled example)
# bytes of lattice move sets kept (maps.movecache: one per ship, options, kernel state and basic set or primitive,
# 0.1-2 MB each: the default ship's plan writes 6, 1.1 MB; kvlcc2 on the open sea 5, 4.4 MB). A byte budget, not a
# count: a ship that redesigns many times writes many entries, and their size grows with the ship and the resolution
MOVES_BYTES = 64 * 2**20
#: bytes of projected sea maps kept (maps.mapcache: 0.16 MB for the bundled example; a chart's size grows with its
#: coastline, so a count would not bound the disk a few national charts take)
MAPS_BYTES = 64 * 2**20


def _versions(libraries: tuple[str, ...]) -> bytes:
    from importlib.metadata import PackageNotFoundError

    out = []
    for lib in libraries:
        try:
            out.append(f"{lib}={installed_version(lib)}\0")
        except PackageNotFoundError:
            out.append(f"{lib}=none\0")
    return "".join(out).encode()


def installed_version(lib: str) -> str:
    """``importlib.metadata.version(lib)``, read from the metadata's ``Version:`` header line rather than by
    parsing the whole file as an e-mail message (numpy's and scipy's hold their README): about 0.004 s of CPU against
    0.010-0.012 s for the 8 numerical libraries in a fresh process (stop 56 review mend, 3 alternated runs, load 3.4;
    docs/kernel-speed.md), the same string: the value as
    the e-mail parser gives it (leading blanks dropped). A header folded over lines, or none found, is left to the
    parser. PackageNotFoundError when ``lib`` is not installed."""
    from importlib.metadata import distribution

    dist = distribution(lib)
    lines = (dist.read_text("METADATA") or dist.read_text("PKG-INFO") or dist.read_text("") or "").splitlines()
    for i, line in enumerate(lines):
        if not line.strip():  # the end of the headers
            break
        if line.startswith("Version:"):
            if i + 1 < len(lines) and lines[i + 1][:1] in (" ", "\t"):  # folded: the parser joins it
                break
            return line[len("Version:") :].lstrip(" \t")
    return dist.version


def _matplotlib_dir(env: str, default: str) -> Path:
    """matplotlib's configuration or cache directory as matplotlib finds it (``$MPLCONFIGDIR``, else the XDG one)."""
    if os.environ.get("MPLCONFIGDIR"):
        return Path(os.environ["MPLCONFIGDIR"]).expanduser()
    return Path(os.environ.get(env) or Path("~", default).expanduser()) / "matplotlib"


def drawing_version() -> str | None:
    """Digest of what the figures depend on beyond the plan and the code: the drawing libraries' versions,
    every matplotlibrc matplotlib would read (``./matplotlibrc``, ``$MATPLOTLIBRC``, its configuration
    directory's), the font list it picks fonts from (its cache's ``fontlist-*.json``) and the size and time of
    the font files it names (:func:`_font_files`). None when
    that font list does not exist (matplotlib then lists the fonts installed at that moment): nothing
    to key the figures' fonts on; None too when the working directory or the home directory cannot be found."""
    try:
        fontlists = sorted(_matplotlib_dir("XDG_CACHE_HOME", ".cache").glob("fontlist-*.json"))
        rc = os.environ.get("MATPLOTLIBRC", "")
        here = Path.cwd() / "matplotlibrc"
        config = _matplotlib_dir("XDG_CONFIG_HOME", ".config") / "matplotlibrc"
    except (OSError, RuntimeError):  # no working directory (removed) or no home: what matplotlib reads is unknown
        return None
    if not fontlists:
        return None
    h = hashlib.sha256(_versions(DRAWING))
    candidates = [here, Path(rc), Path(rc) / "matplotlibrc"] if rc else [here]
    candidates += [config, *fontlists]
    for p in candidates:
        try:
            h.update(str(p).encode() + b"\0" + p.read_bytes() + b"\0")
        except OSError:  # absent (or a directory): read by neither
            h.update(str(p).encode() + b"\0-\0")
    h.update(_font_files(fontlists))
    return h.hexdigest()


def _font_files(fontlists: list[Path]) -> bytes:
    """Size and modification time of every font file outside matplotlib's own (whose fonts change with its version)
    that the font lists name: a system font updated in place (a font package upgrade) leaves the list as it was
    but changes the glyphs drawn and embedded."""
    import json

    out = []
    for fontlist in fontlists:
        try:
            listed = json.loads(fontlist.read_bytes())
            names = sorted({f["fname"] for kind in ("ttflist", "afmlist") for f in listed.get(kind, [])})
        except (OSError, ValueError, TypeError, KeyError, AttributeError):  # unreadable: its bytes are in the key already
            continue
        for name in names:
            if not isinstance(name, str) or not os.path.isabs(name):
                continue
            try:
                st = os.stat(name)
                out.append(f"{name}\0{st.st_size}\0{st.st_mtime_ns}\0")
            except OSError:
                out.append(f"{name}\0-\0")
    return "".join(out).encode()


def outputs_key(plan_key: str, entry_digest: str, start_utc: str, drawing: str | None = None) -> str | None:
    """The key of the files the command writes for the plan entry of digest ``entry_digest`` under ``plan_key``
    with the trial starting at ``start_utc`` (every export and figure: functions of that entry's plan, its start
    time, the code (in the plan's key) and :func:`drawing_version`; the entry's digest too, so that files are
    never served with a plan computed again, whose plan.json timings differ); None when the figures' fonts cannot
    be keyed. ``drawing``: :func:`drawing_version` when the caller has it already (about 22 ms of CPU)."""
    drawing = drawing or drawing_version()
    if drawing is None:
        return None
    return hashlib.sha256(f"outputs\0{plan_key}\0{entry_digest}\0{start_utc}\0{drawing}".encode()).hexdigest()


def load_outputs(directory: Path | None, key: str) -> dict[str, Any] | None:
    """The output set under ``key``: ``{"files": {name: relative path}, "bytes": {relative path: bytes}}``; None when
    there is none or it cannot be read."""
    if directory is None:
        return None
    entry, _ = _read(Path(directory) / f"{key}.out")
    ok = isinstance(entry, dict) and isinstance(entry.get("files"), dict) and isinstance(entry.get("bytes"), dict)
    return entry if ok else None


def touch_outputs(directory: Path | None, key: str) -> None:
    """Mark the output set under ``key`` recently used (pruned last, as reading it would), without reading it: a
    run that restores its own start time's set uses the plan entry's figures too (they are in that set)."""
    if directory is None:
        return
    try:
        os.utime(Path(directory) / f"{key}.out")
    except OSError:  # none kept (or the cache is read-only): nothing to keep longer
        pass


def store_outputs(directory: Path | None, key: str, files: dict[str, str], data: dict[str, bytes]) -> str | None:
    """Keep the output set ``files`` (name -> path relative to the output directory) with every file's ``data``
    under ``key``; skipped without a word as :func:`store` (None returned)."""
    return _write(directory, f"{key}.out", {"files": files, "bytes": data})


def load_blob(directory: Path, name: str) -> Any:
    """The object kept in ``directory/name`` by :func:`store_blob` (None when missing or unreadable)."""
    return _read(Path(directory) / name)[0]


def store_blob(directory: Path, name: str, entry: Any) -> str | None:
    """Keep ``entry`` in ``directory/name`` in the checked format of the plan entries (skipped as :func:`store`)."""
    return _write(directory, name, entry)


def _entry(directory: Path, key: str) -> Path:
    return Path(directory) / f"{key}.plan"


def _read(path: Path) -> tuple[Any, str]:
    """The object pickled in the entry file ``path`` and its payload's digest; (None, "") when missing, truncated,
    corrupted or unreadable."""
    try:
        data = path.read_bytes()
    except OSError:
        return None, ""
    head = len(MAGIC) + 64
    digest = hashlib.sha256(data[head:]).hexdigest()
    if not data.startswith(MAGIC) or digest.encode() != data[len(MAGIC) : head]:
        return None, ""
    try:
        entry = pickle.loads(data[head:])
    except Exception:  # noqa: BLE001 - an entry this code cannot read is no entry
        return None, ""
    try:
        os.utime(path)  # recently used: pruned last
    except OSError:
        pass
    return entry, digest


def _write(directory: Path | None, name: str, entry: Any) -> str | None:
    """Pickle ``entry`` into ``directory/name`` behind its digest (temporary file and rename: a reader never sees
    half an entry) and prune; returns the digest, None when skipped (an entry pickle cannot write, a cache that
    cannot be written)."""
    if directory is None:
        return None
    try:
        payload = pickle.dumps(entry, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - a plan holding something pickle cannot write (a local function) is not kept
        return None
    digest = hashlib.sha256(payload).hexdigest()
    try:
        from primitives.io import atomic_write_bytes

        atomic_write_bytes(Path(directory) / name, MAGIC + digest.encode() + payload)
        _prune(Path(directory))
    except OSError:
        return None
    return digest


def load(directory: Path | None, key: str) -> dict[str, Any] | None:
    """The entry under ``key`` (a dict with at least ``plan``, a Plan), with the digest of its bytes under
    ``digest`` (what :func:`store` returned); None when there is none or it cannot be read (missing, truncated,
    corrupted, written by other code): the caller plans afresh."""
    if directory is None:
        return None
    entry, digest = _read(_entry(directory, key))
    from maps.plan import Plan

    if not isinstance(entry, dict) or not isinstance(entry.get("plan"), Plan):
        return None
    return entry | {"digest": digest}


def store(directory: Path | None, key: str, entry: dict[str, Any]) -> str | None:
    """Write ``entry`` (a dict holding ``plan``) under ``key`` (temporary file and rename: a reader never sees half an
    entry) and remove the oldest entries beyond :data:`KEEP`. An entry that cannot be pickled, or a
    cache that cannot be written (read-only, full disk), is skipped without a word: the command's outputs do not depend on it.
    Returns the digest of the entry's bytes (None when skipped)."""
    return _write(directory, f"{key}.plan", entry)


def _prune(directory: Path) -> None:
    # .hint: cli.plan_cache's
    for suffix, keep in ((".plan", KEEP), (".out", KEEP_OUTPUTS), (".hint", KEEP)):
        for old, _ in newest_first(directory, suffix)[keep:]:
            old.unlink(missing_ok=True)
    # maps.movecache's and maps.mapcache's: the most recently used within a byte budget
    for suffix, budget in ((".moves", MOVES_BYTES), (".map", MAPS_BYTES)):
        prune_to_budget(directory, suffix, budget)
    remove_stale_temporaries(directory, (".plan", ".out", ".moves", ".map"))
