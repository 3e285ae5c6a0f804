"""The no-change records' noise kept on disk per prior and recording length
(identify/detect/noisecache.py): a second ``detect`` reads it instead of drawing and filtering it,
with the same numbers to the bit; an entry that is not whole is computed again; the cache is
bounded, and off where the user turned it off."""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest

from diagnose.recording import write_csv
from identify.detect import noisecache, nullsim
from identify.detect.api import detect, fit_prior, hull_inertia, save_prior, simulated_recording
from identify.detect.batch import detect_all
from identify.detect.vessel import Vessel

HULL = dict(zip(("i_z", "n_rdot"), hull_inertia("naval-vessel")))
FIELDS = ("statistic", "dead_zone", "threshold", "dead_zone_h", "dead_zone_alarm_s")


@pytest.fixture(scope="module")
def prior(tmp_path_factory):
    path = tmp_path_factory.mktemp("noisecache") / "nominal.csv"
    write_csv(simulated_recording(Vessel(), 400, seed=21, measured_moment=True), path)
    return fit_prior([path], "full")


@pytest.fixture(scope="module")
def rec():
    return simulated_recording(Vessel(), 250, seed=61, measured_moment=True, change_at_s=80.0, changed=Vessel(inertia=1.3))


@pytest.fixture(scope="module")
def uncached(prior, rec):
    """``detect`` with no cache (the tests' default: SHIPTRIAL_CACHE_DIR is empty, tests/conftest.py)."""
    assert noisecache.default_dir() is None
    return detect(rec, prior, null_runs=60, **HULL)


def _same(a, b) -> None:
    for k in FIELDS:
        x, y = getattr(a, k), getattr(b, k)
        assert np.array_equal(x, y, equal_nan=True) if isinstance(x, np.ndarray) else repr(x) == repr(y), k
    assert (a.changed, a.property, a.alarm_s, repr(a.evidence)) == (b.changed, b.property, b.alarm_s, repr(b.evidence))


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The cache in ``tmp_path``, in use as ``shiptrial detect`` uses it (:func:`noisecache.used`)."""
    monkeypatch.setenv(noisecache.ENV_DIR, str(tmp_path))
    with noisecache.used():
        yield tmp_path


def _count_draws(monkeypatch) -> list[int]:
    calls: list[int] = []
    draw = nullsim.normals
    monkeypatch.setattr(nullsim, "normals", lambda *a, **k: calls.append(1) or draw(*a, **k))
    return calls


def test_a_second_detect_reads_the_noise_and_gives_the_same_bits(prior, rec, uncached, cache, monkeypatch):
    """The first call draws, filters and writes the entry; the second reads it (memory-mapped, nothing
    drawn) and gives every statistic, threshold and the verdict of the call without a cache, to the
    bit; so does a job of two recordings of that length (``detect_all``), read from the entry."""
    calls = _count_draws(monkeypatch)
    first = detect(rec, prior, null_runs=60, **HULL)
    assert calls == [1] and len(list(cache.iterdir())) == 1
    second = detect(rec, prior, null_runs=60, **HULL)
    assert calls == [1]  # read back, not drawn
    _same(first, uncached)
    _same(second, uncached)
    for d in detect_all([rec, rec], prior, null_runs=60, **HULL):
        _same(d, uncached)
    assert calls == [1]


def test_the_entry_is_keyed_on_what_the_noise_depends_on(prior, rec, cache, monkeypatch):
    """Another seed, number of records, recording length, noise level of the prior, input filter or code is
    another entry (drawn afresh), never the first one's noise (whose answer would differ); the answer read from
    an entry is the cache-less one (test_a_second_detect_reads_the_noise_and_gives_the_same_bits)."""
    calls = _count_draws(monkeypatch)
    detect(rec, prior, null_runs=60, **HULL)
    first = next(iter(prior.noise))
    noisier = replace(prior, noise={**prior.noise, first: 1.5 * prior.noise[first]})
    shorter = simulated_recording(Vessel(), 200, seed=61, measured_moment=True)
    cases = [
        (rec, prior, {"seed": 1}),
        (rec, prior, {"null_runs": 50}),
        (shorter, prior, {}),
        (rec, noisier, {}),
        (rec, replace(prior, prefilter_hz=0.8 * prior.prefilter_hz), {}),
    ]
    for r, p, kw in cases:
        detect(r, p, **({"null_runs": 60} | kw), **HULL)
    monkeypatch.setattr(noisecache, "code_version", lambda: "another version of identify/ or primitives/")
    detect(rec, prior, null_runs=60, **HULL)
    assert calls == [1] * 7 and len(list(cache.iterdir())) == 7


def test_an_entry_filtered_by_the_compiled_loop_is_not_read_by_the_numpy_one(prior, rec, cache, monkeypatch):
    """The noise's input filters run compiled (scipy's bits) in a large job and in numpy (scipy's to rounding,
    primitives.zerophase) in a one-recording command: an entry written by ``shiptrial detect`` on 40 recordings
    is not the noise of a later call on one of them (its thresholds would differ in the last digits from
    those without a cache), and the other way round."""
    from primitives import jitloop

    if not jitloop.AVAILABLE:
        pytest.skip("numba is not installed: one loop only")
    with jitloop.job(10 * jitloop.JOB_MIN_WORK):  # compiled, as a call on many recordings
        detect(rec, prior, null_runs=60, **HULL)
    monkeypatch.setattr(jitloop, "AVAILABLE", False)  # the numpy loops, as a call on one recording
    read = detect(rec, prior, null_runs=60, **HULL)
    monkeypatch.setenv(noisecache.ENV_DIR, "")
    _same(read, detect(rec, prior, null_runs=60, **HULL))
    assert len(list(cache.iterdir())) == 2


@pytest.mark.parametrize("damage", ["truncated", "one byte changed"])
def test_an_entry_that_is_not_whole_is_computed_again(prior, rec, uncached, cache, monkeypatch, damage):
    """A truncated noise file (a disk filled mid-write) or one with a byte changed in its numbers (a bad
    sector, an entry edited by hand: of the right size, so only its SHA-256 tells) is not read: the noise
    is drawn again, the numbers are the cache-less ones, and no error is raised."""
    detect(rec, prior, null_runs=60, **HULL)
    (entry,) = cache.iterdir()
    data = bytearray(entry.read_bytes())
    if damage == "truncated":
        del data[len(data) // 2 :]
    else:
        data[len(data) // 2] ^= 0x40  # an exponent bit of a float64 in the inputs' shares
    entry.write_bytes(bytes(data))
    calls = _count_draws(monkeypatch)
    _same(detect(rec, prior, null_runs=60, **HULL), uncached)
    assert calls == [1]


def _entry(value: float) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    return np.full((3, 20), value), {"x": np.full((20, 3), -value)}, np.zeros((2, 3))


def test_the_cache_keeps_the_most_recently_used_within_its_byte_budget(cache, monkeypatch):
    """Beyond the byte budget (``SHIPTRIAL_DETECT_CACHE_MB``; 256 MB by default: two 500 s entries) the least
    recently used are removed; a read marks an entry used; the newest is kept whatever its size."""
    assert noisecache.budget() == noisecache.BUDGET_BYTES == 256 * 2**20
    noisecache.store("a", *_entry(0.0))
    size = (cache / "a.noise").stat().st_size
    monkeypatch.setenv(noisecache.ENV_MB, str(2.5 * size / 2**20))  # room for two entries, not three
    assert noisecache.budget() == int(2.5 * size)
    noisecache.store("b", *_entry(1.0))
    for t, name in enumerate(("a", "b")):
        os.utime(cache / f"{name}.noise", (1000 + t, 1000 + t))
    assert noisecache.load("a", 3, 20, 2) is not None  # "a" used now: "b" is the oldest
    noisecache.store("c", *_entry(2.0))
    assert sorted(p.name for p in cache.iterdir()) == ["a.noise", "c.noise"]
    r_noise, inputs, blocks = noisecache.load("c", 3, 20, 2)
    assert np.array_equal(r_noise, _entry(2.0)[0]) and list(inputs) == ["x"] and np.array_equal(inputs["x"], _entry(2.0)[1]["x"])
    assert not r_noise.flags.writeable and not inputs["x"].flags.writeable and not blocks.flags.writeable
    assert noisecache.load("c", 4, 20, 2) is None  # another shape: not this entry
    monkeypatch.setenv(noisecache.ENV_MB, "0")
    noisecache.store("d", *_entry(3.0))
    assert [p.name for p in cache.iterdir()] == ["d.noise"]
    for bad in ("lots", "-1", "nan"):
        monkeypatch.setenv(noisecache.ENV_MB, bad)
        assert noisecache.budget() == noisecache.BUDGET_BYTES


def test_the_cache_is_off_where_the_user_turned_it_off(monkeypatch, tmp_path):
    """``SHIPTRIAL_DETECT_CACHE_DIR`` names the directory ("" none; a ``~user`` that does not exist: none,
    not a traceback); the planner's ``SHIPTRIAL_CACHE_DIR`` set empty turns this cache off too; by default
    it is under ``$XDG_CACHE_HOME/shiptrial/detect``."""
    monkeypatch.delenv(noisecache.ENV_DIR, raising=False)
    monkeypatch.setenv(noisecache.ENV_PLANNER, "")
    assert noisecache.default_dir() is None
    monkeypatch.delenv(noisecache.ENV_PLANNER)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert noisecache.default_dir() == tmp_path / "shiptrial" / "detect"
    monkeypatch.setenv(noisecache.ENV_DIR, "~no-such-user-shiptrial/cache")
    assert noisecache.default_dir() is None
    monkeypatch.setenv(noisecache.ENV_DIR, "")
    assert noisecache.default_dir() is None
    with noisecache.used():
        noisecache.store("a", np.zeros((1, 5)), {"x": np.zeros((5, 1))}, np.zeros((0, 1)))
        assert noisecache.load("a", 1, 5, 0) is None
    assert not (tmp_path / "shiptrial").exists()


def test_a_library_call_outside_the_command_touches_no_disk(prior, rec, uncached, tmp_path, monkeypatch):
    """Only ``shiptrial detect`` uses the cache (:func:`noisecache.used`): ``detect`` called from
    Python (a benchmark's thousands of screenings, a notebook) writes and reads nothing, even with the
    directory set."""
    monkeypatch.setenv(noisecache.ENV_DIR, str(tmp_path / "c"))
    _same(detect(rec, prior, null_runs=60, **HULL), uncached)
    assert not (tmp_path / "c").exists()


def test_the_command_writes_the_entry_and_reads_it_back(prior, tmp_path, monkeypatch, capsys):
    """``shiptrial detect`` on one file twice: the first run writes one entry, the second prints the same
    JSON, byte for byte, with the noise read from it (nothing drawn)."""
    from cli.app import _run

    save_prior(prior, tmp_path / "prior.json")
    write_csv(simulated_recording(Vessel(), 250, seed=63, measured_moment=True), tmp_path / "r.csv")
    monkeypatch.setenv(noisecache.ENV_DIR, str(tmp_path / "c"))
    args = ["detect", str(tmp_path / "r.csv"), "--prior", str(tmp_path / "prior.json"), "--profile", "naval-vessel", "--json"]
    assert _run(args) in (0, None)
    first = capsys.readouterr().out
    assert len(list((tmp_path / "c").iterdir())) == 1
    calls = _count_draws(monkeypatch)
    assert _run(args) in (0, None)
    assert capsys.readouterr().out == first and calls == []


def test_a_pod_input_recording_writes_no_entry(prior, cache):
    """From the pod inputs the noise is filtered with the signals (nonlinear derivation): nothing of it
    is the same for another recording, and nothing is written."""
    detect(simulated_recording(Vessel(), 250, seed=62), prior, null_runs=40, **HULL)
    assert not list(cache.iterdir())
