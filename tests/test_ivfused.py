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
from expdesign.ivsolve import TILE
from primitives import jitloop
from primitives.library import model_ship_thesis
from primitives.ship import load_profile

DESIGNS = {"optimized": {"tau1": 0.2, "tau6": 0.3, "tau8": 0.23, "tau11": 0.27}, "random": "random"}

pytestmark = pytest.mark.skipif(not jitloop.AVAILABLE, reason="the fused pass needs numba")


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    return p, model_ship_thesis(p)


def _digests(ship, monkeypatch, fused: bool, runs: int = 12, **kw) -> dict[str, str]:
    p, lib = ship
    real = mc._fused
    calls = []

    def chosen(sh):
        calls.append(real(sh))
        return fused and calls[-1]

    monkeypatch.setattr(mc, "_fused", chosen)
    res = mc.evaluate_designs(p, DESIGNS, runs=runs, seed=3, n_samples=300, primitives=lib, **kw)
    monkeypatch.setattr(mc, "_fused", real)
    assert all(calls), "the model ship's Monte Carlo must take the fused pass when numba is loaded"
    out = {k: r.digest() for k, r in res.items()}
    out |= {f"{k} reference": r.reference.digest() for k, r in res.items() if r.reference is not None}
    return out


@pytest.mark.parametrize(
    "kw",
    [
        dict(estimator="iv"),
        dict(estimator="iv", mean_subtraction="none"),
        dict(estimator="oe"),
        dict(estimator="iv", runs=TILE + 9),  # a full tile of runs stepped together and a partial one
    ],
    ids=str,
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


def test_fused_pass_gives_the_unfused_bits_on_a_thruster_ship_with_wind_terms(monkeypatch):
    """The full-scale profile: azimuth thrusters, air-relative terms in the true model and a
    predictor of another structure (the instruments from the model first, then from the predictor)."""
    p = load_profile("full-scale")
    jitloop.use(jitloop.MIN_WORK)
    sh = mc.prepare(p, {"random": "random"}, mc.MCConfig(runs=4, seed=3, n_samples=300, estimator="iv"))
    real = mc._fused
    assert real(sh)
    out = []
    for fused in (True, False):
        monkeypatch.setattr(mc, "_fused", lambda sh, fused=fused: fused and real(sh))
        out.append(mc.run_chunk(sh, "random", range(4)).digest())
    assert out[0] == out[1]


def test_models_the_fused_pass_cannot_hold_take_the_unfused_path(ship):
    """Every model or protocol outside the pass (pods, roll, rigid body, a heading term, a power
    outside primitives.powers.PRODUCT_POWERS, the mean removed per block, piecewise experiments) is refused: the pass
    would give a silently wrong estimate."""
    import dataclasses

    from primitives.terms import TermSet

    p, lib = ship
    jitloop.use(jitloop.MIN_WORK)

    def shared(profile=p, predictor=None, **cfg):
        sh = mc.prepare(p, {"optimized": DESIGNS["optimized"]}, mc.MCConfig(runs=2, n_samples=200, **cfg), lib)
        return dataclasses.replace(sh, profile=profile, predictor=predictor or sh.predictor)

    assert mc._fused(shared())  # the model ship itself is held
    assert not mc._fused(shared(mean_subtraction="batchwise"))
    assert not mc._fused(shared(protocol="piecewise"))
    naval = load_profile("naval-vessel")  # surge-sway-yaw-roll, two pods, rigid-body matrices
    assert not mc._fused(shared(profile=naval))
    assert not mc._fused(shared(profile=dataclasses.replace(p, pods=naval.pods)))
    assert not mc._fused(shared(profile=dataclasses.replace(p, rigid_body=naval.rigid_body)))
    terms = [list(d) for d in p.predictor.terms]
    for extra in ("v_r*psi", "u_r^5", "|v_r|^5", "phi"):  # (stop 44: integer powers as products; ^3 is held now)
        more = [d + ([extra] if i == 1 else []) for i, d in enumerate(terms)]
        assert not mc._fused(shared(predictor=TermSet(more))), extra
        model = dataclasses.replace(p, model_terms=tuple(tuple(d) for d in more))
        assert not mc._fused(shared(profile=model)), extra
    roll = TermSet([*terms, ["v_r"]])  # a fourth (roll) list on a planar ship: the pass sums three DOFs
    assert not mc._fused(shared(predictor=roll))
    assert not mc._fused(shared(profile=dataclasses.replace(p, model_terms=roll.terms)))


def test_fused_pass_gives_each_run_its_own_numbers_across_tiles(ship):
    """Runs stepped together in tiles (ivsolve.TILE, the last one partial, a subset in any order)
    get the moments and sanity each gets alone."""
    from expdesign.ivsolve import instrument_moments

    p, _ = ship
    jitloop.use(jitloop.MIN_WORK)
    rng = np.random.default_rng(4)
    b, n = 2 * TILE + 7, 120
    inputs = rng.normal(size=(b, n, len(p.inputs)))
    y = rng.normal(size=(b, n + 1, 3)) * 0.1
    runs = rng.permutation(b)[: b - 3]
    coef = p.params(p.instrument_set)[:, None] * (1.0 + 0.01 * rng.normal(size=(1, len(runs))))
    (a, rhs, norms), sane = instrument_moments(p, p.predictor, p.predictor, inputs, np.zeros((b, 3)), coef, runs, y, "complete")
    for j, r in enumerate(runs):
        (a1, rhs1, norms1), sane1 = instrument_moments(
            p, p.predictor, p.predictor, inputs, np.zeros((b, 3)), coef[:, j : j + 1], np.array([r]), y, "complete"
        )
        assert np.array_equal(a[j], a1[0]) and np.array_equal(rhs[j], rhs1[0])
        assert np.array_equal(norms[:, j], norms1[:, 0]) and sane[j] == sane1[0]
