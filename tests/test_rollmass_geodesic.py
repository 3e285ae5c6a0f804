"""identify/rollmass/geodesic.py (stop 59, moved from stop 57's benchmarks/diag_rollmass_redo.py): the geodesic
acceleration is the analytic one on a quadratic residual; the LM follows Rosenbrock's curved valley (as residuals) to
its minimum within a residual budget at which scipy's MINPACK LM is still creeping; it respects its cap and says so;
the acceleration's ratio rule rejects steps; the caller's stationarity rule stops it."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from identify.rollmass.geodesic import ALPHA, LAMBDA0, H, acceleration, geodesic_lm


class _Banana:
    """Rosenbrock's curved valley as residuals ``(A (y - x^2), 1 - x)``: minimum 0 at (1, 1)."""

    def __init__(self, A: float = 10.0):
        self.A = A

    def residual(self, p: np.ndarray) -> np.ndarray:
        return np.array([self.A * (p[1] - p[0] ** 2), 1.0 - p[0]])

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        return np.array([[-2.0 * self.A * p[0], self.A], [-1.0, 0.0]])


START = np.array([-1.2, 1.0])


def test_the_geodesic_acceleration_is_the_analytic_one_on_a_quadratic_residual():
    prob, x, v, lam, h = _Banana(), START, np.array([0.3, -0.2]), 0.7, 0.1
    f, J = prob.residual(x), prob.jacobian(x)
    A = J.T @ J + lam * np.diag((J * J).sum(0))
    r_vv = np.array([-20.0 * v[0] ** 2, 0.0])  # Rosenbrock's residuals' second derivative along v
    a = acceleration(prob, x, f, J, v, A, h)
    assert np.allclose(a, -np.linalg.solve(A, J.T @ r_vv), rtol=1e-9, atol=1e-12)


def test_it_follows_a_curved_valley_where_plain_lm_with_the_same_budget_creeps():
    """A = 100: measured 20 steps, 41 residuals, 15 Jacobians; scipy's LM (MINPACK, exact Jacobian, x_scale 'jac')
    given those 41 residuals is at its cap at (0.82, 0.67). Without the acceleration (``a = 0``, mutant tried) it is at
    its cap of 60 steps at (-0.016, -0.004) (measured; it needs 141 steps, 64 Jacobians)."""
    prob = _Banana(100.0)
    g = geodesic_lm(prob, START, 60)
    assert g.converged and g.status == "converged (step)" and np.allclose(g.x, [1.0, 1.0], atol=1e-6)
    assert g.jacobians <= 20 and g.residuals <= 2 * g.steps + 1
    assert np.array_equal(g.f, prob.residual(g.x)) and np.array_equal(g.J, prob.jacobian(g.x))  # the end's own
    lm = least_squares(prob.residual, START, jac=prob.jacobian, method="lm", x_scale="jac", max_nfev=g.residuals)
    assert lm.status == 0 and np.linalg.norm(lm.x - 1.0) > 0.1  # plain LM, the same budget: at its cap, creeping


def test_it_respects_its_cap_and_says_it_did_not_converge():
    """A cap the walk needs more than (Rosenbrock A = 100 needs 20 steps): it stops at exactly the cap, within the
    evaluation bound, and reports "at cap", not converged. A loop that ignores the cap fails."""
    prob = _Banana(100.0)
    g = geodesic_lm(prob, START, 5)
    assert (g.steps, g.status, g.converged) == (5, "at cap", False)
    assert g.residuals <= 2 * 5 + 1 and g.jacobians <= 5 + 1
    assert np.linalg.norm(g.x - 1.0) > 0.1  # honestly not there


def test_the_ratio_rule_rejects_steps_whose_acceleration_is_too_large():
    """With ``alpha`` tiny every curved step's ``|a|_D > alpha |v|_D``: all are rejected (counted), none is tried
    (no residual beyond the start's and the accelerations'), the point stays. Without the rule (mutant tried) the
    steps are tried and the walk moves."""
    prob = _Banana(100.0)
    g = geodesic_lm(prob, START, 8, alpha=1e-9)
    assert g.rejected_by_ratio == 8 and g.residuals == 1 + 8 and g.jacobians == 1
    assert np.array_equal(g.x, START) and g.status == "at cap"
    assert geodesic_lm(prob, START, 8).rejected_by_ratio < 8  # the default alpha lets steps through


def test_the_ratio_rule_is_the_papers_two_a_over_v_at_most_alpha():
    """Transtrum & Sethna 2012's rule: the step is tried when ``2 |a| / |v| <= alpha`` (here in the ``D`` metric), and
    the default :data:`ALPHA` 1.5 is stop 57's ``|a| <= 0.75 |v|``. The first step from the start, its ratio computed by
    hand: an alpha just above twice it lets the step through, just below rejects it. A rule without the factor 2 (stop
    57's form with the paper's alpha, mutant tried) lets both through."""
    prob = _Banana(100.0)
    f, J = prob.residual(START), prob.jacobian(START)
    D = (J * J).sum(0)
    A = J.T @ J + LAMBDA0 * np.diag(D)
    v = -np.linalg.solve(A, J.T @ f)
    a = acceleration(prob, START, f, J, v, A, H)
    ratio = np.sqrt((a * D) @ a) / np.sqrt((v * D) @ v)
    assert 0.01 < 2 * ratio < ALPHA  # the default takes this step
    assert geodesic_lm(prob, START, 1, alpha=2 * ratio * (1 + 1e-9)).rejected_by_ratio == 0
    assert geodesic_lm(prob, START, 1, alpha=2 * ratio * (1 - 1e-9)).rejected_by_ratio == 1


def test_the_callers_stationarity_rule_stops_it_after_every_nth_accepted_step():
    seen = []

    def stationary(x, f, J):
        seen.append(x.copy())
        return len(seen) == 2

    g = geodesic_lm(_Banana(), START, 200, stationary=stationary, every=2)
    assert g.status == "converged (stationary)" and g.converged
    assert g.jacobians == 1 + 4 and len(seen) == 2  # asked after accepted steps 2 and 4, stopped at the second yes
    assert np.array_equal(seen[-1], g.x)
