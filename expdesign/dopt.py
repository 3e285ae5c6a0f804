"""Optimal dictionary designs: time fractions of the primitives (Ljungberg 2022, ch. 7).

* (7.18) / (7.53): ``max log|det(sum w_q Gamma_q)|`` with Gamma_q = X_q (no mean subtraction)
  or X_q - Y_q Z_q^T (batchwise, (7.52)). The IV Gamma is not exactly symmetric, so the convex
  program uses the *symmetric part* M_q = (Gamma_q + Gamma_q^T)/2 (instruments are close to the
  regressors, so the difference is small) and cvxpy's ``log_det`` (D), ``tr_inv`` (A) or
  ``lambda_min`` (E). Clarabel solves it; SCS is the fallback and then scipy SLSQP, and the
  result says which one was used. The planner tries first the dedicated Frank-Wolfe solver of
  :mod:`expdesign.simplexsolver` (D and A on the plain simplex, without importing cvxpy).
* (7.57): instrument mean removed over the whole experiment, ``max log|det(T - S Zbar^T)|``,
  non-convex; solved with SLSQP over the simplex (plus bounds and linear budgets) from the
  convex solution, equal shares and seeded random points; the best point seen is returned.
* (7.58): prior data enter as an extra fixed-weight term (weight = N_prior / N).

All objectives are evaluated on D Gamma D with D = diag(|diag Gamma_uniform|)^-1/2: the
D-criterion only shifts by a constant, and A/E become unit-free.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from expdesign.constraints import Constraints, minimize_slsqp
from expdesign.errors import DesignError
from expdesign.simplexsolver import SUPPORTED, solve_simplex
from primitives.information import MEAN_SUBTRACTION, PrimitiveInfo

CRITERIA = ("D", "A", "E")
ROBUST = ("bayes-D", "maximin-D")
ALIASES = {"local-D": "D"}  # the robust criteria's name for the design at the profile's values


def canonical_criterion(criterion: str) -> str:
    """The criterion's one name ("local-D" is "D"); a DesignError for one no design knows."""
    c = ALIASES.get(criterion, criterion)
    if c not in CRITERIA + ROBUST:
        raise DesignError(f"criterion must be one of {[*CRITERIA, *ALIASES, *ROBUST]}, got {criterion!r}")
    return c


@dataclass
class InfoSet:
    """Stacked per-primitive moments: X (Q, p, p) (7.50), Y (Q, p) (7.51), Z (Q, p) (7.55), block
    mask (p, p), and an optional prior (7.58) with moments X0, Y0, Z0 and weight ``a``."""

    names: list[str]
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    mask: np.ndarray
    X0: np.ndarray | None = None
    Y0: np.ndarray | None = None
    Z0: np.ndarray | None = None
    a: float = 0.0
    scale: np.ndarray = field(init=False)

    @classmethod
    def from_infos(cls, infos: list[PrimitiveInfo], prior: PrimitiveInfo | None = None, prior_weight: float = 0.0) -> InfoSet:
        if not infos:
            raise DesignError("the primitive library is empty; give at least one informative primitive")
        s = cls(
            [i.name for i in infos],
            np.stack([i.X for i in infos]),
            np.stack([i.Y for i in infos]),
            np.stack([i.Z for i in infos]),
            infos[0].mask.astype(float),
        )
        if prior is not None and prior_weight > 0:
            s.X0, s.Y0, s.Z0, s.a = prior.X, prior.Y, prior.Z, float(prior_weight)
        return s

    def __post_init__(self) -> None:
        g = self.gamma(np.full(len(self.names), 1.0 / len(self.names)), "batchwise")
        d = np.abs(np.diag(g))
        self.scale = 1.0 / np.sqrt(np.where(d > 0, d, 1.0))

    @property
    def n_params(self) -> int:
        return self.X.shape[1]

    def per_primitive(self, mean_subtraction: str) -> np.ndarray:
        """Gamma_q (Q, p, p) for 'none' (X_q) or 'batchwise' (7.52)."""
        if mean_subtraction == "none":
            return self.X.copy()
        return self.X - np.einsum("qi,qj->qij", self.Y, self.Z) * self.mask

    def prior_gamma(self, mean_subtraction: str) -> np.ndarray:
        p = self.n_params
        if self.X0 is None:
            return np.zeros((p, p))
        g = self.X0 if mean_subtraction == "none" else self.X0 - np.outer(self.Y0, self.Z0) * self.mask
        return self.a * g

    def gamma(self, w: np.ndarray, mean_subtraction: str) -> np.ndarray:
        """Gamma of the mix with fractions w: (7.18), (7.53) or (7.57) (+ the prior term (7.58))."""
        w = np.asarray(w, float)
        if mean_subtraction != "complete":
            return np.einsum("q,qij->ij", w, self.per_primitive(mean_subtraction)) + self.prior_gamma(mean_subtraction)
        T = np.einsum("q,qij->ij", w, self.X)
        S = w @ self.Y
        zsum, wsum = w @ self.Z, w.sum()
        if self.X0 is not None:
            T, S, zsum, wsum = T + self.a * self.X0, S + self.a * self.Y0, zsum + self.a * self.Z0, wsum + self.a
        return T - np.outer(S, zsum / max(wsum, 1e-300)) * self.mask

    def scaled(self, g: np.ndarray) -> np.ndarray:
        return g * np.outer(self.scale, self.scale)

    def logdet(self, w: np.ndarray, mean_subtraction: str) -> float:
        """log|det Gamma(w)| (unscaled), -inf when singular."""
        sign, ld = np.linalg.slogdet(self.scaled(self.gamma(w, mean_subtraction)))
        return float(ld - 2 * np.log(self.scale).sum()) if sign != 0 else -np.inf

    def value(self, w: np.ndarray, mean_subtraction: str, criterion: str = "D") -> float:
        """Criterion to maximise: log|det Gamma| (D), -tr(M^-1) (A), lambda_min(M) (E) with
        M = (G^T G)^(1/2), G = D Gamma D, the symmetric polar factor of the scaled Gamma: its
        eigenvalues are the singular values of G, log det M = log|det Gamma| + const as in the
        D-criterion, and M = G whenever G is symmetric positive definite. (The asymmetric Gamma
        of (7.57) can have an indefinite symmetric part although it is well conditioned.)"""
        if criterion == "D":
            return self.logdet(w, mean_subtraction)
        if criterion not in CRITERIA:
            raise DesignError(f"criterion must be one of {list(CRITERIA)}, got {criterion!r}")
        sv = np.linalg.svd(self.scaled(self.gamma(w, mean_subtraction)), compute_uv=False)
        if criterion == "E":
            return float(sv[-1])
        return -float(np.sum(1.0 / sv)) if sv[-1] > 0 else -np.inf


# -- what the instrument-mean subtraction removes -------------------------------------------------

# Information below this fraction of what the regressor-instrument products carry before the mean
# is removed is cancellation noise: X and Y Z^T agree to their last digits when the instrument is
# constant over every mean-subtraction batch (a surge force held through every zig-zag), and what
# is left of double precision's 16 digits after that is below 1e-13 of X in practice.
MEAN_SUBTRACTION_NOISE = 1e-9


def lost_to_mean_subtraction(
    info: InfoSet, w: np.ndarray, mean_subtraction: str, rel_tol: float = MEAN_SUBTRACTION_NOISE
) -> dict[int, float]:
    """Parameters the instrument-mean subtraction of (7.53)/(7.57) leaves unidentifiable in the mix
    ``w``: {index: fraction of its information that survives}. A parameter is lost when the
    diagonal of Gamma(w) after subtraction is below ``rel_tol`` of that before (its instrument is
    constant over every batch: batchwise over each primitive, complete over the whole trial), or
    when it loads (> 0.3) on a direction in which Gamma, normalised by the information before
    subtraction, is singular to ``rel_tol`` (a combination the subtraction removes). Parameters
    without information before the subtraction are :func:`primitives.information.unidentified_parameters`'s."""
    if mean_subtraction == "none":
        return {}
    w = np.asarray(w, float)
    raw = np.abs(np.diag(info.gamma(w, "none")))
    sub = info.gamma(w, mean_subtraction)
    live = raw > 0
    frac = np.abs(np.diag(sub)) / np.where(live, raw, 1.0)
    lost = {int(i): float(frac[i]) for i in np.flatnonzero(live & (frac < rel_tol))}
    idx = np.flatnonzero(live)
    d = 1.0 / np.sqrt(raw[idx])
    g = sub[np.ix_(idx, idx)] * np.outer(d, d)
    if g.size and np.all(np.isfinite(g)):
        _, sv, vt = np.linalg.svd(g)
        for s_k, row in zip(sv, vt):
            if s_k < rel_tol * max(sv[0], 1e-300):
                for j in np.flatnonzero(np.abs(row) > 0.3):
                    lost.setdefault(int(idx[j]), float(frac[idx[j]]))
    return dict(sorted(lost.items()))


def varying_primitives(info: InfoSet, index: int, mean_subtraction: str, rel_tol: float = MEAN_SUBTRACTION_NOISE) -> list[str]:
    """The primitives in which parameter ``index`` keeps information after the subtraction of
    each primitive's own instrument mean (its instrument varies within the primitive)."""
    if mean_subtraction == "none":
        return list(info.names)
    raw = np.abs(info.X[:, index, index])
    sub = np.abs(info.per_primitive("batchwise")[:, index, index])
    return [n for n, a, b in zip(info.names, raw, sub) if a > 0 and b >= rel_tol * a]


# -- results ------------------------------------------------------------------------------------


@dataclass
class SolveResult:
    """Fractions w (Q,), the criterion value, the solver used and notes; for the convex program the
    gradient g_q of the criterion and a guaranteed efficiency bound; for the non-convex one the
    objective at each start and at the end point reached from it."""

    weights: np.ndarray
    objective: float
    solver: str
    notes: list[str] = field(default_factory=list)
    gradient: np.ndarray | None = None
    max_gradient: float | None = None
    efficiency_bound: float | None = None
    starts: list[dict] = field(default_factory=list)
    winner: str | None = None


# -- convex program (7.18) / (7.53) ---------------------------------------------------------------


def _sym_matrices(info: InfoSet, mean_subtraction: str) -> tuple[np.ndarray, np.ndarray]:
    """Scaled symmetric parts M_q (Q, p, p) and prior M_0 used by the convex relaxation.
    'complete' (7.57) is relaxed to its batchwise counterpart (7.53)."""
    ms = "batchwise" if mean_subtraction == "complete" else mean_subtraction
    g = info.per_primitive(ms) * np.outer(info.scale, info.scale)
    g0 = info.scaled(info.prior_gamma(ms))
    return 0.5 * (g + np.swapaxes(g, 1, 2)), 0.5 * (g0 + g0.T)


def _sym_value(m: np.ndarray, criterion: str) -> float:
    ev = np.linalg.eigvalsh(m)
    if criterion == "E":
        return float(ev[0])
    if ev[0] <= 0:
        return -np.inf
    return float(np.sum(np.log(ev))) if criterion == "D" else -float(np.sum(1.0 / ev))


def certificate(
    info: InfoSet, w: np.ndarray, cons: Constraints, criterion: str, mean_subtraction: str
) -> tuple[np.ndarray, float, float | None]:
    """General equivalence theorem for the symmetric relaxation.

    D: g_q = tr(M^-1 M_q); by the AM-GM inequality on the eigenvalues of M^-1/2 M(w') M^-1/2,
    det M(w') / det M(w) <= (tr(M^-1 M(w')) / p)^p, so the D-efficiency of w is at least
    p / max_{w' feasible} tr(M^-1 M(w')) (= p / max_q g_q on the plain simplex; equal to 1 exactly
    at the optimum, where max_q g_q = p). A: h_q = tr(M^-2 M_q); convexity of tr(M^-1) gives
    A-efficiency >= 2 - (tr(M^-2 M_0) + max h.w') / tr(M^-1). E: no bound (non-smooth).
    Returns (gradient, max over the feasible set, bound).
    """
    mq, m0 = _sym_matrices(info, mean_subtraction)
    m = m0 + np.einsum("q,qij->ij", w, mq)
    p = m.shape[0]
    try:
        minv = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        return np.full(len(w), np.nan), np.nan, None
    if criterion == "D":
        g = np.einsum("ij,qji->q", minv, mq)
        mx = cons.max_linear(g) + float(np.trace(minv @ m0))
        return g, mx, float(min(1.0, p / mx)) if mx > 0 else None
    if criterion == "A":
        m2 = minv @ minv
        h = np.einsum("ij,qji->q", m2, mq)
        mx = cons.max_linear(h) + float(np.trace(m2 @ m0))
        return h, mx, float(max(0.0, min(1.0, 2.0 - mx / np.trace(minv))))
    return np.full(len(w), np.nan), np.nan, None


def _cvx_problem(mq: np.ndarray, m0: np.ndarray, cons: Constraints, criterion: str):
    import cvxpy as cp

    q = mq.shape[0]
    w = cp.Variable(q)
    m = m0 + sum(w[i] * mq[i] for i in range(q))
    m = (m + m.T) / 2
    obj = {"D": cp.Maximize(cp.log_det(m)), "A": cp.Minimize(cp.tr_inv(m)), "E": cp.Maximize(cp.lambda_min(m))}[criterion]
    c = [cp.sum(w) == 1, w >= cons.lo, w <= cons.hi]
    if cons.A.size:
        c.append(cons.A @ w <= cons.b)
    return cp.Problem(obj, c), w


def _scipy_sym(mq: np.ndarray, m0: np.ndarray, cons: Constraints, criterion: str) -> np.ndarray:
    """Last-resort solver of the symmetric relaxation: SLSQP from equal shares."""
    q = mq.shape[0]

    def f(w):
        v = _sym_value(m0 + np.einsum("q,qij->ij", w, mq), criterion)
        return -v if np.isfinite(v) else 1e6

    cons_l = [{"type": "eq", "fun": lambda x: x.sum() - 1.0}]
    if cons.A.size:
        cons_l.append({"type": "ineq", "fun": lambda x: cons.b - cons.A @ x})
    r = minimize_slsqp(
        f,
        cons.project(np.full(q, 1.0 / q)),
        bounds=list(zip(cons.lo, cons.hi)),
        constraints=cons_l,
        options={"maxiter": 500, "ftol": 1e-12},
    )
    return np.clip(r.x, cons.lo, cons.hi)


DEDICATED = "frank-wolfe"


def _dedicated(mq: np.ndarray, m0: np.ndarray, cons: Constraints, criterion: str, notes: list[str]) -> np.ndarray | None:
    """Weights from :func:`expdesign.simplexsolver.solve_simplex` where it applies (D or A on the
    plain simplex) and certifies its optimum, else None with a note."""
    if criterion not in SUPPORTED or not cons.is_simplex:
        notes.append(
            f"{DEDICATED} does not apply ({criterion}-criterion{'' if cons.is_simplex else ', constrained fractions'}); "
            "trying the next solver"
        )
        return None
    r = solve_simplex(mq, m0, criterion)
    if r is None:
        notes.append(f"{DEDICATED} did not certify an optimum; trying the next solver")
        return None
    if not r.unique:  # any optimal mix would do; the interior-point solver picks the central one, as `shiptrial design`
        notes.append(f"{DEDICATED}: the optimal weights are not unique; trying the next solver")
        return None
    return r.weights


def solve_convex(
    info: InfoSet,
    criterion: str = "D",
    mean_subtraction: str = "batchwise",
    constraints: Constraints | None = None,
    solvers: tuple[str, ...] = ("CLARABEL", "SCS"),
) -> SolveResult:
    """Convex design (7.18)/(7.53) on the symmetrized information matrices (see module doc).

    Tries ``solvers`` in order (cvxpy solver names, or ``"frank-wolfe"`` for
    :mod:`expdesign.simplexsolver`, which avoids importing cvxpy), then scipy SLSQP; every
    fallback is recorded in ``notes``. The result carries the equivalence-theorem certificate
    (:func:`certificate`).
    """
    if criterion not in CRITERIA:
        raise DesignError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if mean_subtraction not in MEAN_SUBTRACTION:
        raise DesignError(f"mean subtraction must be one of {MEAN_SUBTRACTION}, got {mean_subtraction!r}")
    q = len(info.names)
    cons = constraints or Constraints.simplex(q)
    mq, m0 = _sym_matrices(info, mean_subtraction)
    notes: list[str] = []
    if mean_subtraction == "complete":
        notes.append("convex relaxation of (7.57): batchwise mean subtraction (7.53), symmetric part of Gamma")
    else:
        notes.append("convex program on the symmetric part of Gamma (the IV Gamma is close to, not exactly, symmetric)")
    w, used = _solve_sym(mq, m0, cons, criterion, solvers, notes)
    w = cons.project(w / w.sum())
    g, mx, bound = certificate(info, w, cons, criterion, mean_subtraction)
    val = _sym_value(m0 + np.einsum("q,qij->ij", w, mq), criterion)
    if criterion == "D":
        val -= 2 * np.log(info.scale).sum()  # log det of the unscaled symmetric matrix
    return SolveResult(w, float(val), used, notes, g, mx, bound)


def _solve_sym(
    mq: np.ndarray, m0: np.ndarray, cons: Constraints, criterion: str, solvers: tuple[str, ...], notes: list[str]
) -> tuple[np.ndarray, str]:
    """The weights of the symmetrized program from the first of ``solvers`` that succeeds, else
    scipy SLSQP, and the solver's name; each failure and fallback recorded in ``notes``."""
    for name in solvers:
        w = _dedicated(mq, m0, cons, criterion, notes) if name == DEDICATED else _solve_cvx(mq, m0, cons, criterion, name, notes)
        if w is not None:
            return w, name
    notes.append("all conic solvers failed; used scipy SLSQP on the same objective")
    return _scipy_sym(mq, m0, cons, criterion), "scipy-SLSQP"


def _solve_cvx(
    mq: np.ndarray, m0: np.ndarray, cons: Constraints, criterion: str, name: str, notes: list[str]
) -> np.ndarray | None:
    """The weights from cvxpy's solver ``name`` (clipped to the bounds), or None when it fails
    (recorded in ``notes``, as is an inaccurate optimum)."""
    import cvxpy as cp

    try:
        prob, var = _cvx_problem(mq, m0, cons, criterion)
        with warnings.catch_warnings():  # an inaccurate status is recorded in the notes instead
            warnings.simplefilter("ignore", UserWarning)
            prob.solve(solver=name)
        if prob.status in ("optimal", "optimal_inaccurate") and var.value is not None:
            if prob.status == "optimal_inaccurate":
                notes.append(f"{name} reported an inaccurate optimum")
            return np.clip(np.asarray(var.value, float), cons.lo, cons.hi)
        notes.append(f"{name} failed (status {prob.status}); trying the next solver")
    except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
        notes.append(f"{name} failed ({type(exc).__name__}: {str(exc).splitlines()[0][:80]}); trying the next solver")
    return None
