"""Levenberg-Marquardt with geodesic acceleration (Transtrum & Sethna 2012), the output-error fit's continuation where
its exact-Jacobian path ends unconverged (stop 59; stop 57 wrote it as a diagnostic, benchmarks/diag_rollmass_redo.py).

Why: such ends creep along a curved valley (the sway row's scale M + X_v with Y_v, Y_r coupled to K_vdot, stop 57):
a plain LM step along the valley's tangent leaves the curved floor, the cost rises and lambda grows, so each accepted
step is short. The geodesic correction bends the step along the valley. Pure numpy over any problem with
``residual(x)`` and ``jacobian(x)``; :func:`identify.rollmass.oe_fit._lm_geodesic` supplies the fit's own stationarity
rule (the load's decrement) as ``stationary``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

# the step rule's constants. From Transtrum & Sethna 2012 (section on geodesic acceleration): the finite-difference
# length h of r_vv (in units of the step) and the form of the acceptance rule, 2 |a| / |v| <= alpha. ALPHA is 1.5, twice
# the paper's suggested 0.75: it is stop 57's bench's |a| <= 0.75 |v| written in the paper's form, the rule stop 59's
# figures were measured with (docs/mass-accuracy.md "Stop 59"; the paper's 0.75 is not measured here). Stop 57's bench's
# own choices, not the paper's (it discusses Marquardt's factors and "delayed gratification", up 2 / down 3): lambda's
# start, its fall on an accepted step and rise on a rejected one, and the lambda past which no step lowers the cost
ALPHA = 1.5
H = 0.1
LAMBDA0 = 1e-3
DOWN, UP = 5.0, 3.0
LAMBDA_MAX = 1e16
# relative cost fall of an accepted step below which the walk has stopped
COST_RTOL = 1e-14


class Problem(Protocol):
    """A least-squares problem: minimise ``|residual(x)|^2``; ``jacobian(x)`` is d residual / dx."""

    def residual(self, x: np.ndarray) -> np.ndarray: ...

    def jacobian(self, x: np.ndarray) -> np.ndarray: ...


@dataclass
class GeodesicResult:
    """Where :func:`geodesic_lm` stopped: the point, its residual and Jacobian, the proposed steps, the
    residual and Jacobian evaluations, the steps the acceleration's ratio rule rejected, and the status
    (``"converged (step)"``, ``"converged (cost)"``, ``"converged (lambda)"``, ``"converged (stationary)"`` or
    ``"at cap"``)."""

    x: np.ndarray
    f: np.ndarray
    J: np.ndarray
    steps: int
    residuals: int
    jacobians: int
    rejected_by_ratio: int
    status: str

    @property
    def converged(self) -> bool:
        return self.status != "at cap"


def acceleration(
    prob: Problem, x: np.ndarray, f: np.ndarray, J: np.ndarray, v: np.ndarray, A: np.ndarray, h: float
) -> np.ndarray:
    """The geodesic acceleration of step ``v`` (Transtrum & Sethna 2012, the section on geodesic acceleration): ``a = -A^-1 J^T r_vv`` with
    ``A = J^T J + lambda D`` and the directional second derivative ``r_vv = (2/h) ((r(x + h v) - r) / h - J v)`` from
    one more residual (exact for a residual quadratic in x)."""
    fh = prob.residual(x + h * v)
    return -np.linalg.solve(A, J.T @ ((2.0 / h) * ((fh - f) / h - J @ v)))


def _norm(u: np.ndarray, D: np.ndarray) -> float:
    """``|u|`` in the ``D`` metric (Marquardt's scaling)."""
    return float(np.sqrt((u * D) @ u))


def geodesic_lm(
    prob: Problem,
    x: np.ndarray,
    max_steps: int,
    xtol: float = 1e-10,
    stationary: Callable[[np.ndarray, np.ndarray, np.ndarray], bool] | None = None,
    every: int = 5,
    alpha: float = ALPHA,
) -> GeodesicResult:
    """Levenberg-Marquardt with geodesic acceleration (Transtrum & Sethna 2012, "Improvements to the
    Levenberg-Marquardt algorithm for nonlinear least-squares minimization", arXiv:1201.5885, the section on geodesic acceleration).

    Step rule: the LM step ``v = -(J^T J + lambda D)^-1 J^T r`` (``D``: the running maximum of diag(J^T J), Marquardt's
    scaling) gets the second-order correction ``a`` (:func:`acceleration`); ``x + v + a/2`` is tried only when
    ``2 |a|_D <= alpha |v|_D`` (the paper's acceptance rule, here in the ``D`` metric; :data:`ALPHA` is 1.5, twice the
    paper's suggested 0.75, see there), else the step is rejected and lambda rises by :data:`UP`.
    A tried step that lowers the cost is accepted and lambda falls by :data:`DOWN`, else lambda rises by :data:`UP`.
    Converged when an accepted step is small (``|v + a/2|_D <= xtol (|x|_D + xtol)``), its relative cost fall is below
    :data:`COST_RTOL`, lambda passes :data:`LAMBDA_MAX` (no step of any length lowers the cost), or ``stationary(x, r,
    J)`` holds, checked every ``every`` accepted steps (the caller's own rule); else it stops ``"at cap"`` after
    ``max_steps`` proposed steps, accepted or not. A step costs up to two residuals (the acceleration's and the tried
    point's) and, accepted, one Jacobian: at most ``2 max_steps + 1`` residuals and ``max_steps + 1`` Jacobians."""
    f = prob.residual(x)
    cost = f @ f
    J = prob.jacobian(x)
    D = np.maximum((J * J).sum(0), 1e-300)
    lam, nres, njac, accepted, rejected, it = LAMBDA0, 1, 1, 0, 0, 0
    status = "at cap"
    while it < max_steps:
        if lam > LAMBDA_MAX:
            status = "converged (lambda)"
            break
        it += 1
        D = np.maximum(D, (J * J).sum(0))
        A = J.T @ J + lam * np.diag(D)
        try:
            v = -np.linalg.solve(A, J.T @ f)
            nres += 1
            a = acceleration(prob, x, f, J, v, A, H)
        except np.linalg.LinAlgError:
            lam *= 10
            continue
        if 2.0 * _norm(a, D) > alpha * _norm(v, D):  # the same decisions as stop 57's |a| > 0.75 |v|: x2 is exact
            rejected += 1
            lam *= UP
            continue
        step = v + 0.5 * a
        fn = prob.residual(x + step)
        nres += 1
        if not fn @ fn < cost:  # a NaN residual is no descent either
            lam *= UP
            continue
        rel = (cost - fn @ fn) / cost
        x, f, cost = x + step, fn, fn @ fn
        J = prob.jacobian(x)
        njac += 1
        lam = max(lam / DOWN, 1e-12)
        accepted += 1
        stop = _stopped(step, x, D, xtol, rel)
        if not stop and stationary is not None and accepted % every == 0 and stationary(x, f, J):
            stop = "converged (stationary)"
        if stop:
            status = stop
            break
    return GeodesicResult(x, f, J, it, nres, njac, rejected, status)


def _stopped(step: np.ndarray, x: np.ndarray, D: np.ndarray, xtol: float, rel: float) -> str:
    """Whether the walk has stopped after an accepted ``step`` to ``x`` with relative cost fall ``rel`` (``""``: no)."""
    if _norm(step, D) <= xtol * (_norm(x, D) + xtol):
        return "converged (step)"
    return "converged (cost)" if rel < COST_RTOL else ""
