"""The lattice moves kept on disk between commands (maps.movecache): a plan from another start reads
the ship's moves instead of running the helm, and is the plan computed without the cache bit for bit;
the key changes with the profile, the lattice options and the code; an unreadable entry is built
again; the moves read hold the caller's profile."""

from __future__ import annotations

import os
import pickle
from dataclasses import replace

import numpy as np
import pytest

from maps import chain, lattice, motionset, movecache, plancache
from maps.planner import plan_trial
from primitives import jitloop, library
from primitives.ship import load_profile

COUNTS = {"steep_zigzag_surge": 1}
OPTS = dict(headings=4, run_in_s=0)
START_A = (60.16035, 24.97727, 90.0)
START_B = (60.14203, 25.01183, 270.0)


@pytest.fixture(scope="module")
def profile():
    return load_profile("full-scale")


def _plan(profile, start):
    return plan_trial(profile=profile, counts=COUNTS, start=start, **OPTS)


def _same(a, b):
    """Every figure and step of two plans (the timings in stats aside)."""
    for name in ("t", "track", "lonlat", "speed", "step_of_sample", "inputs"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert pickle.dumps(a.steps) == pickle.dumps(b.steps)
    assert (a.feasible, a.counts, a.min_clearance_m) == (b.feasible, b.counts, b.min_clearance_m)


def _forbid_building(mp):
    def built(*args, **kw):
        raise AssertionError("moves built although kept on disk")

    mp.setattr(motionset, "lattice_basic_moves", built)
    mp.setattr(chain, "informative_moves", built)
    mp.setattr(lattice, "helm_for", built)
    # and their swept footprints, kept with them (stop 60: the basic moves stored by the planner alone were kept
    # without them, and every later plan formed them again, 35-40 ms of CPU)
    mp.setattr(library, "swept_footprint", built)


@pytest.fixture(scope="module")
def without_cache(profile):
    """The plan from START_B computed with no cache at all (the tests' default)."""
    return _plan(profile, START_B)


def test_plan_from_another_start_reads_the_moves_and_is_the_same(profile, without_cache, tmp_path):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
        first = _plan(profile, START_A)
        kept = sorted(tmp_path.glob("*.moves"))
        assert len(kept) == 2  # the basic moves and the one informative primitive's
        _forbid_building(mp)
        again = _plan(profile, START_B)
    assert first.feasible and again.feasible
    _same(again, without_cache)


def test_moves_read_hold_the_callers_profile(profile, tmp_path, monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    o = chain.PlanOptions(**OPTS)
    built = chain._basic_moves(profile, 400.0, o, {})
    read = chain._basic_moves(profile, 400.0, o, {})
    assert read is not built and all(pr.profile is profile for m in read for pr in m.prims)
    for a, b in zip(built, read):
        assert a.name == b.name
        np.testing.assert_array_equal(a.dcell, b.dcell)
        for pa, pb in zip(a.prims, b.prims):
            np.testing.assert_array_equal(pa.inputs, pb.inputs)
            np.testing.assert_array_equal(pa.track, pb.track)


def test_key_follows_profile_options_and_code(profile, tmp_path, monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    opts = (400.0, 4, False, 0, 1.0, True, "lattice")
    k = movecache.key(profile, "basic", opts)
    assert k == movecache.key(load_profile("full-scale"), "basic", opts)
    _ = profile.model, profile.predictor  # cached properties computed: the same ship, the same key
    assert k == movecache.key(profile, "basic", opts)
    assert k != movecache.key(replace(profile, cruise_speed_mps=profile.cruise_speed_mps + 0.1), "basic", opts)
    assert k != movecache.key(profile, "basic", (401.0, *opts[1:]))
    assert k != movecache.key(profile, "basic", (*opts[:-1], "ship"))
    assert k != movecache.key(profile, "informative", opts)
    monkeypatch.setattr(plancache, "code_version", lambda: "other code")
    assert k != movecache.key(profile, "basic", opts)


def test_key_follows_the_kernel_state(profile, tmp_path, monkeypatch):
    """A small simulation runs the numpy loop until the compiled one is loaded (last-bit differences for
    pods and rigid-body ships): moves built in either state are two entries."""
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(jitloop, "loaded", lambda: False)
    k = movecache.key(profile, "basic", ())
    monkeypatch.setattr(jitloop, "loaded", lambda: True)
    assert k != movecache.key(profile, "basic", ())


def test_no_cache_directory_keeps_nothing(profile, tmp_path, monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("HOME", str(tmp_path))
    assert movecache.key(profile, "basic", ()) is None
    assert movecache.load(None, profile) is None
    movecache.store(None, [1], profile)  # no error, nothing written
    chain._basic_moves(profile, 400.0, chain.PlanOptions(**OPTS), {})
    assert not list(tmp_path.rglob("*"))


def test_moves_kept_within_their_byte_budget(profile, tmp_path, monkeypatch):
    """The most recently used entries within MOVES_BYTES stay, the newest whatever its size; plans are not counted."""
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    plancache.store_blob(tmp_path, "p.plan", b"x" * 50_000)
    for i in range(4):
        movecache.store(f"k{i}", b"x" * 10_000, profile)
        os.utime(tmp_path / f"k{i}.moves", ns=(i * 10**9, i * 10**9))  # k3 the newest
    monkeypatch.setattr(plancache, "MOVES_BYTES", 25_000)
    assert movecache.load("k1", profile) == b"x" * 10_000  # read: used most recently
    movecache.store("k4", b"x" * 10_000, profile)
    assert sorted(p.name for p in tmp_path.glob("*.moves")) == ["k1.moves", "k4.moves"]
    assert (tmp_path / "p.plan").exists()
    movecache.store("big", b"x" * 40_000, profile)
    assert sorted(p.name for p in tmp_path.glob("*.moves")) == ["big.moves"]


@pytest.mark.parametrize("damage", ["truncate", "garbage", "foreign", "misnamed"])
def test_unreadable_entry_is_built_again(profile, tmp_path, monkeypatch, damage):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    o = chain.PlanOptions(**OPTS)
    built = chain._basic_moves(profile, 400.0, o, {})
    (entry,) = tmp_path.glob("*.moves")
    data = entry.read_bytes()
    if damage == "truncate":
        entry.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        entry.write_bytes(b"\0" * 100)
    elif damage == "foreign":  # a well-formed entry whose payload this code cannot read: built again
        plancache.store_blob(tmp_path, entry.name, (entry.stem, b"not a pickle"))
    else:  # another key's well-formed entry under this key's name (copied, renamed): not read
        other = movecache.key(profile, "basic", ("other options",))
        movecache.store(other, [], profile)
        (tmp_path / f"{other}.moves").replace(entry)
    again = chain._basic_moves(profile, 400.0, o, {})
    assert [m.name for m in again] == [m.name for m in built]
    for a, b in zip(built, again):
        np.testing.assert_array_equal(a.prims[0].track, b.prims[0].track)
    assert movecache.load(entry.stem, profile) is not None  # written again


def test_refs_are_written_as_their_places_and_read_as_the_readers_objects(profile):
    # stop 53 (the kept design): a value leaves out objects kept elsewhere, by identity (an equal copy is written
    # out), and a reader whose refs lack a place reads no value
    a, b = np.arange(1000.0), np.arange(1000.0)
    data = movecache.dumps({"a": a, "again": a, "copy": b, "profile": profile}, profile, [a])
    assert len(data) < len(movecache.dumps({"a": a, "again": a, "copy": b, "profile": profile}, profile)) - 7000
    mine = np.zeros(3)
    read = movecache.loads(data, profile, [mine])
    assert read["a"] is mine and read["again"] is mine and read["profile"] is profile
    np.testing.assert_array_equal(read["copy"], b)
    with pytest.raises(pickle.UnpicklingError):
        movecache.loads(data, profile)
