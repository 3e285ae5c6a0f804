"""A dedicated solver of the convex dictionary design (7.18)/(7.53) on the plain simplex.

    max phi(w) over w >= 0, sum w = 1,   M(w) = M_0 + sum_q w_q M_q   (symmetric p x p),
    phi = log det M (D)  or  -tr M^-1 (A).

Why: the planner designs a library on every ``plan-trial`` call, and importing cvxpy (with the
scipy.stats it pulls in) costs more than a second of the call, while the problem is a small
smooth concave program (about 10 primitives, 10 parameters) that needs no conic solver.
cvxpy stays the reference (``shiptrial design``) and the fallback for what this solver does
not do: the E-criterion (non-smooth), bounds or budgets on the fractions, and any problem it
cannot certify.

Method: Frank-Wolfe with away steps (Wolfe 1970; for D-optimal designs Todd & Yildirim 2007,
Ahipasaoglu, Sun & Todd 2008) with exact line search, the step length found from the
eigenvalues of M^-1/2 D M^-1/2 (D the matrix direction), which keeps M positive definite although
single M_q may be indefinite (instrumental-variable moments); once the support settles a
Newton step on the support (equality-constrained, KKT system) polishes the weights. It stops on
the duality-gap certificate of the equivalence theorem (Kiefer-Wolfowitz): the Frank-Wolfe gap
``max_q g_q - g.w`` with g the gradient (D: g_q = tr(M^-1 M_q), so ``p / (p + gap)`` bounds
the D-efficiency from below when M_0 = 0) below ``tol``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SUPPORTED = ("D", "A")
_CONE_MARGIN = 0.999999  # a line search stops this fraction of the way to the edge of the positive definite cone
_BISECTIONS, _BISECTION_TOL = 100, 1e-15  # exact line search: at most this many halvings, to this relative width
_NEWTON_HALVINGS = 30  # damping halvings of a Newton step before it is given up
_ZERO_WEIGHT = 1e-14  # a weight below this after a step is set to 0 (leaves the support)
_START_TOL, _START_ITER = 1e-4, 500  # the loose solves of the shifted problems in _positive_definite_start


@dataclass
class SimplexSolution:
    """Weights, the criterion value, the final Frank-Wolfe gap, the iterations used and whether
    the optimal weights are unique (:func:`_unique`)."""

    weights: np.ndarray
    value: float
    gap: float
    iterations: int
    unique: bool = True


class _Model:
    """The criterion, its gradient and Hessian, and exact line searches, at one point."""

    def __init__(self, mq: np.ndarray, m0: np.ndarray, criterion: str) -> None:
        self.mq, self.m0, self.criterion = mq, m0, criterion

    def matrix(self, w: np.ndarray) -> np.ndarray:
        return self.m0 + np.einsum("q,qij->ij", w, self.mq)

    def factor(self, w: np.ndarray) -> np.ndarray | None:
        """Lower Cholesky factor of M(w), None when M(w) is not positive definite."""
        try:
            return np.linalg.cholesky(self.matrix(w))
        except np.linalg.LinAlgError:
            return None

    def value(self, lo: np.ndarray) -> float:
        if self.criterion == "D":
            return float(2.0 * np.log(np.diag(lo)).sum())
        li = np.linalg.inv(lo)
        return -float(np.sum(li * li))  # tr M^-1 = ||L^-1||_F^2

    def whitened(self, lo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A_q = L^-1 M_q L^-T (Q, p, p) and L^-1."""
        li = np.linalg.inv(lo)
        return np.einsum("ik,qkl,jl->qij", li, self.mq, li), li

    def gradient(self, lo: np.ndarray) -> np.ndarray:
        """D: g_q = tr(M^-1 M_q); A: g_q = tr(M^-2 M_q)."""
        a, li = self.whitened(lo)
        if self.criterion == "D":
            return np.einsum("qii->q", a)
        k = li @ li.T  # L^-1 L^-T; tr(M^-2 M_q) = tr(A_q K)
        return np.einsum("qij,ji->q", a, k)

    def hessian(self, lo: np.ndarray, sel: np.ndarray) -> np.ndarray:
        """Hessian of phi in the weights ``sel`` (negative semi-definite)."""
        a, li = self.whitened(lo)
        a = a[sel]
        if self.criterion == "D":
            return -np.einsum("qij,rji->qr", a, a)
        k = li @ li.T
        ak = np.einsum("qij,jk->qik", a, k)
        h = np.einsum("rij,qjk->rqik", a, ak)
        t = np.einsum("rqii->rq", h)
        return -(t + t.T)

    def line_search(self, lo: np.ndarray, direction: np.ndarray, t_max: float) -> float:
        """argmax over t in [0, t_max] of phi(w + t d): with L^-1 D L^-T = U diag(lam) U^T,
        phi(t) - phi(0) = sum log(1 + t lam) (D) or -sum c_i / (1 + t lam_i) (A)."""
        a, li = self.whitened(lo)
        lam, u = np.linalg.eigh(np.einsum("q,qij->ij", direction, a))
        c = np.ones_like(lam) if self.criterion == "D" else np.sum((li.T @ u) ** 2, axis=0)
        neg = lam < 0
        if neg.any():  # stay inside the positive definite cone
            t_max = min(t_max, _CONE_MARGIN * float(np.min(-1.0 / lam[neg])))

        def slope(t: float) -> float:
            den = 1.0 + t * lam
            return float(np.sum(lam / den)) if self.criterion == "D" else float(np.sum(c * lam / den**2))

        if slope(t_max) >= 0:
            return t_max
        if slope(0.0) <= 0:
            return 0.0
        a_, b_ = 0.0, t_max  # the slope is decreasing (phi concave in t): bisection to machine precision
        for _ in range(_BISECTIONS):
            mid = 0.5 * (a_ + b_)
            if slope(mid) > 0:
                a_ = mid
            else:
                b_ = mid
            if b_ - a_ <= _BISECTION_TOL * max(1.0, b_):
                break
        return 0.5 * (a_ + b_)


def _unique(model: _Model, g: np.ndarray, rel: float = 1e-6, rank_tol: float = 1e-9) -> bool:
    """Whether the optimum is the only one. M* = M(w*) is unique (phi is strictly concave in M);
    another optimal w differs from w* by d with sum d_q M_q = 0, sum d_q = 0, non-zero only where
    g_q is maximal (complementary slackness). No such d: the weights are unique."""
    active = np.flatnonzero(g >= g.max() - rel * max(1.0, abs(float(g.max()))))
    if len(active) < 2:
        return True
    cols = model.mq[active].reshape(len(active), -1)
    k = np.column_stack([cols, np.full(len(active), np.linalg.norm(cols, axis=1).mean())]).T
    sv = np.linalg.svd(k, compute_uv=False)
    return bool(len(sv) >= len(active) and sv[-1] > rank_tol * sv[0])


def _newton_on_support(model: _Model, w: np.ndarray, lo: np.ndarray, support: np.ndarray) -> np.ndarray | None:
    """One Newton step of phi on {w_S : sum w_S = 1} (KKT system), damped to keep w >= 0 and M
    positive definite and to increase phi; None when it cannot improve."""
    g = model.gradient(lo)[support]
    h = model.hessian(lo, support)
    n = len(g)
    kkt = np.zeros((n + 1, n + 1))
    kkt[:n, :n], kkt[:n, n], kkt[n, :n] = h, 1.0, 1.0
    try:
        d = np.linalg.solve(kkt, np.concatenate([-g, [0.0]]))[:n]
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(d)):
        return None
    f0 = model.value(lo)
    neg = d < 0
    t = min(1.0, float(np.min(-w[support][neg] / d[neg]))) if neg.any() else 1.0
    for _ in range(_NEWTON_HALVINGS):
        trial = w.copy()
        trial[support] = np.maximum(w[support] + t * d, 0.0)
        trial /= trial.sum()
        lt = model.factor(trial)
        if lt is not None and model.value(lt) >= f0:
            return trial
        t *= 0.5
    return None


def solve_simplex(
    mq: np.ndarray, m0: np.ndarray, criterion: str = "D", *, tol: float = 1e-9, max_iter: int = 5000, w0: np.ndarray | None = None
) -> SimplexSolution | None:
    """Maximise the ``criterion`` of M(w) = m0 + sum w_q mq[q] over the simplex (see the module
    docstring). Stops when the Frank-Wolfe gap (relative to |g.w|, or absolute when that is
    below 1) is <= ``tol``; returns None when M(uniform) is singular or the gap is not reached
    (the caller then uses a conic solver)."""
    if criterion not in SUPPORTED:
        return None
    q = mq.shape[0]
    model = _Model(np.asarray(mq, float), np.asarray(m0, float), criterion)
    w = np.full(q, 1.0 / q) if w0 is None else np.asarray(w0, float).copy()
    if model.factor(w) is None:
        w = _positive_definite_start(model, w)
        if w is None:
            return None
    return _frank_wolfe(model, w, tol, max_iter)


def _positive_definite_start(model: _Model, w: np.ndarray, stages: int = 40) -> np.ndarray | None:
    """Weights with M(w) positive definite when M(uniform) is not (single M_q of an IV design
    can be indefinite): the problem with M_0 + s I, solved loosely for a shrinking shift s,
    until the unshifted M(w) is positive definite."""
    ev = np.linalg.eigvalsh(model.matrix(w))
    s = 2.0 * max(-ev[0], 0.0) + 1e-6 * max(abs(ev[-1]), 1.0)
    eye = np.eye(len(ev))
    for _ in range(stages):
        shifted = _Model(model.mq, model.m0 + s * eye, model.criterion)
        r = _frank_wolfe(shifted, w, _START_TOL, _START_ITER)
        if r is None:
            return None
        w = r.weights
        lam_min = float(np.linalg.eigvalsh(model.matrix(w))[0])
        if lam_min > 0:
            return w
        s = max(0.1 * s, 0.5 * (s - lam_min))  # M(w) + s I stays positive definite (-lam_min < s)
    return None


def _frank_wolfe(model: _Model, w: np.ndarray, tol: float, max_iter: int) -> SimplexSolution | None:
    """Away-step Frank-Wolfe with Newton polishing from ``w`` (M(w) positive definite)."""
    lo = model.factor(w)
    if lo is None:
        return None
    prev_support: tuple[int, ...] = ()
    for it in range(1, max_iter + 1):
        g = model.gradient(lo)
        gw = float(g @ w)
        gap = float(g.max() - gw)
        if gap <= tol * max(1.0, abs(gw)):
            return SimplexSolution(w, model.value(lo), gap, it, _unique(model, g))
        support = np.flatnonzero(w > 0)
        key = tuple(support)
        if key == prev_support and len(support) > 1:  # the support has settled: polish on it
            prev_support = ()  # then a Frank-Wolfe step again, which can grow the support
            nw = _newton_on_support(model, w, lo, support)
            if nw is not None and (nl := model.factor(nw)) is not None:
                w, lo = nw, nl
                continue
        else:
            prev_support = key
        j = int(np.argmax(g))
        k = support[int(np.argmin(g[support]))]
        if g[j] - gw >= gw - g[k] or w[k] >= 1.0:  # toward the best vertex
            d = -w.copy()
            d[j] += 1.0
            t = model.line_search(lo, d, 1.0)
        else:  # away from the worst vertex in the support
            d = w.copy()
            d[k] -= 1.0
            t = model.line_search(lo, d, w[k] / (1.0 - w[k]))
        if t <= 0.0:
            return None
        w = np.maximum(w + t * d, 0.0)
        w[w < _ZERO_WEIGHT] = 0.0
        w /= w.sum()
        lo = model.factor(w)
        if lo is None:
            return None
    return None
