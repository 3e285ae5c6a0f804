"""Engines: the same seed gives the same numbers inline, on local cores and on a Dask cluster."""

import numpy as np
import pytest

from expdesign.parallel import DaskEngine, Engine, LocalEngine, get_engine, task_seeds


def _noisy_sim(seed: int) -> np.ndarray:
    from primitives.ship import load_profile
    from primitives.simulate import Disturbances, simulate

    prof = load_profile("model-ship")
    res = simulate(prof, np.tile([3000.0, 200.0, 100.0], (80, 1)), disturbances=Disturbances.from_profile(prof), batch=4, seed=seed)
    return res.y[:, -1]


def test_task_seeds_are_stable_and_distinct():
    a, b = task_seeds(7, 5), task_seeds(7, 5)
    assert a == b and len(set(a)) == 5
    assert task_seeds(8, 5) != a


def test_inline_and_local_pool_agree():
    seeds = task_seeds(3, 4)
    r1 = Engine().map(_noisy_sim, seeds, progress=False)
    r2 = LocalEngine(2).map(_noisy_sim, seeds, progress=False)
    assert r1.complete and r2.complete
    for x, y in zip(r1.results, r2.results):
        np.testing.assert_array_equal(x, y)


def test_dask_local_cluster_agrees_with_local():
    distributed = pytest.importorskip("distributed")
    seeds = task_seeds(3, 4)
    local = Engine().map(_noisy_sim, seeds, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with get_engine(cluster.scheduler_address) as eng:
            assert isinstance(eng, DaskEngine)
            remote = eng.map(_noisy_sim, seeds, progress=False)
    assert remote.complete
    for x, y in zip(local.results, remote.results):
        np.testing.assert_array_equal(x, y)


def test_interrupt_keeps_finished_results():
    calls = []

    def task(i):
        if i == 2:
            raise KeyboardInterrupt
        calls.append(i)
        return i * 10

    res = Engine().map(task, [0, 1, 2, 3], progress=False)
    assert res.interrupted and res.finished() == [0, 10] and res.done == [True, True, False, False]


def test_scheduler_from_environment(monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_SCHEDULER", "inline")
    assert type(get_engine()) is Engine
    monkeypatch.delenv("SHIPTRIAL_SCHEDULER")
    assert isinstance(get_engine(), LocalEngine)
