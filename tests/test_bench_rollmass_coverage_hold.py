"""``bench_rollmass_coverage.py repeat --vary ROLE`` (stop 60): a fresh sea for one role's dataset only, the case's
other datasets on the held sea. The experiment's reading rests on it: a dataset held must be bit-identical over the
realizations, the varied one must change, and the held sea must be the one ``--vary all`` draws for that realization."""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks import bench_rollmass_coverage as bc
from tests.physics import basin_truth as bt


def _datasets(monkeypatch, vary: str, k: int) -> dict[str, dict[str, np.ndarray]]:
    """The four datasets of one short ``base`` run on realization ``k`` of sea seed 5, ``vary`` as ``repeat --vary``."""
    for name in ("_narrowband", "_jonswap"):  # the wrappers _fresh_sea installs are undone after the test
        monkeypatch.setattr(bt, name, getattr(bt, name))
    hold = bc._held_sea(argparse.Namespace(vary=vary, case="case2", sea_seed=5, held_sea=0, realizations=2))
    bc._fresh_sea(1.0, [5, k], hold)
    return bt.simulate_runs("base", 1, bt.variant_seed(2015, "base"), length=0.05)[1]


def test_vary_one_role_holds_the_others(monkeypatch):
    held, varied = _datasets(monkeypatch, "calibration", 0), _datasets(monkeypatch, "calibration", 1)
    calibration = bt.CASES["case2"][1]
    for name in bt.DATASETS:
        same = all(np.array_equal(held[name][c], varied[name][c]) for c in ("p", "a_s", "r", "phi"))
        assert same == (name != calibration), name  # only the calibration's sea is drawn afresh


def test_held_sea_is_the_all_draw_of_that_realization(monkeypatch):
    held, every = _datasets(monkeypatch, "loaded", 0), _datasets(monkeypatch, "all", 0)
    for name in bt.DATASETS:
        assert np.array_equal(held[name]["p"], every[name]["p"]), name
    other = _datasets(monkeypatch, "all", 1)
    assert not np.array_equal(every[bt.CASES["case2"][0]]["p"], other[bt.CASES["case2"][0]]["p"])
