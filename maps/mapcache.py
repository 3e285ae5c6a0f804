"""The projected sea map kept on disk between commands, as the ship's lattice moves are
(:mod:`maps.movecache`): :func:`maps.geo.load_map` reads the GeoJSON, repairs and projects every
feature and unites the land, the shallow water and the obstacles (0.22-0.27 s of CPU for the bundled
Helsinki map, measured at load 10-14), while the map it makes depends only on the file's bytes, the
draught and under-keel clearance, and the code. :func:`load_map_kept` reads it back in about 3 ms (CPU, key included, load 2.7).

The key is a SHA-256 digest of :func:`maps.plancache.code_version` (the project's sources and the
numerical libraries' versions: shapely's GEOS and pyproj's PROJ make the geometry), the machine
(:func:`maps.movecache.machine`, as for the moves), the path as given (the map keeps it as its
``source``), the file's bytes and the load's options. The entries live beside the plan cache's
(``*.map``, at most :data:`maps.plancache.MAPS_BYTES` bytes of them, the least recently used removed first) in
its checked format, the key inside the payload: a missing, truncated, unreadable or misnamed entry
is loaded again, never an error; a map that cannot be loaded is never kept (the load reports it in
its own words), nor one whose file changed between its key and its load. ``SHIPTRIAL_CACHE_DIR=""`` keeps no cache; ``plan-trial --no-cache`` still reads and
writes it, as it does the moves: it plans afresh on the map the file gives, bit for bit. The export chart of the
map (:func:`maps.export.chart.chart_of`: land and no-go areas in lon/lat, the file's depth areas) is kept in the
same entry and read with it (:func:`kept_chart`). What the planner makes from that map alone is kept beside it, as
``*.map`` entries keyed by the map's key and their arguments (stop 56): the obstacles grown by the margin
(:func:`kept_no_go`) and the collision grid's blocked cells (:func:`kept_grid`). Stop 57 added the lattice moves' placements on that grid
(:func:`kept_placements`, keyed by the map's key and a digest of the grid, options and moves: 72 kB bit-packed for
the default ship; `benchmarks/bench_placements_kept.py`: 0.16-0.18 s of this process's CPU made, the forked helper's
half beside it, against 2-3 ms read back, load 16). On the bundled map for the default
ship (a scratch script outside the repository, least CPU of 7, load 4.4-5.3; docs/kernel-speed.md, stop 56): made,
0.026-0.032 s
for the no-go area at 20 m and 0.039-0.044 s for the grid; read back, about 2 ms each. Those are the figures
:func:`kept_no_go`, :func:`kept_grid` and :class:`maps.collision.CollisionGrid` refer to.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from shapely.geometry.base import BaseGeometry

from maps import plancache
from maps.geo import SeaMap, load_map, map_source

if TYPE_CHECKING:
    from maps.collision import CollisionGrid, Window


def key(path: str | Path | None, *, draught_m: float, ukc_m: float, repair: bool) -> str | None:
    """The entry's key of :func:`maps.geo.load_map` with these arguments (None when the cache is off or
    the file cannot be read: the load then reports it)."""
    from maps.movecache import machine

    if plancache.default_dir() is None:
        return None
    src = map_source(path)
    try:
        digest = plancache.map_digest(src)
    except OSError:
        return None
    h = hashlib.sha256(f"map\0{plancache.code_version()}\0{machine()}\0{src}\0{draught_m!r}\0{ukc_m!r}\0{repair!r}\0".encode())
    h.update(digest)
    return h.hexdigest()


def load_map_kept(path: str | Path | None = None, *, draught_m: float = 0.0, ukc_m: float = 0.5, repair: bool = True) -> SeaMap:
    """:func:`maps.geo.load_map` of these arguments, read from the cache when it holds it (and kept
    there once loaded otherwise): the same map, bit for bit."""
    k = key(path, draught_m=draught_m, ukc_m=ukc_m, repair=repair)
    directory = plancache.default_dir()
    if k is not None and directory is not None:
        entry = plancache.load_blob(Path(directory), f"{k}.map")
        # the key inside the entry: a file copied or renamed onto another key's name is no entry
        if isinstance(entry, tuple) and len(entry) == 3 and entry[0] == k and isinstance(entry[1], SeaMap):
            return _keep_chart(entry[1], entry[2], k)
    sea = load_map(path, draught_m=draught_m, ukc_m=ukc_m, repair=repair)
    # kept only when the file still holds the bytes keyed: one edited while it loaded would otherwise leave
    # the edited file's map under the earlier bytes' key, read for those bytes when the edit is undone
    if k is not None and directory is not None and key(path, draught_m=draught_m, ukc_m=ukc_m, repair=repair) == k:
        from maps.export.chart import chart_of

        try:
            chart = chart_of(sea)
        except Exception:  # noqa: BLE001 - the chart is the exports': their own call makes it, or says what fails
            chart = None
        plancache.store_blob(Path(directory), f"{k}.map", (k, sea, chart))
        _keep_chart(sea, chart, k)
    return sea


def _keep_chart(sea: SeaMap, chart: Any, k: str) -> SeaMap:
    """Hold ``chart`` as the chart of ``sea``, the map :func:`load_map_kept` returns (one at a time), and its key."""
    _CHARTS.clear()
    _CHARTS[id(sea)] = (sea, chart, k)
    return sea


# the export chart and the key of the map load_map_kept last returned (its id, the map held beside them and checked
# by identity)
_CHARTS: dict[int, tuple[SeaMap, Any, str]] = {}


def kept_chart(sea: SeaMap) -> Any:
    """:func:`maps.export.chart.chart_of` of ``sea``: the chart kept with the map when ``sea`` is the map
    :func:`load_map_kept` returned (made from it when it was kept, read with it: 0.09-0.1 s of CPU a plan on
    the bundled map, measured in stop 52's profile), else made now."""
    from maps.export.chart import chart_of

    kept = _CHARTS.get(id(sea))
    if kept is not None and kept[0] is sea and kept[1] is not None:
        return kept[1]
    return chart_of(sea)


# ---------------------------------------------------------------- what the planner makes from the map alone


def _derived_key(sea: SeaMap, what: str, params: tuple) -> tuple[Path, str] | None:
    """The cache directory and the key of ``what`` made from ``sea`` with ``params`` (plain values, by their repr):
    the map's own key (code, machine, file, load options) and those; None when ``sea`` is not the map
    :func:`load_map_kept` last returned or the cache is off. The one directory serves the read and the store, so
    the two cannot disagree."""
    kept = _CHARTS.get(id(sea))
    directory = plancache.default_dir()
    if kept is None or kept[0] is not sea or directory is None:
        return None
    return Path(directory), hashlib.sha256(f"{what}\0{kept[2]}\0{params!r}\0".encode()).hexdigest()


def _read_derived(where: tuple[Path, str] | None) -> Any:
    """The value kept under ``where`` (directory, derived key); None when there is none: no key, or the entry
    missing, damaged or misnamed."""
    if where is None:
        return None
    directory, k = where
    entry = plancache.load_blob(directory, f"{k}.map")
    return entry[1] if isinstance(entry, tuple) and len(entry) == 2 and entry[0] == k else None


def _store_derived(where: tuple[Path, str] | None, value: Any) -> None:
    """Keep ``value`` under ``where`` (directory, derived key), the key inside the entry; nothing when no key."""
    if where is not None:
        directory, k = where
        plancache.store_blob(directory, f"{k}.map", (k, value))


def kept_no_go(sea: SeaMap, margin: float) -> None:
    """Make ``sea.no_go(margin)`` ready, read from the cache when it was made before for this map (a buffer of the
    whole coastline: see the module's figures), else made and kept. The geometry read back has the made one's
    coordinates (shapely pickles it as WKB), so every use is the same. A margin of 0 or less keeps nothing: no_go
    then buffers nothing, and without a trial area is the map's obstacles themselves, whose entry would be a second
    copy of the whole obstacle set."""
    if margin <= 0 or sea.has_no_go(margin):
        return
    where = _derived_key(sea, "no_go", (float(margin),))
    geom = _read_derived(where)
    if isinstance(geom, BaseGeometry):
        sea.adopt_no_go(margin, geom)
        return
    _store_derived(where, sea.no_go(margin))


def kept_grid(sea: SeaMap, window: Window, margin: float, sub: int, pad_m: float) -> CollisionGrid:
    """:class:`maps.collision.CollisionGrid` of these arguments, its blocked cells read from the cache when they were
    made before for this map and arguments (see the module's figures), else made and kept (bit-packed: 34 kB for
    the default ship's 513 x 537 cells)."""
    import numpy as np

    from maps.collision import CollisionGrid

    w = (float(window.x0), float(window.y0), float(window.res), int(window.ni), int(window.nj))
    where = _derived_key(sea, "grid", (w, float(margin), int(sub), float(pad_m)))
    kept = _read_derived(where)
    blocked = None
    if isinstance(kept, tuple) and len(kept) == 2 and isinstance(kept[1], bytes):
        shape = tuple(kept[0])
        bits = np.frombuffer(kept[1], dtype=np.uint8)
        if len(shape) == 2 and bits.size * 8 >= shape[0] * shape[1]:
            blocked = np.unpackbits(bits, count=shape[0] * shape[1]).astype(bool).reshape(shape)
    grid = CollisionGrid(sea, window, margin, sub, pad_m, blocked=blocked)
    if blocked is None:
        _store_derived(where, (grid.blocked.shape, np.packbits(grid.blocked).tobytes()))
    return grid


def kept_placements(sea: SeaMap, inputs: Callable[[], str], shape: tuple[int, int, int, int], make: Callable[[], list]) -> list:
    """The lattice moves' placements (:meth:`maps.chain.Lattice.placements`: per move and heading, the lattice points
    where its footprint is collision-free and those inside the soft clearance zone), read from the cache when they
    were made before for this map and ``inputs()`` (the digest of everything else they are made from:
    :meth:`maps.chain.Lattice.placement_inputs`, called only when the entry could be kept), else made by ``make`` and kept, bit-packed. ``shape``: (moves,
    headings, ni, nj); an entry of another shape or length is made again. Read back, the same boolean arrays, read-only
    (as ``make`` must return them, so that both paths behave alike)."""
    import numpy as np

    where = _placements_key(sea, inputs, shape)
    kept = _read_derived(where)
    size = int(np.prod(shape))
    if isinstance(kept, bytes) and len(kept) == (2 * size + 7) // 8:
        both = np.unpackbits(np.frombuffer(kept, dtype=np.uint8), count=2 * size).astype(bool).reshape((2, *shape))
        both.flags.writeable = False
        return [[(both[0, mi, h], both[1, mi, h]) for h in range(shape[1])] for mi in range(shape[0])]
    out = make()
    if where is not None:
        both = np.array([[[p[k] for p in per] for per in out] for k in range(2)], dtype=bool)
        if both.shape == (2, *shape):  # made as described: kept
            _store_derived(where, np.packbits(both).tobytes())
    return out


def _placements_key(sea: SeaMap, inputs: Callable[[], str], shape: tuple[int, int, int, int]) -> tuple[Path, str] | None:
    """:func:`kept_placements`' entry (directory, derived key), None when it cannot be kept; ``inputs()`` (the digest)
    called only when it can. The one key of the read, the store and ``benchmarks/bench_placements_kept.py``."""
    if _derived_key(sea, "placements", ()) is None:
        return None
    return _derived_key(sea, "placements", (inputs(), tuple(int(n) for n in shape)))
