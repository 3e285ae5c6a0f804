"""``bench_rollmass_coverage.py repeat --vary ROLE`` (stop 60; :mod:`benchmarks.rollmass_coverage_repeat`): a fresh
sea for one role's dataset only, the case's other datasets on the held sea. The experiment's reading rests on it: a
dataset held must be bit-identical over the realizations, the varied one must change, and the held sea must be the one
``--vary all`` draws for that realization."""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks import rollmass_coverage_repeat as bc
from tests.physics import basin_truth as bt


def _datasets(monkeypatch, vary: str, k: int) -> dict[str, dict[str, np.ndarray]]:
    """The four datasets of one short ``base`` run on realization ``k`` of sea seed 5, ``vary`` as ``repeat --vary``."""
    for name in ("_narrowband", "_jonswap"):  # the wrappers fresh_sea installs are undone after the test
        monkeypatch.setattr(bt, name, getattr(bt, name))
    hold = bc.held_sea(argparse.Namespace(vary=vary, case="case2", sea_seed=5, held_sea=0, realizations=2))
    bc.fresh_sea(1.0, [5, k], hold)
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


def test_freeze_noise_replays_the_first_fits_whiteners(monkeypatch):
    """``--freeze-noise``: the first fit's ``FROZEN_STAGES`` noise models are estimated, every later stage gets the
    same stage's model back (not one estimated from its own residuals), the stages in order over fits and LM paths."""
    made = []

    def estimate(errs, ar, ar_order):  # stands in for oe_fit._reweighted: one new noise model per call
        made.append((errs, ar, ar_order))
        return [[np.array([float(len(made))])]], np.ones((1, 3)), np.ones((1, 3))

    monkeypatch.setattr(bc.oe_fit, "_reweighted", estimate)  # restored after the test, with frozen_noise's wrapper
    kept = bc.frozen_noise()
    n = bc.FROZEN_STAGES
    first = [bc.oe_fit._reweighted([np.full((4, 3), k)], None, 2) for k in range(n)]
    later = [bc.oe_fit._reweighted([np.full((4, 3), 100 + k)], None, 2) for k in range(3 * n)]
    assert len(made) == n and kept == first  # only the first fit's stages were estimated
    assert all(later[k] is first[k % n] for k in range(3 * n))


def _sensor_datasets(monkeypatch, k: int | None) -> dict[str, dict[str, np.ndarray]]:
    """One short ``base`` run without its sea; ``k``: realization ``k``'s fresh sensor noise (``repeat
    --fresh-sensor``), ``None``: the run's own draw (plain ``repeat``)."""
    for name in ("_narrowband", "_jonswap", "_measure"):  # the wrappers installed below are undone after the test
        monkeypatch.setattr(bt, name, getattr(bt, name))
    bc.fresh_sea(0.0, [5, 0])
    if k is not None:
        bc.fresh_sensor([5, k])
    return bt.simulate_runs("base", 1, bt.variant_seed(2015, "base"), length=0.05)[1]


def test_fresh_sensor_draws_each_realizations_own_noise(monkeypatch):
    """Without the sea the recordings differ only by the sensor's noise: the run's own draw is the same on every
    realization, so only ``--fresh-sensor`` makes two realizations differ (gyro, accelerometer and AHRS roll angle),
    and one realization's draw is reproducible."""
    own, own_again = _sensor_datasets(monkeypatch, None), _sensor_datasets(monkeypatch, None)
    first, second, first_again = (_sensor_datasets(monkeypatch, k) for k in (0, 1, 0))
    for name in bt.DATASETS:
        for c in ("p", "a_s", "r", "phi"):
            assert np.array_equal(own[name][c], own_again[name][c]), (name, c)
            assert np.array_equal(first[name][c], first_again[name][c]), (name, c)
            assert not np.array_equal(first[name][c], second[name][c]), (name, c)
            assert not np.array_equal(first[name][c], own[name][c]), (name, c)
        # the sensor's noise only: the commanded rudder of the run is untouched
        assert np.allclose(first[name]["delta"], own[name]["delta"], atol=np.deg2rad(0.3)), name
