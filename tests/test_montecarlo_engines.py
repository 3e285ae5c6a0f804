"""The Dask engine's capacity (issue 14): the Monte Carlo cuts its tasks per worker slot, so the
engine must count the workers the cluster will have, not only those connected at the instant it
asks (workers still starting, or restarting under their nanny after a loss)."""

from __future__ import annotations

import time

import pytest

import expdesign.parallel as par
from expdesign.parallel import DaskEngine, get_engine

distributed = pytest.importorskip("distributed")


def _cluster(n: int, threads: int = 1):
    return distributed.LocalCluster(n_workers=n, threads_per_worker=threads, processes=False, dashboard_address=None)


def test_capacity_waits_for_the_workers_the_cluster_is_configured_for():
    with _cluster(1) as cluster, DaskEngine(cluster) as eng:
        cluster.scale(3)  # the new workers start in the background
        assert eng.expected_workers() == 3
        assert eng.capacity() == (3, 1)


def test_capacity_on_an_address_waits_for_a_first_worker():
    with _cluster(0, threads=2) as cluster, get_engine(cluster.scheduler_address) as eng:
        assert eng.expected_workers() == 0  # an address does not say how many workers will connect
        cluster.scale(1)
        assert eng.capacity() == (1, 2)  # the worker's threads, not the no-worker fallback (1, 1)


def test_capacity_without_any_worker_gives_up_after_the_wait(monkeypatch):
    monkeypatch.setattr(par, "WORKER_WAIT_S", 0.5)
    with _cluster(0) as cluster, get_engine(cluster.scheduler_address) as eng:
        t = time.perf_counter()
        assert eng.capacity() == (1, 1)
        assert time.perf_counter() - t < 10
