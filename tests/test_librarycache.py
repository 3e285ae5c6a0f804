"""The ship's library and its information kept between commands (maps.librarycache): the first
design made from the kept library is the design made from a fresh one, bit for bit."""

from __future__ import annotations

import struct
from dataclasses import replace

import numpy as np

import maps.librarycache as librarycache
from maps.trialdesign import first_design
from primitives.ship import load_profile


def _canon(v, profile, depth=0):
    """``v`` as plain values: arrays as (dtype, shape, bytes), objects as their attributes, the profile by
    name (pickles of equal objects can differ in which strings they share)."""
    if v is profile:
        return "<profile>"
    if isinstance(v, np.ndarray):
        return (str(v.dtype), v.shape, v.tobytes())
    if isinstance(v, float):
        return struct.pack("<d", v)  # bit for bit, NaN included
    if isinstance(v, (list, tuple)):
        return [_canon(x, profile, depth + 1) for x in v]
    if isinstance(v, dict):
        return {k: _canon(x, profile, depth + 1) for k, x in v.items()}
    if hasattr(v, "__dict__") and depth < 8:
        return (type(v).__name__, _canon(vars(v), profile, depth + 1))
    return v


def _bits(first, profile):
    return _canon((first.design, first.infos, first.baseline, first.library), profile)


def test_kept_library_gives_the_same_first_design(tmp_path, monkeypatch):
    profile = load_profile("full-scale")
    fresh = first_design(profile, trial_length_s=1800.0)  # no cache (the tests' setting)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    stored = first_design(profile, trial_length_s=1800.0)
    assert len(list(tmp_path.glob("*.moves"))) == 1

    def refuse(*a, **k):
        raise AssertionError("computed again")

    monkeypatch.setattr(librarycache, "ship_library", refuse)
    monkeypatch.setattr(librarycache, "library_information", refuse)
    read = first_design(profile, trial_length_s=1800.0)
    assert _bits(fresh, profile) == _bits(stored, profile) == _bits(read, profile)
    assert all(p.profile is profile for p in read.library)  # the caller's profile, not a copy


def test_no_cache_directory_keeps_no_library(tmp_path, monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", "")
    lib, infos = librarycache.kept_library(load_profile("full-scale"))
    assert len(lib) == len(infos) > 0
    assert not list(tmp_path.rglob("*.moves"))


def test_damaged_entry_is_computed_again(tmp_path, monkeypatch):
    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    lib, infos = librarycache.kept_library(profile)
    (entry,) = tmp_path.glob("*.moves")
    entry.write_bytes(entry.read_bytes()[:100])
    lib2, infos2 = librarycache.kept_library(profile)
    assert [p.name for p in lib2] == [p.name for p in lib]
    assert _canon(infos2, profile) == _canon(infos, profile)


def test_changed_profile_is_not_served_the_kept_library(tmp_path, monkeypatch):
    # a user's ship file edited (one particular changed) reads no entry of the ship it was
    full = load_profile("full-scale")
    true = full.parameter_sets[full.simulation_set]
    changed = replace(full, parameter_sets=full.parameter_sets | {full.simulation_set: true * 1.1})
    _, fresh = librarycache.kept_library(changed)  # no cache (the tests' setting)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    _, kept_full = librarycache.kept_library(full)
    _, read = librarycache.kept_library(changed)
    assert _canon(read, changed) == _canon(fresh, changed)
    assert _canon(read, changed) != _canon(kept_full, full)
    assert len(list(tmp_path.glob("*.moves"))) == 2
