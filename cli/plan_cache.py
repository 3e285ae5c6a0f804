"""``shiptrial plan``'s use of the plan cache for its output files: a run whose plan was read from the
cache (:mod:`maps.plancache`) and whose files were written before for the same start time copies
those files' bytes instead of drawing and exporting again (the figures' drawer, the crew exports:
about 2.6 s of a cached run's 3.2 s of CPU before); one at another start time copies the figures no start
time changes (:data:`FIGURES`, kept per plan entry) and exports the rest. The files are functions of the cached
plan, its start time, the code and the drawing libraries and configuration (:func:`maps.plancache.outputs_key`),
so the copy is byte for byte what exporting would write. Also the plan's own entry: its key
(:func:`cache_slot`) and its reading (:func:`read_cached`)."""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # annotations only
    from maps.geo import SeaMap
    from maps.plan import Plan
    from maps.trialdesign import TrialDesign

_HINT: list[Path] = []  # this command line's hint file (expect_kept_files), until note_kept updates it


def expect_kept_files(args: list[str]) -> bool:
    """Whether the last run of this command line (``args`` with ``--out`` left out, in this directory) found or
    kept its output files, for a start time that still holds: ``plan-trial`` then forks no drawer before parsing
    (:func:`cli.drawer.start_early`), whose imports (about 0.5 s of CPU) a run that copies its files throws away.
    Only a guess: a run that finds no files draws them all the same (its drawer started later)."""
    from maps.plancache import default_dir

    _HINT.clear()
    directory = default_dir()
    if directory is None:
        return False
    words, skip = [], False
    for a in args:
        if not skip and a != "--out" and not a.startswith("--out="):
            words.append(a)
        skip = a == "--out" and not skip
    try:
        path = directory / (hashlib.sha256("\0".join([os.getcwd(), *words]).encode()).hexdigest()[:32] + ".hint")
        _HINT.append(path)
        return time.time() < float(path.read_text())
    except (OSError, ValueError):  # no hint, a damaged one, or a working directory removed: the drawer forks early
        return False


def forget_command() -> None:
    """Forget this command line's hint file (the command has ended; a later one in this process has its own)."""
    _HINT.clear()


def note_kept(cache_dir: Path | None, kept: bool, default_start: datetime | None) -> None:
    """Record for :func:`expect_kept_files` whether this command line's files are kept, until ``default_start``
    when the start time was the default one (the next full hour: the next run's files differ from then on)."""
    if not _HINT:
        return
    path = _HINT.pop()
    try:
        if kept and cache_dir is not None and path.parent == Path(cache_dir):
            path.write_text(repr(default_start.timestamp()) if default_start is not None else "inf")
        else:
            path.unlink(missing_ok=True)
    except OSError:  # a cache that cannot be written: the next run forks its drawer early
        pass


def saved_outputs(
    cache_dir: Path | None, plan_key: str | None, digest: str | None, start_utc: str, drawing: str | None = None
) -> dict[str, Any] | None:
    """The output set kept for the plan entry of ``digest`` under ``plan_key`` starting at ``start_utc``; None when
    there is none. ``drawing``: :func:`maps.plancache.drawing_version`, when known."""
    from maps import plancache

    if cache_dir is None or plan_key is None or not digest:
        return None
    try:
        key = plancache.outputs_key(plan_key, digest, start_utc, drawing)
    except Exception:  # noqa: BLE001 - a cache that cannot be keyed is no cache: the files are drawn as without one
        return None
    saved = plancache.load_outputs(cache_dir, key) if key is not None else None
    if saved is None or not all(_plain(k) and isinstance(v, bytes) for k, v in saved["bytes"].items()):
        return None
    names = saved["files"]
    if not all(isinstance(v, str) for v in names.values()) or not set(names.values()) <= saved["bytes"].keys():
        return None
    return saved


def restore_outputs(saved: dict[str, Any], out: Path) -> dict[str, Path]:
    """Write the saved set's files into the (temporary) output directory ``out``; returns its files by name."""
    for rel, data in saved["bytes"].items():
        (out / rel).write_bytes(data)
        os.chmod(out / rel, 0o644)  # as the exporters leave them (primitives.io.atomic_write_bytes), whatever the umask
    return {name: out / rel for name, rel in saved["files"].items()}


def keep_outputs(
    cache_dir: Path | None, plan_key: str | None, digest: str | None, start_utc: str, files: dict[str, Path], out: Path
) -> bool:
    """Keep the files just written into ``out`` (every one but the output directory's marker) for the next run
    of the plan entry of ``digest`` under ``plan_key`` with the same start time, and its figures
    (:data:`FIGURES`) for a run of that entry at any start time (:func:`saved_sets`; skipped when the figures'
    configuration cannot be keyed); True when kept."""
    from maps.plancache import drawing_version
    from primitives.io import OUTPUT_MARKER

    if cache_dir is None or plan_key is None or not digest:
        return False
    try:  # keyed now: a first run's drawer has just built matplotlib's font list
        drawing = drawing_version()
    except Exception:  # noqa: BLE001 - never a failed run for a cache
        return False
    written = [p for p in sorted(out.iterdir()) if p.name != OUTPUT_MARKER]
    names = {name: Path(p).name for name, p in files.items()}
    kept = _keep(cache_dir, plan_key, digest, start_utc, drawing, names, written)
    figures = {name: rel for name, rel in names.items() if name in FIGURES}
    if kept and figures:
        _keep(cache_dir, plan_key, digest, _ANY_START, drawing, figures, [out / rel for rel in figures.values()])
    return kept


# the files no start time changes (plan.png, the design ratios, the track and states PNGs, the two GeoJSON files: none
# is given the start time): kept for the plan entry whatever the start time, so a run of a cached plan at another hour
# copies them instead of drawing or exporting them again
FIGURES = ("plot", "design_ratios_png", "track_png", "states_png", "trajectory_geojson", "geojson")
_ANY_START = "any start time"  # in the figures' output key, where a start time's ISO string is otherwise


def saved_sets(
    cache_dir: Path | None, plan_key: str | None, digest: str | None, start_utc: str
) -> tuple[dict[str, Any] | None, dict[str, bytes] | None]:
    """The output set kept for the plan entry of ``digest`` under ``plan_key`` at ``start_utc``
    (:func:`saved_outputs`), and when there is none the figures (:data:`FIGURES`, bytes by file name) kept for
    that entry at any start time; each None when there is none."""
    from maps.plancache import drawing_version

    if cache_dir is None or plan_key is None or not digest:
        return None, None
    try:
        drawing = drawing_version()
    except Exception:  # noqa: BLE001 - as saved_outputs: a cache that cannot be keyed is no cache
        return None, None
    if drawing is None:  # matplotlib's font list not built yet: nothing kept can be keyed
        return None, None
    saved = saved_outputs(cache_dir, plan_key, digest, start_utc, drawing)
    if saved is not None:
        _touch_figures(cache_dir, plan_key, digest, drawing)
        return saved, None
    figures = saved_outputs(cache_dir, plan_key, digest, _ANY_START, drawing)
    if figures is None or not set(figures["files"]) <= set(FIGURES):
        return None, None
    return None, figures["bytes"]


def _touch_figures(cache_dir: Path, plan_key: str, digest: str, drawing: str) -> None:
    """Mark the plan entry's figures (:data:`FIGURES`, kept at any start time) recently used: a run that restores its own
    start time's set reads them from that set, and without this the figures entry would age as if unused and be pruned
    before the sets that a later hour's run would need it beside."""
    from maps import plancache

    # no try: with ``drawing`` known the key is a hash of strings, which cannot fail (saved_outputs's may be asked to
    # find the drawing version itself); touch_outputs passes over a file it cannot touch
    key = plancache.outputs_key(plan_key, digest, _ANY_START, drawing)
    if key is not None:
        plancache.touch_outputs(cache_dir, key)


def _keep(
    cache_dir: Path, plan_key: str, digest: str, start_utc: str, drawing: str | None, names: dict[str, str], written: list[Path]
) -> bool:
    """Keep the files ``written`` (named by ``names``: output name -> file name) under the output key of the plan
    entry and ``start_utc`` (``drawing``: :func:`maps.plancache.drawing_version`); True when kept."""
    from maps import plancache

    if drawing is None:
        return False
    try:  # a cache that cannot be keyed or read back is skipped: the run's own files are written all the same
        key = plancache.outputs_key(plan_key, digest, start_utc, drawing)
        if key is None:
            return False
        if all(p.is_file() and _plain(p.name) for p in written):  # flat, as every output set is today
            data = {p.name: p.read_bytes() for p in written}
            if set(names.values()) <= data.keys():
                return plancache.store_outputs(cache_dir, key, names, data) is not None
    except Exception:  # noqa: BLE001 - never a failed run for a cache
        pass
    return False


def _plain(rel: object) -> bool:
    """A file name directly in the output directory (no directory part, nothing hidden)."""
    return isinstance(rel, str) and PurePosixPath(rel).name == rel and rel not in ("", ".", "..") and not rel.startswith(".")


@dataclass
class Planned:
    """A plan and what its outputs are written from, read from the plan cache or made here: ``digest``,
    its cache entry's (None when not stored); ``t0``, the trial's start; ``saved`` and ``figures``, the
    output files kept in the cache for this plan and start time, or for another start time (the figures)."""

    result: Plan
    design: TrialDesign | None
    sea: SeaMap
    chart: Any
    digest: str | None
    t0: datetime
    saved: Any = None
    figures: Any = None


@dataclass
class CacheSlot:
    """Where this run's plan goes in the plan cache: ``dir`` None with the cache off, ``key`` None as
    well when the map file cannot be read; ``map_digest``, the map file's digest read before the key."""

    dir: Path | None = None
    key: str | None = None
    map_digest: bytes | None = None


def cache_slot(prof: Any, map_path: Path | None, inputs: dict[str, Any], cache: bool) -> CacheSlot:
    """This run's place in the plan cache (none with ``cache`` False or no cache directory)."""
    from maps import plancache

    cache_dir = plancache.default_dir() if cache else None
    if cache_dir is None:
        return CacheSlot()
    keyed_digest = map_digest(map_path)
    return CacheSlot(cache_dir, cache_key(prof, map_path, inputs), keyed_digest)


def read_cached(slot: CacheSlot, start_time: str | None, no_export: bool) -> Planned | None:
    """The plan the cache holds for this run (None on a miss, or for an entry this command did not
    write), with the output files kept for it (:func:`saved_sets`)."""
    from maps import plancache
    from maps.export._common import iso, resolve_start

    hit = plancache.load(slot.dir, slot.key) if slot.key is not None else None
    if hit is None or not {"design", "sea", "chart"} <= hit.keys():  # not an entry this command wrote
        return None
    result = hit["plan"]
    planned = Planned(result, hit["design"], hit["sea"], hit["chart"], hit["digest"], resolve_start(result, start_time))
    if result.feasible and not no_export:  # the files this plan and start time gave, when kept: nothing to draw
        # another start time's run drew the same figures: only the schedule's files differ
        planned.saved, planned.figures = saved_sets(slot.dir, slot.key, planned.digest, iso(planned.t0))
    return planned


def cache_key(prof: Any, map_path: Path | None, inputs: dict[str, Any]) -> str | None:
    """The plan cache's key of these inputs; None when the map file cannot be read (load_map then
    reports it in its own words)."""
    from maps import plancache
    from maps.geo import map_source

    try:
        return plancache.plan_key(prof, map_source(map_path), **inputs)
    except OSError:
        return None


def map_digest(map_path: Path | None) -> bytes | None:
    """The SHA-256 of the map file the plan cache keys (None when it cannot be read)."""
    from maps import plancache
    from maps.geo import map_source

    try:
        return plancache.map_digest(map_source(map_path))
    except OSError:
        return None
