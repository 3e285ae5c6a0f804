"""The robust design's fast paths (issue 28's performance line) against the builds they replace:
the information at every draw summed in one compiled pass (primitives.regkernel.block_moments,
never storing Phi) against mean Phi Phi^T from Phi, in every mean-subtraction mode; the draws' own
D-optimal mixes by the multiplicative algorithm on flattened matrices against the einsum form;
and the robust designs of both paths, which must agree to the tolerances stated here."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import expdesign.robust as robust
from expdesign.dopt import Constraints
from expdesign.prior import spread_prior
from primitives import jitloop, regkernel
from primitives.library import design_dictionary
from primitives.regressors import predictor_regressors, regressor_signals
from primitives.ship import load_profile
from primitives.simulate import simulate

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _draw_states(name: str, n_draws: int = 12, n_prims: int = 3):
    profile = load_profile(name)
    lib = [x for x in design_dictionary(profile) if x.kind == "informative"][:n_prims]
    prior = spread_prior(profile, 0.3, n_draws, seed=5)
    thetas = np.vstack([prior.centre[None], prior.draws])
    out = []
    for prim in lib:
        res = simulate(profile, prim.inputs, thetas, nu0=np.tile(prim.nu0, (len(thetas), 1)), batch=len(thetas), positions=True)
        out.append((res.nu, np.broadcast_to(prim.inputs, (len(thetas),) + prim.inputs.shape), res.eta[..., 2]))
    return profile, out


@needs_numba
@pytest.mark.parametrize("name", ["model-ship", "kvlcc2", "full-scale"])
@pytest.mark.parametrize("mode", ["batchwise", "none", "complete"])
def test_fused_moments_match_the_moments_of_phi(monkeypatch, name, mode):
    assert jitloop.use(jitloop.MIN_WORK)
    profile, runs = _draw_states(name)
    blocks = [profile.predictor.dof_slice(i) for i in range(profile.predictor.n_dof)]
    calls = []
    monkeypatch.setattr(regkernel, "_moments", lambda *a, f=regkernel._moments: calls.append(1) or f(*a))
    for nu, inputs, psi in runs:
        fused = robust._draw_moments(profile, nu, inputs, psi, blocks, mode)
        ref = robust._moment_matrices(predictor_regressors(profile, nu, inputs, psi)[0], blocks, mode)
        assert np.array_equal(fused, np.swapaxes(fused, 1, 2))  # exactly symmetric, as the reference
        assert np.array_equal(fused == 0.0, ref == 0.0)  # zero between the DOF blocks, as the reference
        # against the size of the terms before the mean is subtracted: a column that is constant over a
        # run (a fixed thrust) leaves only rounding after subtraction, in both builds
        raw = robust._moment_matrices(predictor_regressors(profile, nu, inputs, psi)[0], blocks, "none")
        scale = np.sqrt(np.einsum("bii->bi", raw))
        rel = np.abs(fused - ref) / np.maximum(scale[:, :, None] * scale[:, None, :], 1e-300)
        assert rel.max() < 1e-12  # the order of the sums only
    assert len(calls) == len(runs)  # the compiled pass ran, not the fallback


def test_fused_moments_fall_back_without_the_compiler(monkeypatch):
    profile, runs = _draw_states("model-ship", n_draws=4, n_prims=1)
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    nu, inputs, psi = runs[0]
    sig, shape = regressor_signals(profile, nu, inputs, psi)
    blocks = [profile.predictor.dof_slice(i) for i in range(3)]
    assert regkernel.block_moments(profile.predictor, sig, shape, blocks) is None
    ref = robust._moment_matrices(predictor_regressors(profile, nu, inputs, psi)[0], blocks, "batchwise")
    assert np.array_equal(robust._draw_moments(profile, nu, inputs, psi, blocks, "batchwise"), ref)


@needs_numba
def test_fused_moments_fall_back_for_a_term_set_the_pass_does_not_build(monkeypatch):
    """A power pow() forms (v_r^5; stop 44: integer powers as products, v_r^3 is built): the compiled pass is not
    used, the moments are those of Phi exactly."""
    assert jitloop.use(jitloop.MIN_WORK)
    profile, runs = _draw_states("model-ship", n_draws=4, n_prims=1)
    t = profile.predictor.terms
    profile = dataclasses.replace(profile, predictor_terms=(t[0], t[1] + ("v_r^5",), t[2]))
    nu, inputs, psi = runs[0]
    blocks = [profile.predictor.dof_slice(i) for i in range(3)]
    monkeypatch.setattr(regkernel, "_moments", lambda *a: pytest.fail("the compiled pass ran"))
    got = robust._draw_moments(profile, nu, inputs, psi, blocks, "batchwise")
    phi = predictor_regressors(profile, nu, inputs, psi)[0]
    assert phi.shape[-1] == got.shape[-1] == 11
    assert np.array_equal(got, robust._moment_matrices(phi, blocks, "batchwise"))


def _optima_einsum(m, tol, start):
    """The multiplicative algorithm as it was written before (einsum on the stacked matrices)."""
    k, q, p = m.shape[:3]
    w = np.tile(np.asarray(start, float) / np.sum(start), (k, 1))
    bound, active = np.zeros(k), np.arange(k)
    for _ in range(robust._MAX_MULTIPLICATIVE):
        ma, wa = m[active], w[active]
        g = np.einsum("kij,kqji->kq", np.linalg.inv(np.einsum("kq,kqij->kij", wa, ma)), ma)
        bound[active] = p / g.max(axis=1)
        left = bound[active] < 1.0 - tol
        wa = wa[left] * g[left] / p
        w[active[left]] = wa / wa.sum(axis=1, keepdims=True)
        active = active[left]
        if not active.size:
            break
    return w, float(bound.min())


def _kernel(monkeypatch, compiled: bool) -> None:
    """The compiled code loaded, or numba out of the picture (the numpy paths)."""
    if compiled:
        assert jitloop.use(jitloop.MIN_WORK)
    else:
        monkeypatch.setattr(jitloop, "AVAILABLE", False)


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=needs_numba)])
def test_draw_optima_are_the_einsum_algorithm(monkeypatch, compiled):
    """Both paths (numpy on flattened matrices; compiled draw by draw) take the einsum form's steps."""
    _kernel(monkeypatch, compiled)
    rng = np.random.default_rng(2)
    a = rng.normal(size=(30, 7, 9, 5))
    m = np.einsum("kqni,kqnj->kqij", a, a) / 9  # rank-5 matrices of 5 parameters: mixes are needed
    start = rng.uniform(0.5, 1.5, 7)
    calls = []
    monkeypatch.setattr(robust, "_optima_compiled", lambda *x, f=robust._optima_compiled: calls.append(1) or f(*x))
    w, bound = robust.draw_optima(m, 1e-4, start)
    assert calls == ([1] if compiled else [])
    w0, bound0 = _optima_einsum(m, 1e-4, start)
    assert bound >= 1 - 1e-4 and bound0 >= 1 - 1e-4 and abs(bound - bound0) < 1e-9
    ld = np.linalg.slogdet(np.einsum("kq,kqij->kij", w, m))[1]
    ld0 = np.linalg.slogdet(np.einsum("kq,kqij->kij", w0, m))[1]
    assert np.abs(w - w0).max() < 1e-9 and np.abs(ld - ld0).max() < 1e-9  # rounding of the products only


@needs_numba
@pytest.mark.parametrize("criterion", ["bayes-D", "maximin-D"])
def test_robust_designs_are_those_of_the_numpy_path(monkeypatch, criterion):
    profile = load_profile("model-ship")
    lib = [x for x in design_dictionary(profile) if x.kind == "informative"]
    prior = spread_prior(profile, 0.3, 40, seed=3)
    assert jitloop.use(jitloop.MIN_WORK)
    fast = robust.draw_information(profile, lib, prior, "batchwise")
    with monkeypatch.context() as m:  # the numpy paths: Phi stored, the optima by the batched algorithm
        m.setattr(robust, "block_moments", lambda *a: None)
        m.setattr(jitloop, "loaded", lambda: False)
        slow = robust.draw_information(profile, lib, prior, "batchwise")
    cons = Constraints.simplex(len(lib))
    a, b = robust.solve_robust(fast, criterion, cons), robust.solve_robust(slow, criterion, cons)
    assert np.abs(a.weights - b.weights).max() < 1e-4  # the same mix (SLSQP's stopping point moves by rounding)
    for info in (fast, slow):  # and the same criterion at both mixes
        assert abs(info.value(a.weights, criterion=criterion) - info.value(b.weights, criterion=criterion)) < 1e-6
    assert np.abs(fast.optimum - slow.optimum).max() < 2e-3  # each draw's optimum to its certificate, p x 1e-4 in log det


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=needs_numba)])
def test_draw_optima_of_a_singular_draw_raise_as_before(monkeypatch, compiled):
    """A draw whose mix is singular: the compiled path hands it to the numpy iterations, which raise."""
    _kernel(monkeypatch, compiled)
    m = np.tile(np.eye(3), (4, 2, 1, 1))
    m[2] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        robust.draw_optima(m)
