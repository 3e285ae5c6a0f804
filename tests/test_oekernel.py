"""The Monte Carlo's compiled passes against the numpy path they replace: the output-error
estimator's Gauss-Newton moments (expdesign.oekernel, sums in another order: H and g within 1e-9
relative), its simulations and mean squares (the same bits), and whole Monte Carlo runs with numba blocked in a subprocess (the numpy path chosen
automatically): the IV estimates identical, the output-error estimates within 1e-3 relative (the
documented tolerance: discrete stop and step decisions of the iteration near its tolerance amplify
the rounding; 2,000 x 2 runs measured at most 6.1e-4, median 1e-7)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from expdesign import oerefine as es
from expdesign.ivsolve import iv_solve
from expdesign.montecarlo import evaluate_designs
from primitives import jitloop
from primitives.library import model_ship_thesis, thesis_primitives
from primitives.regressors import predictor_regressors
from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate
from primitives.terms import TermSet

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")
DESIGNS = {"optimized": {"tau1": 0.2, "tau6": 0.3, "tau8": 0.23, "tau11": 0.27}, "random": "random"}
KW = dict(runs=6, seed=5, n_samples=400)


# Terms beyond the model ship's: the speed U and its inverse, a cube, modulus, stations forward and
# aft, the rudder and propeller inputs (kvlcc2): every branch of the compiled factor code.
EXOTIC = (
    ("u_r*|u_r|", "n^2", "v_r*r", "u*U^-1"),
    ("u_r*v_r", "u_r*r", "v_r*|v_r@-30|", "delta*u_r^2", "delta*n^2", "v_r^3*U^-1"),
    ("u_r*r", "u_r*v_r", "r*|r|", "delta*u_r^2", "delta*n^2", "u_r*|v_r@40|"),
)


def _oe_case(ship: str, exotic: bool):
    """Six runs of three of the ship's informative primitives with measurement noise, and start
    estimates: the model ship's parameters 5 % off, or the exotic terms' least-squares fit on the
    noise-free runs 0.2 % off."""
    p = load_profile(ship)
    prims = [q for q in (model_ship_thesis(p) if ship == "model-ship" else thesis_primitives(p)) if q.kind == "informative"][:3]
    inputs = np.stack([np.resize(q.inputs, (300, q.inputs.shape[1])) for q in prims * 2])  # 6 runs
    nu0 = np.stack([q.nu0 for q in prims * 2])
    rng = np.random.default_rng(1)
    if exotic:
        terms = TermSet(EXOTIC)
        clean = simulate(p, inputs, nu0=nu0, batch=6)
        phi, tgt = predictor_regressors(p, clean.nu, inputs, clean.eta[..., 2], terms=terms)
        theta = iv_solve(terms, phi, phi, tgt, "none")[0] * (1.0 + rng.normal(0.0, 0.002, (6, terms.n_params)))
        std = tuple(0.01 * np.abs(nu0).max(axis=0) + 1e-4)
    else:
        terms, std = p.predictor, (0.02, 0.01, 0.005)
        theta = p.params(p.simulation_set) * (1.0 + rng.normal(0.0, 0.05, (6, terms.n_params)))
    y = simulate(p, inputs, nu0=nu0, disturbances=Disturbances(measurement_std=std), batch=6, seed=2).y
    return p, terms, [es.OEData(inputs, nu0, y)], theta


@needs_numba
@pytest.mark.parametrize("ship, exotic", [("model-ship", False), ("kvlcc2", True)], ids=["model-ship", "kvlcc2-exotic"])
def test_fused_moments_match_the_numpy_moments(ship, exotic):
    p, terms, data, theta = _oe_case(ship, exotic)
    assert jitloop.use(jitloop.MIN_WORK)
    compiled, numpy_path = es._Sims(p, terms, data), es._Sims(p, terms, data, compiled=False)
    assert compiled.calm is not None  # the compiled passes run
    ok, w, _, sims = es._start(compiled, theta, 300)
    _, _, _, ref_sims = es._start(numpy_path, theta, 300)
    assert ok.all()
    idx = np.arange(6)
    fused = compiled.moments(sims, theta, idx, w)
    ref = numpy_path.moments(ref_sims, theta, idx, w)
    assert np.allclose(fused[0], ref[0], rtol=1e-9, atol=0.0)
    scale = np.abs(ref[1]).max(axis=1, keepdims=True)
    assert (np.abs(fused[1] - ref[1]) <= 1e-9 * scale).all()


@needs_numba
@pytest.mark.parametrize("ship, exotic", [("model-ship", False), ("kvlcc2", True)], ids=["model-ship", "kvlcc2-exotic"])
def test_compiled_simulations_and_mean_squares_are_the_numpy_paths_bits(ship, exotic):
    """The output-error path's time-major simulations and mean squares (one diverging run among
    them) against simulate() and the numpy sums: the same bits."""
    p, terms, data, theta = _oe_case(ship, exotic)
    assert jitloop.use(jitloop.MIN_WORK)
    compiled, numpy_path = es._Sims(p, terms, data), es._Sims(p, terms, data, compiled=False)
    theta = theta.copy()
    theta[3] *= 1e3  # explodes
    idx = np.array([0, 2, 3, 5])
    (sims, ms), (ref, ref_ms) = compiled.simulate(theta, idx), numpy_path.simulate(theta, idx)
    with np.errstate(invalid="ignore"):
        assert np.array_equal(sims[0].transpose(2, 0, 1), ref[0][0], equal_nan=True)
    assert np.isinf(ms[2]).all() and np.isfinite(ms[[0, 1, 3]]).all()
    assert np.array_equal(ms, ref_ms)


@needs_numba
def test_a_roll_term_list_on_a_planar_ship_takes_the_numpy_path():
    """The compiled calm loop and moments' pass step three DOFs: a fourth (roll) list is the numpy
    path's, never written past the loop's three-DOF arrays."""
    from expdesign import oekernel

    p, terms, data, _ = _oe_case("model-ship", False)
    assert jitloop.use(jitloop.MIN_WORK)
    assert oekernel.calm_runs(p, terms, data) is not None
    assert oekernel.calm_runs(p, TermSet((*terms.terms, ("v_r",))), data) is None


@needs_numba
def test_the_moments_pass_re_evaluates_exactly_the_terms_a_perturbed_state_moves():
    """The moments' pass takes a term that reads no signal of the perturbed state from its value
    at nu(k) (expdesign.oekernel._reads_state): a term reading u_r, U or a station (which reads r)
    must be re-evaluated for that state, a term of the inputs alone for none."""
    from expdesign import oekernel

    p, terms, data, _ = _oe_case("kvlcc2", True)
    assert jitloop.use(jitloop.MIN_WORK)
    cr = oekernel.calm_runs(p, terms, data)
    names = [name for dof in EXOTIC for name in dof]
    reads = {n: tuple(bool(x) for x in col) for n, col in zip(names, oekernel._reads_state(cr.prog[0], terms.n_params).T)}
    assert reads["n^2"] == reads["delta*n^2"] == (False, False, False)
    assert reads["u*U^-1"] == (True, True, False)  # U moves with u and v
    assert reads["v_r*|v_r@-30|"] == (False, True, True)  # the station reads r
    assert reads["u_r*|v_r@40|"] == (True, True, True)
    assert reads["r*|r|"] == (False, False, True)
    assert reads["delta*u_r^2"] == (True, False, False)


@needs_numba
@pytest.mark.parametrize("ship, exotic", [("model-ship", False), ("kvlcc2", True)], ids=["model-ship", "kvlcc2-exotic"])
def test_reusing_the_terms_a_perturbation_leaves_alone_keeps_the_moments_bits(ship, exotic):
    """The moments with the terms that read no perturbed state taken from their value at nu(k) are
    the moments with every term re-evaluated at every perturbed state (the pass before the reuse),
    to the bit: a term put in the wrong class would move its Jacobian column."""
    import dataclasses

    p, terms, data, theta = _oe_case(ship, exotic)
    assert jitloop.use(jitloop.MIN_WORK)
    sims = es._Sims(p, terms, data)
    ok, w, _, out = es._start(sims, theta, 300)
    assert ok.all() and not all(r.all() for r in sims.calm.reads)  # some term is reused
    idx = np.arange(6)
    reused = sims.moments(out, theta, idx, w)
    sims.calm = dataclasses.replace(sims.calm, reads=[np.ones_like(r) for r in sims.calm.reads])
    every = sims.moments(out, theta, idx, w)
    assert np.array_equal(reused[0], every[0]) and np.array_equal(reused[1], every[1])


def _numpy_path_estimates() -> dict:
    """The same Monte Carlo in a process where numba cannot be imported."""
    code = (
        "import sys, json; sys.modules['numba'] = None\n"
        "from primitives import jitloop; from primitives.ship import load_profile\n"
        "from primitives.library import model_ship_thesis; from expdesign.montecarlo import evaluate_designs\n"
        f"p = load_profile('model-ship'); res = evaluate_designs(p, {DESIGNS!r}, primitives=model_ship_thesis(p), **{KW!r})\n"
        "out = {k: [r.theta.tolist(), r.reference.theta.tolist()] for k, r in res.items()}\n"
        "print(json.dumps([jitloop.kernel_name(), 'numba' in sys.modules and sys.modules['numba'] is not None, out]))"
    )
    root = Path(__file__).resolve().parent.parent
    env = {k: v for k, v in os.environ.items() if k != "SHIPTRIAL_KERNEL"} | {"PYTHONPATH": str(root)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_monte_carlo_without_numba_matches_the_compiled_path():
    kernel, loaded, numpy_res = _numpy_path_estimates()
    assert kernel == "numpy" and not loaded
    p = load_profile("model-ship")
    res = evaluate_designs(p, DESIGNS, primitives=model_ship_thesis(p), **KW)
    for name, r in res.items():
        oe, iv = (np.array(a) for a in numpy_res[name])
        assert np.array_equal(r.reference.theta, iv, equal_nan=True)  # the IV estimates: same bits
        assert np.isfinite(oe).all() and np.isfinite(r.theta).all()
        assert np.max(np.abs(r.theta - oe) / np.abs(oe)) < 1e-3


@needs_numba
def test_compiled_validation_gives_the_numpy_paths_rmse_and_divergence(monkeypatch):
    """The Monte Carlo's validation, compiled (outputs scored and checked against the bound as they
    are made) and numpy, give the same RMSE bits and diverged flags: a run whose largest output is
    the bound itself is kept (|x| <= bound), one a double above it diverged, a NaN parameter or an
    exploding simulation (inf, NaN outputs) diverged."""
    import dataclasses

    from expdesign import mc_validation, oekernel
    from expdesign.montecarlo import MCConfig, prepare

    p = load_profile("model-ship")
    sh = prepare(p, {"opt": DESIGNS["optimized"]}, MCConfig(runs=2, n_samples=200), model_ship_thesis(p))
    jitloop.use(jitloop.MIN_WORK)
    t0 = sh.theta0
    theta = np.stack([t0, t0 * 1.05, t0 * -3.0, np.where(np.arange(len(t0)) == 0, np.nan, t0), t0 * 1e200])
    top = np.abs(simulate(p, sh.val_inputs, theta[1:2], terms=sh.predictor, nu0=sh.val_nu0, batch=1, positions=False).nu).max()
    assert top > np.abs(sh.val_true).max()
    monkeypatch.setattr(mc_validation, "EXPLODE", 1.0)  # the bound is the true output's largest magnitude
    calm_runs = oekernel.calm_runs
    for largest, kept in ((top, True), (np.nextafter(top, 0.0), False)):
        val_true = sh.val_true.copy()
        val_true[-1, 0] = largest  # above every other true output: the bound, to the bit
        case = dataclasses.replace(sh, val_true=val_true)
        monkeypatch.setattr(oekernel, "calm_runs", calm_runs)
        rmse, diverged = mc_validation.validate(case, theta)
        monkeypatch.setattr(oekernel, "calm_runs", lambda *a: None)
        ref_rmse, ref_diverged = mc_validation.validate(case, theta)
        assert np.array_equal(diverged, ref_diverged) and np.array_equal(rmse, ref_rmse)
        assert diverged.tolist() == [False, not kept, True, True, True]


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_inputs_shared_by_every_run_give_the_stacked_inputs_bits(compiled):
    """A fixed design gives every run the same inputs (expdesign.mc_data._batch_inputs: one
    (1, N, m) array for the batch): the output-error fit on them is the fit on the (B, N, m) stack,
    bit for bit, on the compiled path and on the numpy path (OEData.inputs_of broadcasts them)."""
    p = load_profile("model-ship")
    q = next(q for q in model_ship_thesis(p) if q.kind == "informative")
    one = np.resize(q.inputs, (300, q.inputs.shape[1]))[None]
    nu0 = np.tile(np.asarray(q.nu0, float), (5, 1))
    y = simulate(p, one, nu0=nu0, disturbances=Disturbances(measurement_std=(0.02, 0.01, 0.005)), batch=5, seed=4).y
    theta = p.params(p.simulation_set) * (1.0 + np.random.default_rng(2).normal(0.0, 0.05, (5, p.predictor.n_params)))
    data = [es.OEData(one, nu0, y)], [es.OEData(np.repeat(one, 5, axis=0), nu0, y)]
    assert data[0][0].inputs_of(np.array([3, 1])).shape == (2, 300, one.shape[2])
    if not compiled:  # the numpy path: no compiled simulations or moments
        fits = []
        for d in data:
            sims = es._Sims(p, p.predictor, d, compiled=False)
            _, w, _, cur = es._start(sims, theta.copy(), 300)
            idx = np.arange(5)
            fits.append(sims.moments(cur, theta, idx, w))
        for a, b in zip(*fits):
            assert np.array_equal(a, b)
        return
    if not jitloop.use(jitloop.MIN_WORK):  # loads the compiled code: this small fit alone would not
        pytest.skip("numba not installed or SHIPTRIAL_KERNEL=numpy")
    assert all(es._Sims(p, p.predictor, d).calm is not None for d in data)  # the compiled passes run
    shared, stacked = (es.output_error(p, d, theta.copy(), max_iter=4) for d in data)
    assert np.isfinite(shared.theta).all() and (shared.iterations > 0).all()
    assert np.array_equal(shared.theta, stacked.theta) and np.array_equal(shared.cost, stacked.cost)
