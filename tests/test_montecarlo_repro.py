"""A Monte Carlo run's result depends on (seed, run index) only: SHA-256 digests of every
per-run array are identical in process (three chunk sizes), on local pools of 1, 2 and 3
workers with the engine's cut and a finer one, and on a distributed.LocalCluster; interrupted or failed evaluations are partial."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign.mc_parallel import MIN_TASK_RUNS, cut_tasks, evaluate_designs_parallel, plan_tasks
from expdesign.montecarlo import MAX_CHUNK, evaluate_designs
from expdesign.parallel import Engine, LocalEngine
from primitives.library import model_ship_thesis
from primitives.ship import load_profile

DESIGNS = {"optimized": {"tau1": 0.2, "tau6": 0.3, "tau8": 0.23, "tau11": 0.27}, "random": "random"}
KW = dict(runs=12, seed=3, n_samples=300)


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    return p, model_ship_thesis(p)


@pytest.fixture(scope="module")
def reference(ship):
    p, lib = ship
    return evaluate_designs(p, DESIGNS, primitives=lib, **KW)


def _digests(res):
    return {k: r.digest() for k, r in res.items()}


def test_reference_has_diverged_and_finite_runs(reference):
    # the random design diverges in some runs: those must be reproducible too
    assert reference["random"].diverged.any() and not reference["optimized"].diverged.all()
    assert all(len(r.runs) == 12 and not r.partial for r in reference.values())


@pytest.mark.parametrize("chunk", [4, 5, 7])
def test_same_digest_for_every_chunk_size(ship, reference, chunk):
    p, lib = ship
    assert _digests(evaluate_designs(p, DESIGNS, primitives=lib, chunk_size=chunk, **KW)) == _digests(reference)


@pytest.mark.parametrize("count", ["1", "3"])
def test_same_digest_on_one_thread_and_on_three(ship, reference, monkeypatch, count):
    """evaluate_designs runs its chunks on primitives.threads.count() threads (OMP_NUM_THREADS):
    the digests are those of one thread, with chunks really run at once (the first two meet at a
    barrier, which a single thread would never pass)."""
    import threading

    from expdesign import montecarlo

    run_chunk, seen, calls = montecarlo.run_chunk, set(), []
    barrier = threading.Barrier(2, timeout=20)

    def spy(*a, **k):
        calls.append(1)
        seen.add(threading.get_ident())
        if count != "1" and len(calls) <= 2:
            barrier.wait()
        return run_chunk(*a, **k)

    monkeypatch.setattr(montecarlo, "run_chunk", spy)
    monkeypatch.setenv("OMP_NUM_THREADS", count)
    p, lib = ship
    before = threading.active_count()
    assert _digests(evaluate_designs(p, DESIGNS, primitives=lib, chunk_size=2, **KW)) == _digests(reference)
    assert len(calls) == 12 and (len(seen) == 1 if count == "1" else len(seen) >= 2)
    assert threading.active_count() == before  # no thread left running: maps.forked still forks after a Monte Carlo


def test_same_digest_for_run_slices(ship, reference):
    from expdesign.mc_result import merge_results

    p, lib = ship
    parts = [evaluate_designs(p, DESIGNS, primitives=lib, run_slice=s, **KW) for s in ((7, 12), (0, 7))]
    assert _digests(merge_results(parts)) == _digests(reference)


@pytest.mark.parametrize("workers", [1, 2, 3])
@pytest.mark.parametrize("chunk_runs", [None, 2])
def test_same_digest_on_local_pools_however_the_runs_are_cut(ship, reference, workers, chunk_runs):
    # None: the engine's own cut (12 runs are too few for 100-run tasks: one task per worker slot);
    # 2: six tasks per design, so the same runs meet other batches in other processes
    p, lib = ship
    ev = evaluate_designs_parallel(
        p, DESIGNS, scheduler=LocalEngine(workers), chunk_runs=chunk_runs, progress=False, primitives=lib, **KW
    )
    assert ev.complete and _digests(ev.results) == _digests(reference)
    assert ev.engine["tasks"] == (12 if chunk_runs else max(2, workers + workers % 2))
    if workers > 1:
        assert ev.engine["workers"] == workers


def test_same_digest_on_a_dask_local_cluster(ship, reference):
    distributed = pytest.importorskip("distributed")
    p, lib = ship
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        ev = evaluate_designs_parallel(p, DESIGNS, scheduler=cluster.scheduler_address, progress=False, primitives=lib, **KW)
    assert ev.engine["name"] == "dask" and ev.engine["workers"] == 2 and ev.engine["tasks"] == 2
    assert ev.complete and _digests(ev.results) == _digests(reference)


def test_tasks_sized_to_the_machine():
    assert plan_tasks(2000, 2, 2) == 8  # 2 designs x 8 tasks of MAX_CHUNK = 250 runs: 8 per worker
    assert plan_tasks(2000, 2, 8) == 16  # 4 per worker slot, 125 runs each
    # 4 per slot would be 63-run tasks: 2 per slot of 125 runs (the fixed cost per task weighs less)
    assert plan_tasks(2000, 2, 16) == 16
    assert plan_tasks(500, 4, 16) == 4  # 125 runs a slot: one task each, not four of 32 runs
    assert plan_tasks(10, 1, 8) == 8  # fewer runs than 100 per slot: one task per slot
    assert plan_tasks(5000, 1, 1) == 20  # inline: batches of MAX_CHUNK runs, bounded memory
    assert plan_tasks(12, 2, 4, chunk_runs=5) == 3  # an explicit chunk size alone decides


@pytest.mark.parametrize("runs,designs,slots", [(200, 2, 16), (2000, 2, 16), (500, 4, 16), (2000, 2, 3), (7, 3, 2), (1001, 1, 1)])
def test_tasks_cover_every_run_once_in_near_equal_ranges(runs, designs, slots):
    names = [f"d{i}" for i in range(designs)]
    tasks = cut_tasks(names, runs, plan_tasks(runs, designs, slots))
    if slots > 1:  # at least one per worker slot, 4 when they hold MIN_TASK_RUNS runs each
        assert len(tasks) >= min(min(4, max(1, runs * designs // slots // MIN_TASK_RUNS)) * slots, designs * runs)
    for d in names:
        ranges = [(a, b) for n, a, b in tasks if n == d]
        assert [a for a, _ in ranges] == [0] + [b for _, b in ranges[:-1]] and ranges[-1][1] == runs
        sizes = {b - a for a, b in ranges}
        assert max(sizes) - min(sizes) <= 1 and 1 <= min(sizes) and max(sizes) <= MAX_CHUNK


class _InterruptAfter(Engine):
    """An engine whose user presses Ctrl-C after ``n`` tasks."""

    def __init__(self, n: int):
        self.n = n

    def map(self, fn, items, desc="working", progress=True, shared=None, weights=None, unit="tasks"):
        calls = iter(range(len(items)))

        def wrapped(item, sh):
            if next(calls) >= self.n:
                raise KeyboardInterrupt
            return fn(item, sh)

        return super().map(wrapped, items, desc, progress, shared, weights, unit)


def test_interrupted_evaluation_is_partial_and_keeps_finished_runs(ship, reference):
    p, lib = ship
    ev = evaluate_designs_parallel(p, DESIGNS, scheduler=_InterruptAfter(1), chunk_runs=6, progress=False, primitives=lib, **KW)
    assert ev.interrupted and not ev.complete
    assert ev.runs_finished == {"optimized": 6, "random": 0} and set(ev.results) == {"optimized"}  # random: none finished
    r = ev.results["optimized"]
    assert r.partial and r.summary()["runs"] == 6 and r.summary()["runs_requested"] == 12
    np.testing.assert_array_equal(r.theta, reference["optimized"].theta[:6])


def test_a_runs_noise_is_its_own_generators_draws_in_the_documented_order(ship):
    """Each run's current, wind, measurement and heading noise are its generator's draws in that
    order (one call per quantity, as the study was defined), whatever the batch draws with it."""
    from expdesign.montecarlo import run_noise, run_rng
    from primitives.simulate import Disturbances

    d = Disturbances(current_ne=(0.1, -0.2), current_sample_std=0.15, wind_ne=(3.0, 1.0), wind_sample_std=0.5,
                     measurement_std=(0.02, 0.01, 0.005), heading_std=0.01)  # fmt: skip
    n, runs = 40, [0, 7, 3]
    offsets = [np.array([0.05, -0.01]) * (i + 1) for i in runs]
    got = run_noise(d, [run_rng(2, i, 1) for i in runs], n, offsets)
    for j, i in enumerate(runs):
        g = run_rng(2, i, 1)
        cur = np.asarray(d.current_ne) + offsets[j] + g.normal(0.0, 1.0, (n, 2)) * d.current_sample_std
        wind = np.asarray(d.wind_ne) + g.normal(0.0, 1.0, (n, 2)) * d.wind_sample_std
        meas = g.normal(0.0, 1.0, (n + 1, 3)) * np.asarray(d.measurement_std)
        head = g.normal(0.0, 1.0, n + 1) * d.heading_std
        for a, b in zip(got, (cur, wind, meas, head)):
            assert np.array_equal(a[j], b)
    # the stream itself, pinned (numpy's PCG64 and ziggurat normals, today's digests): run 7's first
    # current, last wind, first measurement and last heading sample
    assert (got[0][1, 0, 0], got[1][1, -1, 1]) == (0.4054462279281199, 0.10364829442865264)
    assert (got[2][1, 0, 0], got[3][1, -1]) == (0.009908271968889283, -0.0018091617912908292)


def test_noise_without_heading_or_wind_spread_gives_the_same_numbers_and_no_arrays_for_them():
    """The fused pass reads no heading noise: it is not drawn (the last draws), the rest unchanged;
    a wind without random part is its mean for every run and sample, not a (B, n, 2) array."""
    from expdesign.montecarlo import run_noise, run_rng
    from primitives.simulate import Disturbances

    d = Disturbances(current_ne=(0.1, -0.2), current_sample_std=0.15, wind_ne=(3.0, 0.0),
                     measurement_std=(0.02, 0.01, 0.005), heading_std=0.01)  # fmt: skip
    n, runs = 40, [0, 7, 3]
    offsets = [np.array([0.05, -0.01]) * (i + 1) for i in runs]
    full = run_noise(d, [run_rng(2, i, 1) for i in runs], n, offsets)
    part = run_noise(d, [run_rng(2, i, 1) for i in runs], n, offsets, heading=False)
    assert part[3] is None
    for a, b in zip(full[:3], part[:3]):
        assert np.array_equal(a, b)
    for j, i in enumerate(runs):  # the wind's normals are still drawn: the measurement noise follows them
        g = run_rng(2, i, 1)
        g.normal(0.0, 1.0, (2, n, 2))
        assert np.array_equal(part[2][j], g.normal(0.0, 1.0, (n + 1, 3)) * np.asarray(d.measurement_std))
    assert np.array_equal(part[1], np.broadcast_to([3.0, 0.0], (3, n, 2))) and not any(part[1].strides[:2])


def test_a_fixed_designs_shared_inputs_give_the_digests_of_stacked_inputs(ship, reference, monkeypatch):
    """The fused passes read a fixed design's inputs once for the batch ((1, N, m),
    expdesign.mc_data._batch_inputs); a (B, N, m) stack of the same inputs gives the same digests."""
    from expdesign import mc_data

    seen = []

    def stacked(runs, shared):
        seen.append(shared and all(r is runs[0] for r in runs))
        return np.stack(runs)

    monkeypatch.setattr(mc_data, "_batch_inputs", stacked)
    p, lib = ship
    assert _digests(evaluate_designs(p, DESIGNS, primitives=lib, **KW)) == _digests(reference)
    from primitives import jitloop

    assert any(seen) == jitloop.AVAILABLE  # the fused pass (numba loaded) would have shared them; the numpy path never


def test_batch_inputs_shares_one_array_only_when_every_run_plays_it():
    """_batch_inputs: (1, L, m) of the very array when shared and every run plays it, else the
    (B, L, m) stack (another array with equal numbers is not the same experiment array)."""
    from expdesign.mc_data import _batch_inputs

    a = np.arange(12.0).reshape(4, 3)
    one = _batch_inputs([a, a, a], shared=True)
    assert one.shape == (1, 4, 3) and np.shares_memory(one, a)
    assert _batch_inputs([a, a, a], shared=False).shape == (3, 4, 3)
    assert _batch_inputs([a, a.copy(), a], shared=True).shape == (3, 4, 3)
