"""The ship's library and its information kept between commands (maps.librarycache): the first
design made from the kept library is the design made from a fresh one, bit for bit."""

from __future__ import annotations

import struct
from dataclasses import replace

import numpy as np

import maps.librarycache as librarycache
from maps import movecache
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


def test_kept_first_design_is_the_design_made(tmp_path, monkeypatch):
    # plan-trial's drawer reads the first design instead of importing scipy.optimize and solving (stop 52): the
    # same bits as a design made afresh, and never made again while the entry is there
    import maps.trialdesign as trialdesign

    profile = load_profile("full-scale")
    fresh = first_design(profile, trial_length_s=1800.0)  # no cache (the tests' setting)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    made = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    assert len(list(tmp_path.glob("*.moves"))) == 2  # the library and the design

    def refuse(*a, **k):
        raise AssertionError("designed again")

    monkeypatch.setattr(librarycache, "first_design", refuse)
    monkeypatch.setattr(trialdesign, "design_counts", refuse)
    read = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    assert _bits(fresh, profile) == _bits(made, profile) == _bits(read, profile)
    assert read.design.counts == fresh.design.counts
    assert all(p.profile is profile for p in read.library)  # the caller's profile, not a copy


def test_kept_first_design_is_keyed_by_every_design_option(tmp_path, monkeypatch):
    from expdesign.prior import make_prior

    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    base = dict(criterion="D", mean_subtraction="complete", trial_length_s=1800.0, seed=0)
    librarycache.kept_first_design(profile, **base)
    variants = [
        base | {"trial_length_s": 2400.0},
        base | {"mean_subtraction": "batchwise"},
        base | {"seed": 1},
        base | {"criterion": "A"},
    ]
    for opts in variants:  # each designed afresh (no entry of another option served), equal to first_design's
        kept = librarycache.kept_first_design(profile, **opts)
        assert _bits(kept, profile) == _bits(first_design(profile, **opts), profile)
    assert len(list(tmp_path.glob("*.moves"))) == 2 + len(variants)
    # a --prior-spread prior holds its sampler (a local function): not picklable, so not keyed: designed every
    # time, nothing kept, the design first_design makes
    prior = make_prior(profile, 0.2, None, 20, 0)
    robust = base | {"criterion": "bayes-D"}
    a = librarycache.kept_first_design(profile, parameter_prior=prior, **robust)
    assert len(list(tmp_path.glob("*.moves"))) == 2 + len(variants)
    assert _bits(a, profile) == _bits(first_design(profile, parameter_prior=prior, **robust), profile)


def test_kept_first_design_is_keyed_by_a_file_priors_draws(tmp_path, monkeypatch):
    # review of stop 52: a --prior-file prior (fixed draws, no sampler) is keyed by its pickle's digest: two priors
    # that differ only in their draws get two entries, each first_design's bits; the same draws read again are served
    from expdesign.prior import ParameterPrior, make_prior

    profile = load_profile("full-scale")
    spread = make_prior(profile, 0.2, None, 12, 0)
    a = ParameterPrior(spread.centre, spread.draws, "file a.json")
    b = ParameterPrior(spread.centre, spread.draws * (1 + 1e-3), "file a.json")
    robust = dict(criterion="bayes-D", mean_subtraction="complete", trial_length_s=1800.0, seed=0)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    for prior in (a, b):
        kept = librarycache.kept_first_design(profile, parameter_prior=prior, **robust)
        assert _bits(kept, profile) == _bits(first_design(profile, parameter_prior=prior, **robust), profile)
    assert len(list(tmp_path.glob("*.moves"))) == 3  # the library and one design a prior

    def refuse(*args, **kwargs):
        raise AssertionError("designed again")

    monkeypatch.setattr(librarycache, "first_design", refuse)
    again = ParameterPrior(spread.centre.copy(), spread.draws.copy(), "file a.json")
    assert _bits(librarycache.kept_first_design(profile, parameter_prior=again, **robust), profile) == _bits(
        first_design(profile, parameter_prior=a, **robust), profile
    )


def test_a_design_that_fails_is_not_kept(tmp_path, monkeypatch):
    import pytest

    from primitives.errors import UserError

    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    for _ in range(2):  # the same error both times: nothing kept in between
        with pytest.raises(UserError):
            librarycache.kept_first_design(profile, trial_length_s=1.0)
    assert len(list(tmp_path.glob("*.moves"))) == 1  # the library alone


def test_damaged_design_entry_is_designed_again(tmp_path, monkeypatch):
    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    librarycache.kept_library(profile)
    (lib_entry,) = tmp_path.glob("*.moves")
    made = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    (entry,) = set(tmp_path.glob("*.moves")) - {lib_entry}
    entry.write_bytes(entry.read_bytes()[:100])
    again = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    assert _bits(again, profile) == _bits(made, profile)


def _digest(obj, profile):
    """:func:`maps.plancache.fields_digest` field by field, down the nested dataclasses (the digest of a
    TrialDesign taken whole differs between one made and one read back on s53-integration too: pickle's memo
    writes a string shared by two of its Design's fields once)."""
    from dataclasses import is_dataclass

    from maps import movecache, plancache

    if is_dataclass(obj):
        return [(name, _digest(v, profile)) for name, v in plancache.fields_of(obj)]
    return plancache.fields_digest(obj, lambda v: movecache.dumps(v, profile))


def test_kept_first_design_holds_no_library_and_reads_as_the_design_made(tmp_path, monkeypatch):
    # stop 53 (the kept design): the design's entry leaves the library and its information to kept_library's entry
    # (written as references: about 2 kB instead of 170 kB), and the design read is equal field by field to one
    # made afresh, its library kept_library's very lists, the design's primitives the library's objects
    import maps.trialdesign as trialdesign
    from maps import plancache

    profile = load_profile("full-scale")
    fresh = first_design(profile, trial_length_s=1800.0)  # no cache (the tests' setting)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    lib, infos = librarycache.kept_library(profile)
    (lib_entry,) = tmp_path.glob("*.moves")
    made = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    (entry,) = set(tmp_path.glob("*.moves")) - {lib_entry}
    data = plancache.load_blob(tmp_path, entry.name)[1]
    assert b"PrimitiveInfo" not in data and b"primitives.library" not in data
    assert entry.stat().st_size < lib_entry.stat().st_size / 20

    def refuse(*a, **k):
        raise AssertionError("designed or computed again")

    monkeypatch.setattr(librarycache, "first_design", refuse)
    monkeypatch.setattr(trialdesign, "design_counts", refuse)
    monkeypatch.setattr(librarycache, "ship_library", refuse)
    monkeypatch.setattr(librarycache, "library_information", refuse)
    read = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    assert _digest(read, profile) == _digest(made, profile) == _digest(fresh, profile)
    assert _bits(read, profile) == _bits(fresh, profile)
    assert all(p is q for p, q in zip(read.design.primitives, read.library)) and read.library
    assert all(p.profile is profile for p in read.library)  # the caller's profile, not a copy


def test_kept_design_of_another_library_is_no_entry(tmp_path, monkeypatch):
    # a design entry whose references point into a library of other primitives (the library's entry changed under
    # it) is not read: the design is made again from the library there is, as first_design makes it
    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    librarycache.kept_first_design(profile, trial_length_s=1800.0)
    lib, infos = librarycache.kept_library(profile)
    for short in ((lib[1:], infos[1:]), (lib[:-1], infos[:-1])):  # a place missing; the names shifted
        monkeypatch.setattr(librarycache, "kept_library", lambda p, short=short: short)
        read = librarycache.kept_first_design(profile, trial_length_s=1800.0)
        assert [p.name for p in read.library] == [p.name for p in short[0]]
        assert _digest(read, profile) == _digest(first_design(profile, short[0], trial_length_s=1800.0), profile)
        monkeypatch.undo()
        monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))


def test_kept_design_entry_of_another_shape_is_no_entry(tmp_path, monkeypatch):
    # an entry under the design's key that is not a design part (damaged, or another code's: an array for the
    # names, a reordered library) is designed again, never read nor raised
    profile = load_profile("model-ship")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    fresh = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    lib, infos = librarycache.kept_library(profile)
    k = movecache.key(profile, "first-design", (("trial_length_s", 1800.0), ("prior", None)))
    part = librarycache._design_part(fresh)
    for odd in ((np.array([p.name for p in lib]), *part[1:]), (part[0][::-1], *part[1:])):
        movecache.store(k, odd, profile, [*lib, *infos])
        assert type(movecache.load(k, profile, [*lib, *infos])[0]) is type(odd[0])  # the design's own key
        assert _digest(librarycache.kept_first_design(profile, trial_length_s=1800.0), profile) == _digest(fresh, profile)


def test_kept_ratios_png_is_the_figure_drawn(tmp_path, monkeypatch):
    # plan-trial's drawer reads the kept design's ratios figure instead of drawing it on every run (stop 53): the
    # same bytes as drawn afresh, never drawn again while the entry is there, and another design, a damaged
    # entry or another matplotlib setting is drawn afresh
    import matplotlib

    import expdesign.report as report

    profile = load_profile("full-scale")
    design = first_design(profile, trial_length_s=1800.0).design.design
    fresh = report.ratios_png(design)
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    assert librarycache.kept_ratios_png(profile, design) == fresh
    (entry,) = tmp_path.glob("*.moves")
    drawn = []
    real = report.ratios_png
    monkeypatch.setattr(report, "ratios_png", lambda d: drawn.append(d) or real(d))
    assert librarycache.kept_ratios_png(profile, design) == fresh and drawn == []
    other = replace(design, weights={k: (1.0 if i == 0 else 0.0) for i, k in enumerate(design.weights)})
    assert librarycache.kept_ratios_png(profile, other) == real(other) != fresh and len(drawn) == 1
    with matplotlib.rc_context({"font.size": 14}):  # a user's matplotlibrc: not served the kept bytes
        assert librarycache.kept_ratios_png(profile, design) == real(design) != fresh and len(drawn) == 2
    entry.write_bytes(entry.read_bytes()[:100])
    assert librarycache.kept_ratios_png(profile, design) == fresh and len(drawn) == 3


def _spy_on_drawing(monkeypatch):
    """The designs :func:`expdesign.report.ratios_png` draws from now on (kept_ratios_png imports it when called)."""
    import expdesign.report as report

    drawn = []
    real = report.ratios_png
    monkeypatch.setattr(report, "ratios_png", lambda d: drawn.append(d) or real(d))
    return drawn


def test_kept_ratios_png_of_a_design_read_back_is_the_kept_figure(tmp_path, monkeypatch):
    # the first plan-trial makes the first design afresh and keeps its figure; the next reads the design back,
    # whose whole pickle differs (strings shared otherwise): its figure must still be read, not drawn again
    from maps import movecache

    profile = load_profile("full-scale")
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    made = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    png = librarycache.kept_ratios_png(profile, made.design.design)
    entries = set(tmp_path.glob("*.moves"))
    back = librarycache.kept_first_design(profile, trial_length_s=1800.0)
    assert back is not made and set(tmp_path.glob("*.moves")) == entries  # read back, nothing new kept
    assert movecache.dumps(back.design.design, profile) != movecache.dumps(made.design.design, profile)
    drawn = _spy_on_drawing(monkeypatch)
    assert librarycache.kept_ratios_png(profile, back.design.design) == png and drawn == []
    assert set(tmp_path.glob("*.moves")) == entries


def test_no_cache_directory_draws_the_figure_and_keeps_nothing(tmp_path, monkeypatch):
    import expdesign.report as report

    profile = load_profile("full-scale")
    design = first_design(profile, trial_length_s=1800.0).design.design
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))  # were the default used, it would show here
    monkeypatch.chdir(tmp_path)
    drawn = _spy_on_drawing(monkeypatch)
    for n in (1, 2):
        assert librarycache.kept_ratios_png(profile, design) == report.ratios_png(design) and len(drawn) == 2 * n
    assert list(tmp_path.rglob("*")) == []


def test_a_design_pickle_cannot_write_is_drawn_every_time(tmp_path, monkeypatch):
    import expdesign.report as report

    profile = load_profile("full-scale")
    design = first_design(profile, trial_length_s=1800.0).design.design
    odd = replace(design, certificate={**design.certificate, "note": lambda: None})  # a lambda: no pickle
    monkeypatch.setenv("SHIPTRIAL_CACHE_DIR", str(tmp_path))
    drawn = _spy_on_drawing(monkeypatch)
    for n in (1, 2):
        assert librarycache.kept_ratios_png(profile, odd) == report.ratios_png(design) and len(drawn) == 2 * n
    assert list(tmp_path.glob("*.moves")) == []


_BEFORE_BACKEND = """
import sys
import expdesign.report as report
from maps import librarycache
from maps.trialdesign import first_design
from primitives.ship import load_profile

profile = load_profile("full-scale")
design = first_design(profile, trial_length_s=1800.0).design.design
assert "matplotlib.pyplot" not in sys.modules, "the backend was chosen before the test"
png = librarycache.kept_ratios_png(profile, design)  # keyed before anything chose the backend
gui = sorted(m for m in ("tkinter", "PyQt5", "PyQt6", "PySide2", "PySide6", "gi", "wx") if m in sys.modules)
drawn = []
real = report.ratios_png
report.ratios_png = lambda d: drawn.append(d) or real(d)
again = librarycache.kept_ratios_png(profile, design)  # the backend now Agg (drawing chose it)
print(gui, len(drawn), again == png)
"""


def test_kept_ratios_png_keyed_before_the_backend_is_chosen(tmp_path):
    # a fresh process that has not chosen matplotlib's backend: keying must not choose one (with a display it
    # would import a GUI toolkit) nor key by it (the next call, after drawing chose Agg, would miss)
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    env |= {"SHIPTRIAL_CACHE_DIR": str(tmp_path), "DISPLAY": ":0", "PYTHONPATH": str(root)}
    out = subprocess.run([sys.executable, "-c", _BEFORE_BACKEND], capture_output=True, text=True, cwd=root, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[-2] == "[] 0 True"
