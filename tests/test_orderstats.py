"""primitives/orderstats.py: numpy's median and linear quantile to the bit, without importing numpy.ma."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from primitives.orderstats import median, quantile

ROOT = Path(__file__).resolve().parents[1]


def _same(got, want) -> None:
    assert type(got) is type(want), (type(got), type(want))
    assert np.asarray(got).dtype == np.asarray(want).dtype and np.asarray(got).tobytes() == np.asarray(want).tobytes()


def _cases(dtype):
    rng = np.random.default_rng(3)
    out = [rng.standard_normal(n).astype(dtype) for n in (1, 2, 3, 4, 5, 10, 101, 400, 5000)]
    out += [np.array(v, dtype) for v in ([0.0, -0.0], [-0.0, 0.0, -0.0, 0.0], [1.0, 1.0, 2.0, 2.0], [np.inf, -np.inf, 1.0])]
    out += [np.array(v, dtype) for v in ([np.inf, 1.0], [-np.inf, np.inf], [1.0, np.nan, 2.0], [np.nan], [np.inf, np.inf])]
    out += [rng.standard_normal((40, 3)).astype(dtype)[::3, 1], np.round(rng.standard_normal(50), 1).astype(dtype)]
    return out


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_median_is_numpys_to_the_bit(dtype):
    for x in [*_cases(dtype), np.random.default_rng(4).standard_normal((7, 6)).astype(dtype)]:
        _same(median(x), np.median(x))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_quantile_is_numpys_to_the_bit(dtype):
    """Levels at, between and near the order statistics (the thresholds' bisection's), Python and numpy floats,
    whole arrays and (runs, k) columns with a NaN in one column."""
    rng = np.random.default_rng(5)
    levels = [0.0, 1.0, 0.5, 0.98, 0.975, 1 - 0.02, 0.25, 1 / 3, *rng.uniform(0.9, 1.0, 40), *rng.uniform(0, 1, 20)]
    cols = rng.standard_normal((400, 3)).astype(dtype)
    cols[7, 1] = np.nan
    tied = np.round(rng.standard_normal((64, 2)), 1).astype(dtype)
    for q in levels:
        for x in _cases(dtype):
            _same(quantile(x, float(q)), np.quantile(x, float(q)))
            _same(quantile(x, np.float64(q)), np.quantile(x, np.float64(q)))
        for x in (cols, tied, np.asfortranarray(cols)):
            _same(quantile(x, float(q), axis=0), np.quantile(x, float(q), axis=0))
            _same(quantile(x, np.float64(q), axis=0), np.quantile(x, np.float64(q), axis=0))
        _same(quantile(cols.T, float(q), axis=1), np.quantile(cols.T, float(q), axis=1))


def test_other_inputs_are_numpys_own_call():
    _same(median(np.array(2.5)), np.median(np.array(2.5)))
    _same(median(np.array([3, 1, 2])), np.median(np.array([3, 1, 2])))
    _same(quantile(np.array([3, 1, 2]), 0.5), np.quantile(np.array([3, 1, 2]), 0.5))
    _same(quantile(np.arange(5.0), 1), np.quantile(np.arange(5.0), 1))
    assert np.array_equal(quantile(np.arange(5.0), [0.1, 0.9]), np.quantile(np.arange(5.0), [0.1, 0.9]))
    with pytest.raises(ValueError):
        quantile(np.arange(5.0), 1.5)
    with pytest.warns(RuntimeWarning):
        assert np.isnan(median(np.array([])))


def test_an_older_numpy_gets_its_own_call(monkeypatch):
    """Under a numpy older than the steps followed (orderstats.FOLLOWS_NUMPY false: numpy 2.2's ufuncs have no
    ``out=...``), every call is numpy's own, not a TypeError."""
    import primitives.orderstats as orderstats

    calls = []
    monkeypatch.setattr(orderstats, "FOLLOWS_NUMPY", False)
    monkeypatch.setattr(orderstats.np, "quantile", lambda *a, **k: calls.append("quantile") or np.float64(7.0))
    monkeypatch.setattr(orderstats.np, "median", lambda *a, **k: calls.append("median") or np.float64(8.0))
    x = np.arange(50.0).reshape(25, 2)
    assert quantile(x, 0.9, axis=0) == 7.0 and median(x) == 8.0
    assert calls == ["quantile", "median"]


def test_a_detect_run_does_not_import_numpy_ma(tmp_path):
    """Loading a recording and the thresholds' quantiles no longer import numpy.ma (15-22 ms of a detect process):
    a ``shiptrial detect`` process on a recording has not imported it when it ends."""
    from diagnose.recording import write_csv
    from identify.detect.api import fit_prior, save_prior, simulated_recording
    from identify.detect.vessel import Vessel

    rec, prior = tmp_path / "r.csv", tmp_path / "prior.json"
    write_csv(simulated_recording(Vessel(), 150, seed=1, measured_moment=True), rec)
    save_prior(fit_prior([rec], "full", bootstrap=8), prior)
    code = (
        "import sys\n"
        "from cli.app import _run\n"
        f"_run(['detect', {str(rec)!r}, '--prior', {str(prior)!r}, '--profile', 'naval-vessel'])\n"
        "print('numpy.ma' in sys.modules)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # this tree's code, not an installed copy
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split()[-1:] == ["False"], out.stdout
