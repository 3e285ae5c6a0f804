"""The projected sea map kept between commands (maps.mapcache): the same map as loading the file,
read back instead of loaded, never stale, never an error."""

from __future__ import annotations

import json
import pickle

import pytest

import maps.mapcache as mapcache
from maps.geo import MapError, load_map
from maps.testmaps import archipelago


def _same(a, b) -> bool:
    """Two SeaMaps hold the same values, geometries bit for bit (their WKB)."""
    va, vb = vars(a), vars(b)
    if va.keys() != vb.keys():
        return False
    for k in va:
        if k in ("_fwd", "_inv"):  # pyproj transformers: compared by what they compute
            continue
        x, y = va[k], vb[k]
        if hasattr(x, "wkb"):
            if x.wkb != y.wkb:
                return False
        elif pickle.dumps(x) != pickle.dumps(y):
            return False
    return a.to_lonlat(1234.5, -678.9) == b.to_lonlat(1234.5, -678.9)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(d))
    return d


@pytest.fixture
def map_file(tmp_path):
    p = tmp_path / "arch.geojson"
    p.write_text(json.dumps(archipelago()))
    return p


def test_second_load_reads_the_same_map(cache, map_file, monkeypatch):
    first = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert len(list(cache.glob("*.map"))) == 1
    assert _same(first, load_map(map_file, draught_m=6.0))

    def refuse(*a, **k):
        raise AssertionError("loaded again")

    monkeypatch.setattr(mapcache, "load_map", refuse)
    again = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert again is not first and _same(again, first)


def test_changed_file_or_draught_is_loaded_again(cache, map_file):
    a = mapcache.load_map_kept(map_file, draught_m=6.0)
    b = mapcache.load_map_kept(map_file, draught_m=40.0)  # deeper: more shallow water is an obstacle
    assert _same(b, load_map(map_file, draught_m=40.0)) and not _same(a, b)
    doc = archipelago()
    doc["features"] = doc["features"][:-1]
    map_file.write_text(json.dumps(doc))
    c = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert _same(c, load_map(map_file, draught_m=6.0)) and not _same(a, c)
    assert len(list(cache.glob("*.map"))) == 3


def test_damaged_or_misnamed_entry_is_no_entry(cache, map_file):
    good = mapcache.load_map_kept(map_file, draught_m=6.0)
    (entry,) = cache.glob("*.map")
    entry.write_bytes(entry.read_bytes()[:-10])  # truncated
    assert _same(mapcache.load_map_kept(map_file, draught_m=6.0), good)
    # another key's entry copied onto this key's name
    other_key = mapcache.key(map_file, draught_m=40.0, ukc_m=0.5, repair=True)
    mapcache.load_map_kept(map_file, draught_m=40.0)
    (cache / f"{other_key}.map").replace(entry)
    assert _same(mapcache.load_map_kept(map_file, draught_m=6.0), good)


def test_no_cache_directory_keeps_nothing(tmp_path, map_file, monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", "")
    assert mapcache.key(map_file, draught_m=6.0, ukc_m=0.5, repair=True) is None
    assert _same(mapcache.load_map_kept(map_file, draught_m=6.0), load_map(map_file, draught_m=6.0))
    assert not list(tmp_path.rglob("*.map"))


def test_bad_map_is_refused_as_loading_refuses_it_and_not_kept(cache, tmp_path):
    bad = tmp_path / "bad.geojson"
    bad.write_text('{"type": "FeatureCollection", "features": [{"type": "Feature"}]}')
    with pytest.raises(MapError) as kept:
        mapcache.load_map_kept(bad)
    with pytest.raises(MapError) as direct:
        load_map(bad)
    assert str(kept.value) == str(direct.value)
    missing = tmp_path / "missing.geojson"
    with pytest.raises(MapError):
        mapcache.load_map_kept(missing)
    assert not list(cache.glob("*.map"))


def test_file_edited_while_loading_is_not_kept_under_its_old_bytes(cache, map_file, monkeypatch):
    original = map_file.read_bytes()
    doc = archipelago()
    doc["features"] = doc["features"][:-1]

    def edit_then_load(*a, **k):  # the user saves another version of the file after its bytes were keyed
        map_file.write_text(json.dumps(doc))
        return load_map(*a, **k)

    monkeypatch.setattr(mapcache, "load_map", edit_then_load)
    mapcache.load_map_kept(map_file, draught_m=6.0)
    monkeypatch.setattr(mapcache, "load_map", load_map)
    edited = mapcache.load_map_kept(map_file, draught_m=6.0)  # loaded from the edited file, kept under its bytes
    map_file.write_bytes(original)  # the edit undone
    assert _same(mapcache.load_map_kept(map_file, draught_m=6.0), load_map(map_file, draught_m=6.0))
    assert not _same(edited, load_map(map_file, draught_m=6.0))


def test_file_edited_in_place_with_the_same_size_and_time_is_loaded_again(cache, map_file):
    import os

    a = mapcache.load_map_kept(map_file, draught_m=6.0)
    text, st = map_file.read_text(), map_file.stat()
    i = next(i for i, ch in enumerate(text) if ch in "12345678" and text[i - 1] in "0123456789.")
    map_file.write_text(text[:i] + str(int(text[i]) + 1) + text[i + 1 :])  # one digit of one coordinate
    os.utime(map_file, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert map_file.stat().st_size == st.st_size and map_file.stat().st_mtime_ns == st.st_mtime_ns
    b = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert _same(b, load_map(map_file, draught_m=6.0)) and not _same(a, b)


def _chart_bits(c):
    """A chart's values, geometries as WKB (the depth areas' too)."""
    return (c.name, c.land.wkb, c.no_go.wkb, [(g.wkb, d) for g, d in c.depth_areas], c.extent)


def test_kept_chart_is_the_chart_of_the_map(cache, monkeypatch):
    # stop 52: the export chart is made once with the map and read with it; another map object is charted afresh
    import maps.export.chart as chart_mod
    from maps.geo import bundled_map_path

    path = bundled_map_path("helsinki")
    fresh = chart_mod.chart_of(load_map(path, draught_m=6.0))
    made = mapcache.load_map_kept(path, draught_m=6.0)
    assert _chart_bits(mapcache.kept_chart(made)) == _chart_bits(fresh)

    def refuse(*a, **k):
        raise AssertionError("charted again")

    monkeypatch.setattr(chart_mod, "chart_of", refuse)
    read = mapcache.load_map_kept(path, draught_m=6.0)
    assert read is not made and _chart_bits(mapcache.kept_chart(read)) == _chart_bits(fresh)
    monkeypatch.undo()
    other = load_map(path, draught_m=6.0)  # not the map the cache returned: charted now, the same bits
    assert mapcache.kept_chart(other) is not mapcache.kept_chart(read)
    assert _chart_bits(mapcache.kept_chart(other)) == _chart_bits(fresh)


def test_a_chart_that_fails_does_not_fail_the_map(cache, monkeypatch):
    # review of stop 52: the chart is the exports'; a map is kept and planned on even when charting it raises, and
    # the exports' own call makes it (here: raises again, where the export reports it)
    import maps.export.chart as chart_mod
    from maps.geo import bundled_map_path

    def broken(*a, **k):
        raise ValueError("no chart")

    monkeypatch.setattr(chart_mod, "chart_of", broken)
    path = bundled_map_path("helsinki")
    sea = mapcache.load_map_kept(path, draught_m=6.0)
    assert mapcache.load_map_kept(path, draught_m=6.0) is not sea  # kept: read back from its entry
    with pytest.raises(ValueError, match="no chart"):
        mapcache.kept_chart(sea)
    monkeypatch.undo()
    assert _chart_bits(mapcache.kept_chart(sea)) == _chart_bits(chart_mod.chart_of(load_map(path, draught_m=6.0)))


def test_an_entry_of_the_code_before_is_loaded_again(cache):
    # review of stop 52: an entry written before the chart was kept with the map (key, map) is no entry: loaded and
    # rewritten with its chart, no error
    from maps import plancache
    from maps.geo import bundled_map_path

    path = bundled_map_path("helsinki")
    k = mapcache.key(path, draught_m=6.0, ukc_m=0.5, repair=True)
    directory = plancache.default_dir()
    plancache.store_blob(directory, f"{k}.map", (k, load_map(path, draught_m=6.0)))
    sea = mapcache.load_map_kept(path, draught_m=6.0)
    assert len(plancache.load_blob(directory, f"{k}.map")) == 3 and mapcache.kept_chart(sea) is not None


# ---------------------------------------------------------------- what the planner makes from the map alone (stop 56)


def _grid_args(sea):
    from maps.collision import Window

    return Window(x0=-1500.0, y0=-1400.0, res=100.0, ni=30, nj=28), 20.0, 4, 600.0  # over the islands


def _fresh_no_go(sea, margin):
    import maps.geo as geo

    geo._NO_GO.clear()  # as a new process: made or read again
    mapcache.kept_no_go(sea, margin)
    return sea.no_go(margin)


def test_no_go_and_grid_read_back_are_the_ones_made(cache, map_file, monkeypatch):
    import numpy as np

    from maps.collision import CollisionGrid

    sea = mapcache.load_map_kept(map_file, draught_m=6.0)
    made = _fresh_no_go(sea, 20.0)
    win, margin, sub, pad = _grid_args(sea)
    grid = mapcache.kept_grid(sea, win, margin, sub, pad)
    assert len(list(cache.glob("*.map"))) == 3  # the map, its no-go area at 20 m and the grid

    def refuse(*a, **k):
        raise AssertionError("made again")

    monkeypatch.setattr(type(sea.obstacles), "buffer", refuse)  # no_go's buffer and the grid's
    monkeypatch.setattr(CollisionGrid, "_blocked", refuse)
    again = mapcache.load_map_kept(map_file, draught_m=6.0)  # a new command: another SeaMap object
    assert _fresh_no_go(again, 20.0).wkb == made.wkb
    kept = mapcache.kept_grid(again, win, margin, sub, pad)
    assert np.array_equal(kept.blocked, grid.blocked) and np.array_equal(kept.first, grid.first)
    assert kept.blocked.dtype == bool and kept.blocked.any() and not kept.blocked.all()


def test_derived_entries_are_keyed_by_map_and_arguments(cache, map_file):
    """Another margin, another window or another map file: made again, never an entry of other arguments."""
    import numpy as np

    from maps.collision import CollisionGrid

    sea = mapcache.load_map_kept(map_file, draught_m=6.0)
    win, margin, sub, pad = _grid_args(sea)
    mapcache.kept_grid(sea, win, margin, sub, pad)
    _fresh_no_go(sea, 20.0)
    assert _fresh_no_go(sea, 35.0).wkb == load_map(map_file, draught_m=6.0).no_go(35.0).wkb  # not the 20 m entry
    for args in ((win, 50.0, sub, pad), (win, margin, sub, 900.0)):
        assert np.array_equal(mapcache.kept_grid(sea, *args).blocked, CollisionGrid(sea, *args).blocked)
    doc = archipelago()
    doc["features"] = doc["features"][:-1]  # the map edited: its key, and so every derived key, changes
    map_file.write_text(json.dumps(doc))
    edited = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert np.array_equal(
        mapcache.kept_grid(edited, win, margin, sub, pad).blocked, CollisionGrid(edited, win, margin, sub, pad).blocked
    )
    import maps.geo as geo

    geo._NO_GO.clear()
    assert _fresh_no_go(edited, 20.0).wkb == edited.no_go(20.0).wkb
    assert len(list(cache.glob("*.map"))) == 2 + 1 + 2 + 2 + 2  # 2 maps, 2 grids + 2 others, 2 + 2 no-go areas


def test_missing_damaged_or_misnamed_derived_entry_is_made_again(cache, map_file):
    import numpy as np

    from maps.collision import CollisionGrid

    sea = mapcache.load_map_kept(map_file, draught_m=6.0)
    win, margin, sub, pad = _grid_args(sea)
    truth = CollisionGrid(sea, win, margin, sub, pad).blocked
    mapcache.kept_grid(sea, win, margin, sub, pad)
    (grid_entry,) = set(cache.glob("*.map")) - {cache / f"{mapcache.key(map_file, draught_m=6.0, ukc_m=0.5, repair=True)}.map"}
    grid_entry.write_bytes(grid_entry.read_bytes()[:-10])  # truncated
    assert np.array_equal(mapcache.kept_grid(sea, win, margin, sub, pad).blocked, truth)
    grid_entry.unlink()  # missing
    assert np.array_equal(mapcache.kept_grid(sea, win, margin, sub, pad).blocked, truth)
    from dataclasses import replace

    moved = replace(win, x0=win.x0 + 700.0)  # another key's entry (the same shape) copied onto this key's name
    other = mapcache.kept_grid(sea, moved, margin, sub, pad)
    (other_entry,) = set(cache.glob("*.map")) - {
        grid_entry,
        cache / f"{mapcache.key(map_file, draught_m=6.0, ukc_m=0.5, repair=True)}.map",
    }
    other_entry.replace(grid_entry)
    assert not np.array_equal(other.blocked, truth)
    assert np.array_equal(mapcache.kept_grid(sea, win, margin, sub, pad).blocked, truth)


def test_a_map_not_from_the_cache_keeps_nothing_derived(cache, map_file):
    """A SeaMap the caller loaded itself (no key known): made as before, nothing written."""
    import numpy as np

    from maps.collision import CollisionGrid

    sea = load_map(map_file, draught_m=6.0)
    win, margin, sub, pad = _grid_args(sea)
    assert np.array_equal(
        mapcache.kept_grid(sea, win, margin, sub, pad).blocked, CollisionGrid(sea, win, margin, sub, pad).blocked
    )
    assert _fresh_no_go(sea, 20.0).wkb == sea.no_go(20.0).wkb
    assert not list(cache.glob("*.map"))


def test_the_planner_uses_the_kept_no_go_area_and_grid(cache, monkeypatch):
    """build_lattice (the planner's lattice: its endpoints and collision grid) on a map from load_map_kept leaves the
    no-go area and the grid beside the map, and a second command's lattice reads them back: with the buffer and the
    grid's construction made to fail it is the same lattice. Fails if maps.chain makes either itself again."""
    import numpy as np

    import maps.geo as geo
    from maps.chain import PlanOptions, build_lattice
    from maps.collision import CollisionGrid
    from maps.motionset import resolve_primitives
    from primitives.ship import load_profile

    prof = load_profile("full-scale")
    counts = {"steep_zigzag_surge": 1}
    prims = resolve_primitives(prof, counts, None)
    moves: dict = {}  # the moves built once for both lattices: only the map's steps are under test

    def lattice():
        geo._NO_GO.clear()  # as a new process
        sea = mapcache.load_map_kept(None, draught_m=prof.draught_m)
        return build_lattice(sea, prof, prims, counts, options=PlanOptions(), cache=moves)

    made = lattice()
    assert len(list(cache.glob("*.map"))) == 3  # the map, its no-go area at the margin and the grid

    def refuse(*a, **k):
        raise AssertionError("made again")

    sea_type = type(made.sea.obstacles)
    monkeypatch.setattr(sea_type, "buffer", refuse)  # no_go's buffer
    monkeypatch.setattr(CollisionGrid, "_blocked", refuse)
    again = lattice()
    assert again.sea is not made.sea and len(list(cache.glob("*.map"))) == 3
    assert np.array_equal(again.grid.blocked, made.grid.blocked) and np.array_equal(again.grid.first, made.grid.first)
    assert (again.start_cell, again.goal_cell, again.window) == (made.start_cell, made.goal_cell, made.window)


def test_a_zero_margin_keeps_no_second_copy_of_the_obstacles(cache, map_file):
    """no_go(0) without a trial area is the map's obstacles themselves: nothing derived is kept for it."""
    sea = mapcache.load_map_kept(map_file, draught_m=6.0)
    assert _fresh_no_go(sea, 0.0).wkb == load_map(map_file, draught_m=6.0).no_go(0.0).wkb
    assert len(list(cache.glob("*.map"))) == 1  # the map's own entry only


def _placement_lattice(moves: dict, options=None, prof=None):
    """build_lattice on the bundled map from load_map_kept, as a new process would (the moves shared between calls:
    only the map's steps are under test)."""
    import maps.geo as geo
    from maps.chain import PlanOptions, build_lattice
    from maps.motionset import resolve_primitives
    from primitives.ship import load_profile

    prof = prof or load_profile("full-scale")
    counts = {"steep_zigzag_surge": 1}
    geo._NO_GO.clear()
    sea = mapcache.load_map_kept(None, draught_m=prof.draught_m)
    return build_lattice(sea, prof, resolve_primitives(prof, counts, None), counts, options=options or PlanOptions(), cache=moves)


def _refuse_placements(monkeypatch) -> None:
    from maps.collision import CollisionGrid

    def refuse(*a, **k):
        raise AssertionError("placements made again")

    monkeypatch.setattr(CollisionGrid, "valid_everywhere", refuse)
    monkeypatch.setattr(CollisionGrid, "footprint_rows", refuse)


def _same_placements(a, b) -> bool:
    import numpy as np

    return len(a) == len(b) and all(
        len(pa) == len(pb) and all(np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1]) for x, y in zip(pa, pb))
        for pa, pb in zip(a, b)
    )


def test_the_placements_are_kept_beside_the_map(cache, monkeypatch):
    """The moves' placements made on a map from load_map_kept are kept beside it, and a second command's lattice
    reads them back (the footprints' rasterising and the collision look-ups made to fail): the same arrays, so the
    same A* problem. Fails if maps.chain makes them again."""
    import numpy as np

    moves: dict = {}
    made = _placement_lattice(moves)
    before = set(cache.glob("*.map"))
    pm = made.placements()
    assert len(set(cache.glob("*.map")) - before) == 1  # one entry: the placements
    _refuse_placements(monkeypatch)
    again = _placement_lattice(moves)
    assert _same_placements(again.placements(), pm)
    assert all(x[0].dtype == bool and x[1].dtype == bool for per in again.placements() for x in per)
    for kept in (pm, again.placements()):  # read-only both when made and when read back
        assert not any(a.flags.writeable for per in kept for x in per for a in x)
    assert np.array_equal(again.problem().succ.dst, made.problem().succ.dst)


def test_stale_placements_are_not_read(cache, monkeypatch):
    """Another code version (or library version: both are in plancache.code_version), another margin, another
    clearance cost or another ship gives another key: the placements are made again, equal to a fresh lattice's."""
    from maps import plancache
    from maps.chain import PlanOptions
    from maps.collision import CollisionGrid

    moves: dict = {}
    _placement_lattice(moves).placements()
    calls = []
    real = CollisionGrid.valid_everywhere

    def counted(self, rows):
        calls.append(1)
        return real(self, rows)

    monkeypatch.setattr(CollisionGrid, "valid_everywhere", counted)
    for options in (PlanOptions(margin=25.0), PlanOptions(clearance_cost=PlanOptions().clearance_cost + 1.0)):
        calls.clear()
        _placement_lattice(moves, options).placements()
        assert calls, options
    calls.clear()
    from dataclasses import replace

    from primitives.ship import load_profile

    wider = load_profile("full-scale")
    _placement_lattice({}, prof=replace(wider, beam_m=wider.beam_m * 1.2)).placements()  # other footprints
    assert calls
    version = plancache.code_version()
    monkeypatch.setattr(plancache, "code_version", lambda: version + "-other")
    calls.clear()
    lat = _placement_lattice(moves)
    pm = lat.placements()
    assert calls
    monkeypatch.setattr(plancache, "code_version", lambda: version)
    assert _same_placements(pm, _placement_lattice({}).placements())


def test_the_placements_digest_changes_with_every_input(cache):
    """Lattice.placement_inputs changes when any one input of the placements changes: extra, the window (shifted,
    same ni x nj; another resolution), the grid's sub-cells and blocked cells, the margin, the soft zone
    (clearance_lengths), its cost, the heading table, and a move's snapping errors, cell steps and footprints. Fails
    if any of them is left out of the digest."""
    import copy
    from dataclasses import replace

    import numpy as np
    import shapely

    lat = _placement_lattice({})
    base = lat.placement_inputs(0.0)
    assert lat.placement_inputs(0.0) == base
    assert lat.placement_inputs(5.0) != base

    def changed(**attrs) -> str:
        other = copy.copy(lat)
        for name, value in attrs.items():
            setattr(other, name, value)
        return other.placement_inputs(0.0)

    w, g, o = lat.window, lat.grid, lat.options
    grids = []
    for name, value in (("sub", g.sub + 1), ("blocked", ~g.blocked)):
        grids.append(copy.copy(g))
        setattr(grids[-1], name, value)
    moves = []
    m = lat.moves[0]
    for name, value in (("snap_m", np.asarray(m.snap_m) + 1.0), ("dcell", np.asarray(m.dcell) + 1)):
        moves.append(copy.copy(m))
        setattr(moves[-1], name, value)
    variants = [
        changed(window=replace(w, x0=w.x0 + w.res)),
        changed(window=replace(w, res=w.res * 1.1)),
        *(changed(grid=grid) for grid in grids),
        changed(options=replace(o, margin=o.margin + 1.0)),
        changed(options=replace(o, clearance_lengths=3.0)),
        changed(options=replace(o, clearance_cost=o.clearance_cost + 1.0)),
        changed(table=np.asarray(lat.table)[::-1].copy()),
        *(changed(moves=[mv, *lat.moves[1:]]) for mv in moves),
    ]
    prim = copy.copy(m.prims[0])
    object.__setattr__(prim, "footprint", shapely.buffer(m.prims[0].footprint, 1.0))
    grown = copy.copy(m)
    grown.prims = [prim if p is m.prims[0] else p for p in m.prims]
    variants.append(changed(moves=[grown, *lat.moves[1:]]))
    assert base not in variants
    assert len(set(variants)) == len(variants)


def test_a_damaged_placements_entry_is_made_again(cache, monkeypatch):
    """A truncated or garbled placements entry is made again (no error): the same arrays as made."""
    moves: dict = {}
    lat = _placement_lattice(moves)
    before = set(cache.glob("*.map"))
    pm = lat.placements()
    (entry,) = set(cache.glob("*.map")) - before
    data = entry.read_bytes()
    for damaged in (data[: len(data) // 2], data[:-40] + b"\0" * 40, b""):
        entry.write_bytes(damaged)
        assert _same_placements(_placement_lattice(moves).placements(), pm)
    _refuse_placements(monkeypatch)  # made again and kept again: read back now
    assert _same_placements(_placement_lattice(moves).placements(), pm)
