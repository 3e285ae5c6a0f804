"""The oe fit as a numerical procedure: a residual smooth enough to differentiate, a stop short of
the optimum said (never a silent "converged"), and the roll-centre prior's uncertainty in the interval."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import OptimizeResult

from identify.rollmass import output_error as oe
from identify.rollmass.estimate import estimate
from identify.rollmass.model import Load, load_profile
from identify.rollmass.simulate import Noise, simulate_case

PROF = load_profile()
CAL = Load(0.2, -0.256)


@pytest.fixture(scope="module")
def case2():
    return simulate_case(PROF, "case2", Noise.from_profile(PROF, 0.05), seed=3, length_factor=0.3)


def _problem(datasets) -> tuple[oe._Problem, np.ndarray]:
    kn = PROF.known
    free = oe.SHARED + ("z_f", "m", "zbar_m")
    w = np.array([1.0 / oe._measured(d).std(axis=0) for d in datasets])
    start = oe.start_values(PROF)
    x = np.array([start[k] for k in oe.SHARED] + [kn.z_f_prior, 0.4, -0.268])
    return oe._Problem(datasets, kn, CAL, kn.z_f_prior, free, w, None, kn.z_f_prior_sd), x


@pytest.mark.parametrize("name", ["Y_r", "Y_pdot", "K_vdot", "X_v", "zbar_m"])
def test_the_residual_is_smooth_enough_for_finite_differences(case2, name):
    """Central differences at steps 1e-6 and 1e-8 agree: the fit's Jacobian is a derivative, not
    rounding noise. Through the transfer function (ss2tf + order-4 lfilter) they differed by 10-800 %
    and LM stopped on xtol far from the optimum (basin truth base, case 2: 0.347 kg for 0.400)."""
    prob, x = _problem(case2)
    j = prob.free.index(name)
    d = []
    for h in (1e-6, 1e-8):
        e = np.zeros_like(x)
        e[j] = h * max(1.0, abs(x[j]))
        d.append((prob.residual(x + e) - prob.residual(x - e)) / (2 * e[j]))
    assert np.linalg.norm(d[0] - d[1]) < 1e-3 * np.linalg.norm(d[0])


def test_a_fit_stopped_short_of_a_stationary_point_is_said(case2, monkeypatch):
    """An optimiser that stops where it started (as LM's xtol test did on the ridge) with
    ``success`` set must not yield a silent "converged": the Newton decrement check says it."""

    def stuck(prob, x0, tol):
        f = prob.residual(x0)
        jac = oe.central_jacobian(prob.residual, x0)
        return OptimizeResult(
            x=x0, fun=f, cost=0.5 * f @ f, jac=jac, success=True, message="`xtol` termination condition is satisfied."
        )

    monkeypatch.setattr(oe, "_lm", stuck)
    monkeypatch.setattr(oe, "FINISH_STEPS", 0)
    e = estimate(case2, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    assert not e.converged
    assert any("not at a stationary point" in w for w in e.warnings)


def test_the_sandwich_carries_a_priors_uncertainty():
    """Two parameters the data see only as their sum, the second with a prior of sd 1: the
    covariance of the second is the prior's (1), not the near-zero the data rows alone give."""
    rng = np.random.default_rng(0)
    n = 400
    col = rng.standard_normal(3 * n)
    J = np.vstack([np.column_stack([col, col]), [[0.0, 1.0]]])
    f = np.r_[rng.standard_normal(3 * n), 0.0]
    cov = oe.sandwich_cov(J, f, [n], lags=0)
    assert cov[1, 1] == pytest.approx(1.0, rel=0.05)
    assert cov[0, 0] + cov[1, 1] + 2 * cov[0, 1] == pytest.approx(1 / (col @ col), rel=0.2)
