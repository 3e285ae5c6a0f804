"""The compiled regressor build (primitives.regkernel) against the numpy build it replaces: the same
bits for every built-in profile's predictor and for terms with stations, moduli and the powers
formed as products (primitives.powers); a term set with another power keeps the numpy build; the build never loads numba. The numpy build runs whenever
numba is missing or SHIPTRIAL_KERNEL=numpy is set (tests/test_jitloop.py checks the selection)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from primitives import jitloop, regkernel
from primitives.regressors import predictor_regressors
from primitives.ship import builtin_profiles, load_profile
from primitives.terms import TermSet

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _data(profile, b: int = 6, n: int = 300, seed: int = 0):
    rng = np.random.default_rng(seed)
    nd = profile.n_dof
    y = rng.normal(0.0, 1.0, (b, n + 1, nd)) * np.array([0.3, 0.1, 0.02, 0.01][:nd]) + np.array([1.5, 0, 0, 0][:nd])
    inputs = rng.normal(0.0, 1.0, (b, n, len(profile.inputs)))
    psi = rng.uniform(-3.0, 3.0, (b, n + 1))
    return y, inputs, psi


def _numpy_build(monkeypatch, *args, **kw):
    with monkeypatch.context() as m:
        m.setattr(jitloop, "AVAILABLE", False)
        return predictor_regressors(*args, **kw)[0]


@needs_numba
@pytest.mark.parametrize("name", [n for n in builtin_profiles() if load_profile(n).n_dof == 3])
def test_compiled_regressors_are_the_numpy_bits(monkeypatch, name):
    assert jitloop.use(jitloop.MIN_WORK)  # the compiled build runs once a simulation has loaded numba
    profile = load_profile(name)
    y, inputs, psi = _data(profile)
    calls = []
    with monkeypatch.context() as m:  # the compiled build must be the one that ran
        m.setattr(regkernel, "_build", lambda *a, f=regkernel._build: calls.append(1) or f(*a))
        compiled = predictor_regressors(profile, y, inputs, psi)[0]
    numpy_phi = _numpy_build(monkeypatch, profile, y, inputs, psi)
    assert (calls == [1]) == (regkernel._program(profile.predictor.terms) is not None)
    assert compiled.shape == numpy_phi.shape
    assert np.array_equal(compiled, numpy_phi, equal_nan=True)


@needs_numba
def test_stations_moduli_squares_and_reciprocals(monkeypatch):
    assert jitloop.use(jitloop.MIN_WORK)
    profile = load_profile("model-ship")
    terms = TermSet(
        [
            ["u_r", "u_r*|u_r|", "U^-1*v_r^2", "tau_x"],
            ["|v_r@-0.7|*v_r@1.3", "r^2*U^-1", "tau_y"],
            ["|r|*r", "u_r*v_r*r", "tau_n"],
        ]
    )
    y, inputs, psi = _data(profile, seed=3)
    y[0, 5] = np.nan  # a gap in the record stays a NaN row in both
    compiled = predictor_regressors(profile, y, inputs, psi, terms=terms)[0]
    numpy_phi = _numpy_build(monkeypatch, profile, y, inputs, psi, terms=terms)
    assert regkernel._program(terms.terms) is not None
    assert np.isnan(compiled[0, 5]).any() and np.isfinite(compiled[1]).all()
    assert np.array_equal(compiled, numpy_phi, equal_nan=True)


@needs_numba
def test_cubes_fourth_powers_and_inverse_squares_are_built_compiled_with_the_numpy_bits(monkeypatch):
    """v_r^3, |v_r@1.3|^4, U^-2 (the MMG structure's powers) are products on both builds (stop 44:
    integer powers as products), so the compiled build covers them with the numpy build's bits."""
    assert jitloop.use(jitloop.MIN_WORK)
    profile = load_profile("model-ship")
    terms = TermSet([["u_r", "v_r^4*U^-2", "tau_x"], ["v_r^3", "|v_r@1.3|^4*r^3", "tau_y"], ["r^3*U^-2", "U^-1*v_r^3", "tau_n"]])
    y, inputs, psi = _data(profile, seed=5)
    assert regkernel._program(terms.terms) is not None
    compiled = predictor_regressors(profile, y, inputs, psi, terms=terms)[0]
    assert np.array_equal(compiled, _numpy_build(monkeypatch, profile, y, inputs, psi, terms=terms))


def test_other_powers_keep_the_numpy_build():
    """v_r^5: numpy's vectorised power and the C library's pow may differ in the last bit."""
    jitloop.use(jitloop.MIN_WORK)
    terms = TermSet([["u_r"], ["v_r^5", "tau_y"], ["r"]])
    assert regkernel._program(terms.terms) is None
    assert regkernel.regressor_matrix(terms, {"u_r": np.ones(3)}, (3,)) is None


_NO_LOAD = """
import numpy as np
from primitives import jitloop
from primitives.regressors import predictor_regressors
from primitives.ship import load_profile
rng = np.random.default_rng(0)
for name in ("model-ship", "naval-vessel"):  # one the compiled build covers, one it leaves to numpy
    p = load_profile(name)
    b, n = 20, 1000  # 20,000 samples: as large as the simulation kernel's load threshold
    y = rng.normal(0.0, 0.1, (b, n + 1, p.n_dof)) + 1.0
    phi = predictor_regressors(p, y, rng.normal(0.0, 1.0, (b, n, len(p.inputs))), rng.uniform(-3, 3, (b, n + 1)))[0]
    assert np.isfinite(phi).any()
print(jitloop._LOADED)
"""


@needs_numba
def test_the_regressor_build_never_loads_numba():
    """Loading numba costs about 0.6 s of CPU for a build numpy does about as fast: a process whose
    first large call is a Phi build (the particulars fit, robust design, information) must not pay it."""
    out = subprocess.run([sys.executable, "-c", _NO_LOAD], capture_output=True, text=True, timeout=120, check=True).stdout
    assert out.split() == ["False"]
