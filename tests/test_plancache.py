"""The plan cache (maps.plancache): a second `plan` with the same inputs reads the design and plan
back and writes the same files; any change of the profile, map or an option is another key; an
entry that cannot be read is ignored, with no traceback, and the plan computed again."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from cli.app import _run
from maps import plancache
from maps.geo import bundled_map_path
from maps.planoptions import PlanOptions
from primitives.ship import load_profile

START = "2026-06-01T08:00Z"
ARGS = ["plan", "--counts", "steep_zigzag_surge=1", "--json", "--start-time", START]
QUICK = "--no-export"  # plan.json, trajectory and plan.png only


def _plan_cli(out, capsys, *extra):
    rc = _run([*ARGS, "--out", str(out), *extra])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    return json.loads(cap.out), (out / "plan.json").read_bytes()


@pytest.fixture(scope="module")
def first(tmp_path_factory):
    """One planned run with every export into a cache of its own: (cache directory, plan.json bytes,
    every output file's bytes by name)."""
    root = tmp_path_factory.mktemp("plancache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SHIPTRIAL_CACHE_DIR", str(root / "cache"))
        assert _run([*ARGS, "--out", str(root / "out")]) == 0
    out = root / "out"
    return root / "cache", (out / "plan.json").read_bytes(), {p.name: p.read_bytes() for p in out.iterdir()}


@pytest.fixture
def cache_dir(first, tmp_path, monkeypatch, capsys):
    """A copy of the first run's cache, used by this test's commands."""
    capsys.readouterr()
    d = tmp_path / "cache"
    shutil.copytree(first[0], d)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(d))
    return d


def _forbid(mp, module, name, why):
    """Make ``module.name`` fail the test when called."""

    def called(*args, **kw):
        raise AssertionError(why)

    mp.setattr(module, name, called)


def _key(**change):
    inputs = dict(
        counts=None,
        start=None,
        goal=None,
        scenario=None,
        criterion="D",
        mean_subtraction="complete",
        trial_length_s=None,
        seed=0,
        parameter_prior=None,
        vessel_name="",
        options=PlanOptions(),
    )
    profile = change.pop("profile", load_profile("full-scale"))
    map_file = change.pop("map_file", bundled_map_path())
    return plancache.plan_key(profile, map_file, **(inputs | change))


def test_key_changes_with_profile_map_and_every_option(tmp_path):
    base = _key()
    assert _key() == base  # the same inputs, the same key
    prof = load_profile("full-scale")
    edited = tmp_path / "helsinki-edited.geojson"
    edited.write_bytes(bundled_map_path().read_bytes().replace(b"}", b"} ", 1))  # one byte more, the same map
    copied = tmp_path / "helsinki.geojson"
    copied.write_bytes(bundled_map_path().read_bytes())  # the same bytes elsewhere: not the bundled example to the planner
    others = {
        "profile": _key(profile=replace(prof, draught_m=prof.draught_m + 0.1)),
        "ship": _key(profile=load_profile("kvlcc2")),
        "map": _key(map_file=edited),
        "map path": _key(map_file=copied),
        "margin": _key(options=PlanOptions(margin=25.0)),
        "headings": _key(options=PlanOptions(headings=8)),
        "seed": _key(seed=1),
        "criterion": _key(criterion="A"),
        "trial length": _key(trial_length_s=1200.0),
        "counts": _key(counts={"steep_zigzag_surge": 1}),
        "start": _key(start=(60.1, 24.9, 180.0)),
        "vessel": _key(vessel_name="Aurora"),
    }
    assert base not in others.values() and len(set(others.values())) == len(others)


def test_code_version_changes_with_the_kernel_choice(monkeypatch):
    plancache.code_version.cache_clear()
    monkeypatch.setenv("SHIPTRIAL_KERNEL", "numpy")
    numpy_kernel = plancache.code_version()
    plancache.code_version.cache_clear()
    monkeypatch.delenv("SHIPTRIAL_KERNEL")
    try:
        assert plancache.code_version() != numpy_kernel
    finally:
        plancache.code_version.cache_clear()


def test_second_run_reads_the_cache_and_writes_the_same_bytes(first, tmp_path, cache_dir, capsys, monkeypatch):
    assert len(list(cache_dir.glob("*.plan"))) == 1
    import maps.planner

    with monkeypatch.context() as mp:
        _forbid(mp, maps.planner, "plan_with_design", "planned although the cache holds the plan")
        second, b = _plan_cli(tmp_path / "b", capsys)
    assert second["from_cache"] is True and b == first[1]  # plan.json byte for byte, timings those of the first run
    again = {p.name: p.read_bytes() for p in (tmp_path / "b").iterdir()}
    assert again.keys() == first[2].keys() and len(again) >= 12  # every export: card PDF and HTML, PNGs, GPX, RTZ, ...
    assert [k for k in again if again[k] != first[2][k]] == []
    fresh, c = _plan_cli(tmp_path / "c", capsys, "--no-cache", QUICK)  # computed again: the same plan but its timings
    assert fresh["from_cache"] is False and len(list(cache_dir.glob("*.plan"))) == 1  # --no-cache writes nothing
    timing = ("time_s", "expansions_per_s", "search_s")

    def untimed(doc):
        if isinstance(doc, dict):
            return {k: untimed(v) for k, v in doc.items() if not k.endswith(timing)}
        return [untimed(v) for v in doc] if isinstance(doc, list) else doc

    assert untimed(json.loads(c)) == untimed(json.loads(first[1]))


def test_changed_option_is_a_miss(tmp_path, cache_dir, capsys):
    other, _ = _plan_cli(tmp_path / "b", capsys, "--margin", "25", QUICK)
    assert other["from_cache"] is False and len(list(cache_dir.glob("*.plan"))) == 2


def _damaged(data: bytes, damage: str) -> bytes:
    if damage == "truncate":
        return data[: len(data) // 2]
    if damage == "flip":
        return data[:-10] + bytes([data[-10] ^ 0xFF]) + data[-9:]
    if damage == "garbage":
        return b"\x00\xff" * 1000
    if damage == "empty":
        return b""
    payload = b"not a pickle"  # a well-formed header over a payload that is no pickle: what a checksum cannot catch
    return plancache.MAGIC + hashlib.sha256(payload).hexdigest().encode() + payload


@pytest.mark.parametrize("damage", ["truncate", "flip", "garbage", "empty", "unpicklable"])
def test_damaged_entry_reads_as_none(cache_dir, damage):
    (entry,) = cache_dir.glob("*.plan")
    assert plancache.load(cache_dir, entry.stem) is not None
    entry.write_bytes(_damaged(entry.read_bytes(), damage))
    assert plancache.load(cache_dir, entry.stem) is None


def test_damaged_entry_is_planned_again_without_traceback(first, tmp_path, cache_dir, capsys):
    (entry,) = cache_dir.glob("*.plan")
    entry.write_bytes(_damaged(entry.read_bytes(), "flip"))
    again, b = _plan_cli(tmp_path / "b", capsys, QUICK)
    assert again["from_cache"] is False and plancache.load(cache_dir, entry.stem) is not None  # rewritten
    assert json.loads(b)["counts"] == json.loads(first[1])["counts"]


def test_copy_of_the_bundled_map_is_not_read_from_its_entry(tmp_path, cache_dir, capsys):
    """The bundled Helsinki map's start and goal are the planner's defaults; a copy of its bytes
    elsewhere has none, so the same command on the copy is refused rather than given the cached
    plan (the key holds the map's path, not only its bytes)."""
    copied = tmp_path / "helsinki.geojson"
    copied.write_bytes(bundled_map_path().read_bytes())
    rc = _run([*ARGS, "--out", str(tmp_path / "b"), "--map", str(copied)])
    err = capsys.readouterr().err
    assert rc == 2 and "no start point" in err, err
    assert len(list(cache_dir.glob("*.plan"))) == 1


def test_entry_pickle_cannot_write_is_skipped(tmp_path):
    plancache.store(tmp_path / "cache", "k", {"plan": lambda: None})  # no error: the plan is simply not kept
    assert not (tmp_path / "cache").exists()


def test_unwritable_cache_is_skipped(first, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    entry = plancache.load(first[0], next(first[0].glob("*.plan")).stem)
    plancache.store(blocker / "cache", "k", entry)  # no error: the command's outputs do not depend on it
    assert not (blocker / "cache").exists()


def test_empty_variable_means_no_cache(monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", "")
    assert plancache.default_dir() is None
    monkeypatch.delenv("SHIPTRIAL_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", "/somewhere")
    assert str(plancache.default_dir()) == "/somewhere/shiptrial/plans"


def test_old_entries_are_pruned(tmp_path, monkeypatch):
    monkeypatch.setattr(plancache, "KEEP", 2)
    for i in range(4):
        (tmp_path / f"{i}.plan").write_bytes(b"x")
        os.utime(tmp_path / f"{i}.plan", ns=(i * 10**9, i * 10**9))
    (tmp_path / ".3.plan.killed").write_bytes(b"x")  # the temporary file of a writer killed an hour ago
    os.utime(tmp_path / ".3.plan.killed", ns=(0, 0))
    (tmp_path / ".2.plan.writing").write_bytes(b"x")  # one being written now
    plancache._prune(tmp_path)
    assert sorted(p.name for p in tmp_path.glob("*.plan")) == ["2.plan", "3.plan"]
    assert sorted(p.name for p in tmp_path.glob(".*")) == [".2.plan.writing"]


def test_temporary_file_renamed_meanwhile_is_no_failed_write(tmp_path, monkeypatch):
    # another process's temporary file, listed by the sweep of killed writers and renamed into place before its stat
    (tmp_path / ".k.map.abcd").write_bytes(b"x")
    real = Path.stat

    def stat(self, *a, **k):
        if self.name.startswith(".k.map."):
            raise FileNotFoundError(self)
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "stat", stat)
    assert plancache.store_blob(tmp_path, "other.map", (1, 2)) is not None
    assert plancache.load_blob(tmp_path, "other.map") == (1, 2)


def test_no_home_means_no_cache_not_a_tilde_directory(monkeypatch):
    # without HOME (and no password entry) expanduser leaves "~": the cache must not land in "./~/.cache"
    monkeypatch.delenv(plancache.ENV_DIR, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(plancache.os.path, "expanduser", lambda p: p)
    assert plancache.default_dir() is None


# the output files kept with the plan (cli/plan_cache.py): a second run copies them instead of drawing and exporting


def _files(out):
    return {p.name: p.read_bytes() for p in out.iterdir()}


def _start_sets(cache_dir):
    """The output sets kept for one start time each (not the plans' figures kept for any start time)."""
    from cli.plan_cache import FIGURES

    return [p for p in cache_dir.glob("*.out") if not set(plancache.load_outputs(cache_dir, p.stem)["files"]) <= set(FIGURES)]


def _figure_sets(cache_dir):
    return sorted(set(cache_dir.glob("*.out")) - set(_start_sets(cache_dir)))


def test_second_run_copies_the_kept_files_without_exporting(first, tmp_path, cache_dir, capsys, monkeypatch):
    import cli.plan_cmd

    assert len(_start_sets(cache_dir)) == 1 and len(_figure_sets(cache_dir)) == 1

    with monkeypatch.context() as mp:
        _forbid(mp, cli.plan_cmd, "write_outputs_all", "exported although the cache holds the files")
        second, _ = _plan_cli(tmp_path / "b", capsys)
    again = _files(tmp_path / "b")
    assert second["from_cache"] is True and again == first[2]  # all 13 files, byte for byte
    assert sorted(Path(v).name for v in second["files"].values()) == sorted(k for k in again if not k.startswith("."))


def _forbid_drawing(mp):
    """Fail the command (its drawer's error) when any PNG figure is drawn rather than copied."""
    import cli.drawer
    import maps.export.plots
    import maps.output

    drawn = [(maps.export.plots, n) for n in ("plot_track", "plot_states", "track_figure", "states_figure")]
    for module, name in [*drawn, (maps.output, "plot_plan")]:  # the figures (the HTML card's images too)
        _forbid(mp, module, name, f"{name} drew a figure the cache holds")
    _forbid(mp, cli.drawer, "_design_ratios", "the design ratios drawn although the cache holds them")


def test_other_start_time_copies_the_figures_and_exports_the_rest_as_an_uncached_run(
    first, tmp_path, cache_dir, capsys, monkeypatch
):
    later = ("--start-time", "2026-06-01T09:00Z")
    with monkeypatch.context() as mp:
        _forbid_drawing(mp)
        cached, _ = _plan_cli(tmp_path / "b", capsys, *later)
    assert cached["from_cache"] is True and len(_start_sets(cache_dir)) == 2  # a second output set kept
    assert len(_figure_sets(cache_dir)) == 1  # the figures: one set for the plan whatever the start time
    _plan_cli(tmp_path / "c", capsys, *later, "--no-cache")
    b, c = _files(tmp_path / "b"), _files(tmp_path / "c")
    assert b.keys() == c.keys() and [k for k in b if b[k] != c[k]] == ["plan.json"]  # its timing fields only
    assert b["full-scale-trial.gpx"] != first[2]["full-scale-trial.gpx"]  # the schedule moved: not the first run's files
    assert all(b[k] == first[2][k] for k in b if k.endswith(".png"))


def test_other_start_time_copies_both_geojson_files(first, tmp_path, cache_dir, capsys, monkeypatch):
    """trajectory.geojson and the crew's GeoJSON carry no start time: kept with the figures, a run at another start
    time copies them (no GeoJSON exported) and they are the bytes an uncached run at that time writes."""
    import maps.export.geojson

    later = ("--start-time", "2026-06-01T10:00Z")
    with monkeypatch.context() as mp:
        _forbid(mp, maps.export.geojson, "write_geojson", "a GeoJSON file exported although the cache holds it")
        cached, _ = _plan_cli(tmp_path / "b", capsys, *later)
    assert cached["from_cache"] is True
    _plan_cli(tmp_path / "c", capsys, *later, "--no-cache")
    b, c = _files(tmp_path / "b"), _files(tmp_path / "c")
    geo = sorted(k for k in b if k.endswith(".geojson"))
    assert geo == ["full-scale-trial.geojson", "trajectory.geojson"] and all(b[k] == c[k] == first[2][k] for k in geo)


def test_a_run_restoring_its_own_set_keeps_the_figures_young(first, tmp_path, cache_dir, capsys):
    """A run that copies its own start time's whole set uses the plan's figures too: their entry is marked used
    as the set's is, so that the next sets kept prune the set of an older plan before the figures an hour later needs."""
    (figures,) = _figure_sets(cache_dir)
    (own,) = _start_sets(cache_dir)
    for entry in (figures, own):
        os.utime(entry, ns=(10**9, 10**9))  # both long unused
    again, _ = _plan_cli(tmp_path / "b", capsys)
    assert again["from_cache"] is True and _files(tmp_path / "b") == first[2]
    assert own.stat().st_mtime_ns > 10**9 and figures.stat().st_mtime_ns > 10**9


@pytest.mark.parametrize("damage", ["truncate", "flip", "unpicklable"])
def test_damaged_figures_are_drawn_again(first, tmp_path, cache_dir, capsys, damage):
    (entry,) = _figure_sets(cache_dir)
    entry.write_bytes(_damaged(entry.read_bytes(), damage))
    later = ("--start-time", "2026-06-01T09:00Z")
    _plan_cli(tmp_path / "b", capsys, *later)
    _plan_cli(tmp_path / "c", capsys, *later, "--no-cache")
    b, c = _files(tmp_path / "b"), _files(tmp_path / "c")
    assert [k for k in b if b[k] != c[k]] == ["plan.json"] and plancache.load_outputs(cache_dir, entry.stem) is not None


@pytest.mark.parametrize("damage", ["truncate", "flip", "unpicklable"])
def test_damaged_output_set_is_exported_again(first, tmp_path, cache_dir, capsys, damage):
    (entry,) = _start_sets(cache_dir)
    entry.write_bytes(_damaged(entry.read_bytes(), damage))
    assert plancache.load_outputs(cache_dir, entry.stem) is None
    again, _ = _plan_cli(tmp_path / "b", capsys)
    assert again["from_cache"] is True and _files(tmp_path / "b") == first[2]
    assert plancache.load_outputs(cache_dir, entry.stem) is not None  # written again


def test_files_are_not_served_with_a_plan_computed_again(tmp_path, cache_dir, capsys):
    """A plan entry computed again (its timings differ) gets its own files: never the old run's plan.json."""
    (entry,) = cache_dir.glob("*.plan")
    entry.write_bytes(_damaged(entry.read_bytes(), "flip"))
    replanned, _ = _plan_cli(tmp_path / "b", capsys)
    assert replanned["from_cache"] is False and len(_start_sets(cache_dir)) == 2 and len(_figure_sets(cache_dir)) == 2
    hit, _ = _plan_cli(tmp_path / "c", capsys)
    assert hit["from_cache"] is True and _files(tmp_path / "c") == _files(tmp_path / "b")


def test_outputs_key_changes_with_start_entry_and_drawing_configuration(tmp_path, monkeypatch):
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path / "mpl"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MATPLOTLIBRC", raising=False)
    assert plancache.outputs_key("k", "d", START) is None  # no font list to key the figures' fonts on
    (tmp_path / "mpl").mkdir()
    (tmp_path / "mpl" / "fontlist-v390.json").write_text("{}")
    base = plancache.outputs_key("k", "d", START)
    assert plancache.outputs_key("k", "d", START) == base
    others = {"plan": plancache.outputs_key("k2", "d", START), "entry": plancache.outputs_key("k", "d2", START)}
    others["start"] = plancache.outputs_key("k", "d", "2026-06-01T09:00Z")
    (tmp_path / "mpl" / "fontlist-v390.json").write_text('{"fonts": 1}')
    others["font list"] = plancache.outputs_key("k", "d", START)
    (tmp_path / "mpl" / "matplotlibrc").write_text("lines.linewidth: 3\n")
    others["rc in config"] = plancache.outputs_key("k", "d", START)
    (tmp_path / "matplotlibrc").write_text("lines.linewidth: 3\n")
    others["rc here"] = plancache.outputs_key("k", "d", START)
    monkeypatch.setattr(plancache, "DRAWING", ("matplotlib", "a-library-not-installed"))
    others["libraries"] = plancache.outputs_key("k", "d", START)
    assert base not in others.values() and len(set(others.values())) == len(others)


def test_old_output_sets_are_pruned(tmp_path, monkeypatch):
    monkeypatch.setattr(plancache, "KEEP_OUTPUTS", 1)
    for i in range(3):
        (tmp_path / f"{i}.out").write_bytes(b"x")
        os.utime(tmp_path / f"{i}.out", ns=(i * 10**9, i * 10**9))
    (tmp_path / "0.plan").write_bytes(b"x")
    os.utime(tmp_path / "0.plan", ns=(0, 0))
    plancache._prune(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["0.plan", "2.out"]


def _early_forks(monkeypatch):
    import cli.drawer

    calls = []
    real = cli.drawer.start_early
    monkeypatch.setattr(cli.drawer, "start_early", lambda *a: (calls.append(1), real(*a)))
    return calls


def test_command_whose_files_are_kept_forks_no_early_drawer(first, tmp_path, cache_dir, capsys, monkeypatch):
    """The drawer forked before parsing only to be cancelled costs a cached run about 0.5 s of CPU: a command line
    (its --out aside) whose last run kept its files starts none; another one still does."""
    calls = _early_forks(monkeypatch)
    _plan_cli(tmp_path / "b", capsys)
    assert calls == [] and _files(tmp_path / "b") == first[2]
    (kept,) = _start_sets(cache_dir)
    kept.unlink()  # the guess now wrong: the files are drawn all the same (the drawer started after parsing)
    _plan_cli(tmp_path / "c", capsys)
    assert calls == [] and _files(tmp_path / "c") == first[2]
    _plan_cli(tmp_path / "d", capsys, "--start-time", "2026-06-01T09:00Z")  # a command line never run: forked early
    assert calls == [1]


def test_hint_holds_until_the_default_start_time_moves(tmp_path, monkeypatch):
    from cli import plan_cache

    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    args = ["plan", "--out", "x"]
    assert plan_cache.expect_kept_files(args) is False  # never run
    (hint,) = plan_cache._HINT
    for text, expected in (("inf", True), ("1e12", True), ("1000", False), ("garbage", False)):
        hint.write_text(text)  # 1000: a default start time (the next full hour) long past
        assert plan_cache.expect_kept_files(args) is expected
    hint.write_text("inf")
    assert plan_cache.expect_kept_files(["plan", "--out", "y"]) and plan_cache.expect_kept_files(["plan", "--out=z"])
    assert not plan_cache.expect_kept_files(["plan", "--out", "y", "--seed", "1"])  # --out aside, every word counts
    plan_cache.expect_kept_files(args)
    plan_cache.note_kept(tmp_path, False, None)
    assert not hint.exists()  # files not kept: the next run forks its drawer early again


def test_unknown_user_in_cache_variable_means_no_cache(monkeypatch):
    monkeypatch.setenv(plancache.ENV_DIR, "~no-such-user-here/plans")  # expanduser raises RuntimeError
    assert plancache.default_dir() is None


def test_removed_working_directory_still_writes_the_files(first, tmp_path, cache_dir, capsys, monkeypatch):
    """The hint's and the drawing key's working directory gone: the run draws and exports as without a cache."""
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    assert plancache.drawing_version() is None
    _plan_cli(tmp_path / "b", capsys)
    assert _files(tmp_path / "b") == first[2]


def test_copied_files_are_readable_by_others_whatever_the_umask(first, tmp_path, cache_dir, capsys):
    old = os.umask(0o077)
    try:
        _plan_cli(tmp_path / "b", capsys)
    finally:
        os.umask(old)
    modes = {p.name: p.stat().st_mode & 0o777 for p in (tmp_path / "b").iterdir() if not p.name.startswith(".")}
    assert set(modes.values()) == {0o644}, modes  # as the exporters write them (crews and colleagues read them)


def test_outputs_key_changes_with_a_listed_font_file_updated_in_place(tmp_path, monkeypatch):
    """A system font upgraded at the same path leaves matplotlib's font list as it was but changes the glyphs."""
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path / "mpl"))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mpl").mkdir()
    font = tmp_path / "DejaVuSans.ttf"
    font.write_bytes(b"old glyphs")
    os.utime(font, ns=(10**18, 10**18))
    (tmp_path / "mpl" / "fontlist-v390.json").write_text(json.dumps({"ttflist": [{"fname": str(font)}], "afmlist": []}))
    before = plancache.outputs_key("k", "d", START)
    font.write_bytes(b"new glyphs")
    os.utime(font, ns=(2 * 10**18, 2 * 10**18))
    assert plancache.outputs_key("k", "d", START) not in (None, before)


def test_plan_of_a_map_saved_while_it_loaded_is_not_kept(tmp_path, cache_dir, capsys, monkeypatch):
    """A map file saved between its key and its load (an editor writing while the command runs):
    the plan is of the saved map, so it is not kept under the earlier bytes' key, which would serve
    it for those bytes once the edit is undone."""
    import maps.geo
    import maps.mapcache

    keyed = tmp_path / "keyed.geojson"  # the file the key reads (the load reads the bundled map, as before)
    keyed.write_bytes(bundled_map_path().read_bytes())
    monkeypatch.setattr(maps.geo, "map_source", lambda path: keyed)
    load = maps.mapcache.load_map_kept

    def load_then_save(*args, **kw):
        sea = load(*args, **kw)
        keyed.write_bytes(keyed.read_bytes() + b"\n")  # saved after the key was made
        return sea

    monkeypatch.setattr(maps.mapcache, "load_map_kept", load_then_save)
    before = set(cache_dir.glob("*.plan"))
    again, _ = _plan_cli(tmp_path / "b", capsys, QUICK)
    assert again["from_cache"] is False and set(cache_dir.glob("*.plan")) == before


def test_key_does_not_change_as_the_profile_compiles_its_model():
    # planning fills the profile's cached properties (the compiled model); a key taken after a plan
    # must find the plan stored under the key taken before it
    fresh = replace(load_profile("full-scale"))
    before = _key(profile=fresh)
    assert fresh.model.n_params > 0 and fresh.predictor is not None
    assert _key(profile=fresh) == before


def test_sea_maps_kept_within_their_byte_budget(tmp_path, monkeypatch):
    """Projected maps are kept by bytes, not by count: many small charts stay, a few large ones are bounded."""
    for i in range(plancache.KEEP + 8):
        plancache.store_blob(tmp_path, f"m{i}.map", b"x" * 1_000)
        os.utime(tmp_path / f"m{i}.map", ns=(i * 10**9, i * 10**9))
    assert len(list(tmp_path.glob("*.map"))) == plancache.KEEP + 8
    monkeypatch.setattr(plancache, "MAPS_BYTES", 25_000)
    plancache.store_blob(tmp_path, "big.map", b"x" * 20_000)
    kept = {p.name for p in tmp_path.glob("*.map")}
    assert "big.map" in kept and f"m{plancache.KEEP + 7}.map" in kept and "m0.map" not in kept
    assert sum(p.stat().st_size for p in tmp_path.glob("*.map")) <= 25_000


@dataclass
class _Two:
    a: dict
    b: dict


def test_fields_digest_is_the_same_for_an_object_read_back():
    # a fresh object and its copy read back pickle to different bytes when the fresh one shares a string
    # between fields; field by field they do not (the ratios figure's key and the drawer's check rely on it)
    import pickle

    from maps.plancache import fields_digest

    name = "".join(["sur", "ge"])  # one string object in both fields of the fresh object
    fresh = _Two({name: 1.0}, {name: 2.0})
    back = pickle.loads(pickle.dumps(_Two({"surge": 1.0}, {"".join(["sur", "ge"]): 2.0})))
    assert pickle.dumps(fresh) != pickle.dumps(back)
    assert fields_digest(fresh) == fields_digest(back)
    assert fields_digest(_Two({name: 1.0}, {name: 2.5})) != fields_digest(fresh)
    assert fields_digest(_Two({name: 1.0}, {})) != fields_digest(_Two({}, {name: 1.0}))  # framed by field
    assert fields_digest([1, 2]) == fields_digest([1, 2]) != fields_digest([2, 1])  # not a dataclass: whole


def test_the_drawer_writes_given_figures_and_draws_only_the_missing_ones(first, tmp_path, monkeypatch):
    """A designed plan's figures given to the drawer (``job["png"]``): the design ratios are written, not drawn; an
    entry without them (kept by an older run) draws them."""
    import cli.drawer
    import maps.export.plots
    import maps.output
    from maps.export import default_path

    hit = next(plancache.load(first[0], p.stem) for p in first[0].glob("*.plan"))
    plan, chart, sea = hit["plan"], hit["chart"], hit["sea"]
    names = {n: first[2][n] for n in first[2] if n.endswith(".png")}
    names["design-ratios.png"] = b"ratios"
    drawn = []
    monkeypatch.setattr(
        cli.drawer,
        "_design_ratios",
        lambda design, out: drawn.append(design) or (out / "design-ratios.png").write_bytes(b"drawn"),
    )
    for module, name in [(maps.export.plots, n) for n in ("plot_track", "plot_states", "track_figure", "states_figure")] + [
        (maps.output, "plot_plan")
    ]:
        _forbid(monkeypatch, module, name, f"{name} drew a figure given")
    for given, expect in ((names, b"ratios"), ({k: v for k, v in names.items() if k != "design-ratios.png"}, b"drawn")):
        out = tmp_path / f"out{len(given)}"
        out.mkdir()
        job = {"plan": plan, "sea": sea, "chart": chart, "design": "a design", "t0": START, "dir": out, "png": given}
        cli.drawer.draw_here(job)
        assert (out / "design-ratios.png").read_bytes() == expect
        assert all((out / n).read_bytes() == b for n, b in given.items())
        assert default_path(plan, "card", out).read_bytes() == first[2][default_path(plan, "card", out).name]
    assert drawn == ["a design"]


_CARDS_ONLY = """
import pickle, sys
import cli.drawer
cli.drawer._warm_frozen(cli.drawer._CARD_MODULES)  # what a drawer begun with cards_only imports ahead
cli.drawer.CAN_FORK = False  # the PDF card and states PNG written here too (beside), where sys.modules is looked at
cli.drawer.draw_here(pickle.load(open(sys.argv[1], "rb")))
if "matplotlib.pyplot" in sys.modules:
    import matplotlib
    print("pyplot", matplotlib.get_backend().lower())
else:
    print("no pyplot")
"""


def test_a_drawer_given_every_png_writes_the_cards_without_pyplot(first, tmp_path):
    """The PNGs kept for another start time given, the drawer writes the trial cards without importing pyplot (nor
    the figures' modules): the same files as the run that drew them; one PNG missing from what is given (a figures
    set kept by older code), it is drawn all the same, importing what it needs."""
    import pickle
    import subprocess
    import sys

    hit = next(plancache.load(first[0], p.stem) for p in first[0].glob("*.plan"))
    pngs = {n: b for n, b in first[2].items() if n.endswith(".png")}
    track = next(n for n in pngs if n.endswith("-track.png"))
    for given, expect in ((pngs, "no pyplot"), ({n: b for n, b in pngs.items() if n != track}, "pyplot agg")):
        out = tmp_path / f"out{len(given)}"
        out.mkdir()
        job = {"plan": hit["plan"], "sea": hit["sea"], "chart": hit["chart"], "design": None, "t0": START, "dir": out}
        (tmp_path / "job.pkl").write_bytes(pickle.dumps(job | {"png": given}))
        # another backend asked for (a notebook's, a desktop's): the figure is drawn with Agg all the same
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent), MPLBACKEND="svg")
        run = subprocess.run([sys.executable, "-c", _CARDS_ONLY, str(tmp_path / "job.pkl")], env=env, capture_output=True)
        assert run.returncode == 0, run.stderr.decode()[-2000:]
        assert run.stdout.decode().split() == expect.split()
        files = {p.name: p.read_bytes() for p in out.iterdir()}
        assert files == {n: first[2][n] for n in files} and len(files) == len(pngs) + 2  # PNGs, HTML and PDF cards


def test_the_command_asks_for_the_cards_only_drawer_when_the_figures_are_kept(first, tmp_path, cache_dir, capsys, monkeypatch):
    """The command begins its early drawer with cards_only=True when the plan's figures are kept (a cached plan at a
    new start time: pyplot not imported, about 0.4 s of CPU), and with False on a cache miss (every figure drawn)."""
    import cli.drawer

    flags = []
    real = cli.drawer.Drawer.begin
    monkeypatch.setattr(
        cli.drawer.Drawer, "begin", lambda self, *a, **kw: (flags.append(kw.get("cards_only")), real(self, *a, **kw))[1]
    )
    _plan_cli(tmp_path / "b", capsys, "--start-time", "2026-06-01T09:00Z")  # the figures kept: copied, cards drawn
    assert flags == [True] and _files(tmp_path / "b")["plan.png"] == first[2]["plan.png"]
    for entry in cache_dir.glob("*.plan"):
        entry.unlink()  # a cache miss: planned and drawn again
    _plan_cli(tmp_path / "c", capsys, "--start-time", "2026-06-01T10:00Z")
    assert flags == [True, False]


def test_begin_cards_only_reaches_the_deferred_drawer(monkeypatch):
    """begin(cards_only=True) tells a drawer started before the options to import only the cards' modules."""
    import cli.drawer
    from cli.drawer import _CARD_MODULES, _DRAWING_MODULES, Drawer

    seen = []
    monkeypatch.setattr(cli.drawer, "_warm", lambda until=-1, modules=(): None)
    monkeypatch.setattr(Drawer, "_serve", staticmethod(lambda job_r, *a, modules=(): seen.append(modules)))
    for cards_only in (True, False):
        d = Drawer.__new__(Drawer)
        spec_r, d._spec = os.pipe()
        early_r, early_w = os.pipe()
        d.begin(None, None, cards_only=cards_only)
        Drawer._serve_deferred(-1, spec_r, early_w)
        os.close(early_r)
    assert seen == [_CARD_MODULES, _DRAWING_MODULES]


def test_installed_version_is_importlib_metadata_version():
    """The cache keys' library versions read from the Version header line are importlib.metadata's, for every
    library keyed (installed or not), so that every key is the one the e-mail parser's version gave."""
    from maps.plancache import DRAWING, LIBRARIES

    for lib in (*LIBRARIES, *DRAWING, "pytest", "no-such-library-s56"):
        _assert_as_importlib_metadata(lib)


def _assert_as_importlib_metadata(lib: str) -> None:
    """installed_version(lib) gives importlib.metadata's version, or raises as it does: PackageNotFoundError when
    not installed; KeyError for metadata without a Version header once the importlib_metadata backport is imported
    anywhere in the process (another test, a plugin: its finder then comes first on sys.meta_path, and its
    distributions refuse the missing field where the standard library's give None), so never the body's line."""
    from importlib.metadata import PackageNotFoundError, version

    from maps.plancache import installed_version

    try:
        want = version(lib)
    except (PackageNotFoundError, KeyError) as refused:
        with pytest.raises(type(refused)):
            installed_version(lib)
        return
    assert installed_version(lib) == want, lib


# hand-made installed packages (name, path under a site directory, metadata text): the layouts installed_version
# reads itself or leaves to importlib.metadata's e-mail parser
_LAYOUTS = [
    ("novers", "novers-1.0.dist-info/METADATA", "Metadata-Version: 2.1\nName: novers\n\nVersion: 9.9 in body\n"),
    ("lower", "lower-3.0.dist-info/METADATA", "Metadata-Version: 2.1\nName: lower\nversion: 3.0\n"),
    ("trail", "trail-4.0.dist-info/METADATA", "Metadata-Version: 2.1\nName: trail\nVersion:   4.0  \n"),
    ("folded", "folded-2.0.dist-info/METADATA", "Metadata-Version: 2.1\nName: folded\nVersion: 2.0\n  .post1\n"),
    ("crlf", "crlf-5.0.dist-info/METADATA", "Metadata-Version: 2.1\r\nName: crlf\r\nVersion: 5.0\r\n\r\n"),
    ("eggy", "eggy.egg-info/PKG-INFO", "Metadata-Version: 1.0\nName: eggy\nVersion: 0.7.1\n\nbody\n"),
    ("eggf", "eggf-1.2-py3.11.egg-info", "Metadata-Version: 1.0\nName: eggf\nVersion: 1.2\n"),
]


@pytest.mark.parametrize("name, rel, text", _LAYOUTS, ids=[n for n, _, _ in _LAYOUTS])
def test_installed_version_of_odd_metadata_is_importlib_metadata_version(tmp_path, monkeypatch, name, rel, text):
    """A Version header only in the body (None), in lower case, with trailing blanks, folded over two lines, with
    CRLF endings, an .egg-info directory and an .egg-info file: the version importlib.metadata gives, for each."""
    path = tmp_path / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text.encode())  # bytes: the CRLF layout kept as written
    monkeypatch.syspath_prepend(str(tmp_path))
    _assert_as_importlib_metadata(name)
