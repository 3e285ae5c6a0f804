"""The Monte Carlo's fused IV pass (expdesign.ivsolve.instrument_moments: regressors, instrument
simulation and moments in one compiled pass per run) gives the same bits as the unfused path
(stored Phi, Z from a batched simulation, expdesign.ivsolve.iv_estimates): every per-run array's
digest, with the instrument mean removed over the experiment and without mean removal, for a
fixed and a random design (whose runs include diverged ones), and the output-error refinement
started from them."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign import montecarlo as mc
from primitives import jitloop
from primitives.library import model_ship_thesis
from primitives.ship import load_profile

DESIGNS = {"optimized": {"tau1": 0.2, "tau6": 0.3, "tau8": 0.23, "tau11": 0.27}, "random": "random"}

pytestmark = pytest.mark.skipif(not jitloop.AVAILABLE, reason="the fused pass needs numba")


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    return p, model_ship_thesis(p)


def _digests(ship, monkeypatch, fused: bool, **kw) -> dict[str, str]:
    p, lib = ship
    real = mc._fused
    calls = []

    def chosen(sh):
        calls.append(real(sh))
        return fused and calls[-1]

    monkeypatch.setattr(mc, "_fused", chosen)
    res = mc.evaluate_designs(p, DESIGNS, runs=12, seed=3, n_samples=300, primitives=lib, **kw)
    monkeypatch.setattr(mc, "_fused", real)
    assert all(calls), "the model ship's Monte Carlo must take the fused pass when numba is loaded"
    out = {k: r.digest() for k, r in res.items()}
    out |= {f"{k} reference": r.reference.digest() for k, r in res.items() if r.reference is not None}
    return out


@pytest.mark.parametrize(
    "kw", [dict(estimator="iv"), dict(estimator="iv", mean_subtraction="none"), dict(estimator="oe")], ids=str
)
def test_fused_pass_gives_the_unfused_bits(ship, monkeypatch, kw):
    jitloop.use(jitloop.MIN_WORK)
    assert _digests(ship, monkeypatch, True, **kw) == _digests(ship, monkeypatch, False, **kw)


def test_fused_pass_flags_an_exploding_instrument_simulation(ship):
    """A run whose estimate makes the instrument simulation explode is not sane (its previous
    instruments are kept), as the unfused path's check on Z says."""
    from expdesign.ivsolve import instrument_moments

    p, _ = ship
    jitloop.use(jitloop.MIN_WORK)
    rng = np.random.default_rng(0)
    n = 200
    inputs = rng.normal(size=(2, n, len(p.inputs)))
    y = rng.normal(size=(2, n + 1, 3)) * 0.1
    coef = np.stack([p.params(p.instrument_set), -50.0 * np.abs(p.params(p.instrument_set))], axis=1)
    out = instrument_moments(p, p.predictor, p.predictor, inputs, np.zeros((2, 3)), coef, np.arange(2), y, "complete")
    assert out is not None
    assert out[1].tolist() == [True, False]


def test_local_pool_compiles_once_in_the_parent(ship, monkeypatch):
    """A local pool's workers get the compiled passes from the parent (warmed once before the pool
    starts), not by each loading numba and compiling or loading the same code; inline runs warm
    nothing."""
    from expdesign import mc_parallel
    from expdesign.parallel import Engine, LocalEngine

    p, lib = ship
    warmed = []
    monkeypatch.setattr(mc_parallel, "warm_compiled", lambda sh: warmed.append(sh.config.runs) or mc.warm_compiled(sh))
    kw = dict(runs=4, seed=3, n_samples=200, primitives=lib, progress=False)
    mc_parallel.evaluate_designs_parallel(p, DESIGNS, scheduler=Engine(), **kw)
    assert warmed == []
    ev = mc_parallel.evaluate_designs_parallel(p, DESIGNS, scheduler=LocalEngine(2), **kw)
    assert warmed == [4] and ev.complete
