"""Forward sensitivities of the open-loop simulation (primitives.jitsens, diagnose.sensitivity):
every column against central differences of the simulation itself (issue 26: the --fit-on
baseline's Jacobian and covariance without one simulated member per parameter)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from diagnose.baseline import _extended, _grams
from diagnose.candidates import build_library
from diagnose.heldout import grams, make_parts
from diagnose.model import AugmentedModel, jacobian, prepare, residuals
from diagnose.recording import read_marin_dat
from diagnose.sensitivity import applies
from primitives import jitloop, jitsens
from primitives.ship import load_profile
from primitives.simulate import VelocityStep
from primitives.terms import TermSet

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"
needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")

# every kind of factor the kernel differentiates: stations, moduli, squares, cubes, U^-1, the
# air-relative velocities and the wind-excess signals, an input inside a state term
TERMS = (
    ("u_r", "v_r*r", "u_q*|u_q|", "wx", "delta*u_r"),
    ("v_r", "r", "|v_r@-2.5|*v_r", "v_r^3*U^-1", "wy", "delta"),
    ("r", "v_r", "r^3*U^-1", "wn", "u_r*r", "delta*U"),
)
THETA = np.array(
    [-0.02, 0.3, -0.004, 0.002, -0.001, -0.05, -0.4, -0.03, -0.02, 0.003, 0.02, -0.08, -0.01, -0.05, 0.004, 0.01, 0.02]
)


@needs_numba
def test_kernel_matches_central_differences():
    n = 400
    rng = np.random.default_rng(5)
    t = np.arange(n) * 0.5
    delta = 0.3 * np.sin(0.05 * t) + 0.02 * rng.standard_normal(n)
    wind = np.stack([3.0 + np.sin(0.03 * t), 2.0 * np.cos(0.02 * t)], axis=1)  # body axes (N, 2)
    nu0 = np.array([1.2, 0.05, -0.01])
    tset = TermSet(TERMS)
    p = len(THETA)
    # the members: theta and nu(0), then each parameter moved by +-h (central differences)
    h = np.concatenate([1e-5 * np.maximum(np.abs(THETA), 1e-3), np.full(3, 1e-6)])
    base = np.concatenate([THETA, nu0])
    members = [base]
    for j in range(p + 3):
        for s in (1.0, -1.0):
            m = base.copy()
            m[j] += s * h[j]
            members.append(m)
    M = np.array(members)
    B = len(M)
    jitloop.use(jitloop.MIN_WORK)
    out = jitloop.open_loop(
        VelocityStep(tset, M[:, :p]),
        ["delta"],
        {"delta": np.broadcast_to(delta[:, None], (n, 1))},
        M[:, p:],
        None,
        (np.broadcast_to(wind[:, :1], (n, B)), np.broadcast_to(wind[:, 1:], (n, B))),
        None,
    )
    assert out is not None
    central = (out[1::2] - out[2::2]) / (2 * h[:, None, None])  # (p+3, N+1, 3)
    prog = jitloop.program(tset, ["delta"], jitloop.CALM_STATE)
    s0 = np.zeros((3, p + 3))
    s0[:, p:] = np.eye(3)
    S = jitsens.state_sensitivities(
        out[0], delta[:, None], wind, THETA, prog, np.arange(p), np.zeros((n, 0)), np.zeros(0, int), np.zeros(0, int), s0
    )
    assert S.shape == (n + 1, 3, p + 3)
    for j in range(p + 3):
        ref = central[j]
        err = np.linalg.norm(S[:, :, j] - ref) / np.linalg.norm(ref)
        assert err < 1e-6, (j, err)


def _marin(name: str):
    return read_marin_dat(DATA / f"MARIN_FREE_KVLCC2_{name}_m.dat")


@needs_numba
def test_baseline_jacobian_matches_central_differences():
    prof = load_profile("kvlcc2")
    recs = [_marin("zz_20").window(0, 500), _marin("tc_35").window(0, 400)]
    ext, theta, added = _extended(prof, prof.params(), declared=True)
    assert added  # the declared structure: stations, U^-1, cubes
    rng = np.random.default_rng(2)
    theta = theta + np.where(theta == 0.0, 1e-4 * rng.standard_normal(len(theta)), 0.0)  # every declared term switched on
    model = AugmentedModel(ext, theta, [], n_rec=2)
    preps = [prepare(ext, r, i) for i, r in enumerate(recs)]
    P = model.p0()
    P[model.x0_params()] = 1e-3
    free = list(range(model.n_base)) + model.x0_params()
    w = 1.0 / np.array([0.01, 0.01, 0.001])
    assert applies(model, P, free)
    r0, J = jacobian(model, preps, P, free, w, analytic=True)
    r_fd, _J = jacobian(model, preps, P, free, w)
    assert np.array_equal(r0, r_fd)  # the residual of the simulation itself
    scale = np.sqrt(np.mean(J**2, axis=0))
    errs = []
    for k, j in enumerate(free):
        hj = 1e-5 * max(abs(P[j]), 1e-3)
        Pp, Pm = P.copy(), P.copy()
        Pp[j] += hj
        Pm[j] -= hj
        rp = np.concatenate([(q[0, 1:] * w).ravel() for q in residuals(model, preps, Pp[None])])
        rm = np.concatenate([(q[0, 1:] * w).ravel() for q in residuals(model, preps, Pm[None])])
        ref = (rp - rm) / (2 * hj)
        errs.append(
            (
                np.linalg.norm(J[:, k] - ref) / (np.linalg.norm(ref) + 1e-12 * scale[k]),
                j,
                model.base[j][1] if j < model.n_base else j,
            )
        )
    assert max(errs)[0] < 1e-4, max(errs)


@needs_numba
def test_candidate_slots_are_left_to_finite_differences():
    prof = load_profile("kvlcc2")
    recs = [_marin("zz_10").window(0, 300)]
    cands, _ = build_library(prof, recs)
    model = AugmentedModel(prof, prof.params(), cands, n_rec=1)
    preps = [prepare(prof, recs[0], 0)]
    w = np.ones(3)
    base = list(range(model.n_base))
    P = model.p0()
    assert applies(model, P, base)
    assert not applies(model, P, base + [model.n_base])  # a candidate's parameter free
    P[model.n_base] = 1e-3
    assert not applies(model, P, base)  # a candidate switched on
    a = jacobian(model, preps, P, base, w, analytic=True)
    b = jacobian(model, preps, P, base, w)
    assert np.array_equal(a[1], b[1])


@needs_numba
def test_left_out_grams_match_finite_differences():
    """loo_misfit's Gram matrices (diagnose.baseline._grams) against diagnose.heldout.grams."""
    prof = load_profile("kvlcc2")
    recs = [_marin("zz_10").window(0, 400), _marin("zz_20").window(0, 300)]
    model = AugmentedModel(prof, prof.params(), [])
    preps = [prepare(prof, r) for r in recs]
    P, idx, w = model.p0(), list(range(model.n_base)), 1.0 / np.array([0.01, 0.01, 0.001])
    parts = make_parts(preps, [])
    a = _grams(model, preps, parts, P, idx, w)
    b = grams(model, preps, parts, P, idx, w, model.steps(preps, P))
    assert np.allclose(a.rr, b.rr, rtol=1e-12) and np.allclose(a.den, b.den, rtol=1e-12) and np.array_equal(a.n_rows, b.n_rows)
    # scaled by each column's own size (sqrt(G_ii G_jj), sqrt(G_ii rr) for h, their Cauchy-Schwarz
    # bounds): an absolute tolerance on the largest entry leaves the columns of small terms (here
    # 6 of 13: v_r*r, u_r*v_r, u_r*r, v_r*|v_r|, delta*n^2, r*|r|) unchecked; forward differences are
    # within 4e-4 of the exact Gram matrix on this scale, a column wrong by 1 % is off by 1e-2 or more
    d = np.sqrt(np.einsum("pkcc->pkc", b.G))
    assert np.all(np.abs(a.G - b.G) <= 1e-3 * d[..., :, None] * d[..., None, :])
    assert np.all(np.abs(a.h - b.h) <= 1e-3 * d * np.sqrt(b.rr)[..., None])


def test_without_the_compiler_the_jacobian_is_finite_differences(monkeypatch):
    """No numba (or SHIPTRIAL_KERNEL=numpy): analytic=True falls back to the finite differences,
    the same numbers as without it (the numpy path CI runs on platforms without the compiler)."""
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    prof = load_profile("kvlcc2")
    model = AugmentedModel(prof, prof.params(), [], n_rec=1)
    preps = [prepare(prof, _marin("zz_10").window(0, 200), 0)]
    free, w = list(range(model.n_base)) + model.x0_params(), np.ones(3)
    assert not applies(model, model.p0(), free)
    a = jacobian(model, preps, model.p0(), free, w, analytic=True)
    b = jacobian(model, preps, model.p0(), free, w)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
