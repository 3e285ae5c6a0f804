"""Robust dictionary designs over parameter draws: Bayesian and maximin D-optimality.

The information of a primitive depends on the ship's parameters: the states it produces, hence
its regressors, change with theta. For draws theta_1 .. theta_K (:mod:`expdesign.prior`) every
primitive's inputs are replayed with each draw (one batched simulation per primitive) and

    M_q(theta_k) = mean Phi Phi^T - (mean Phi)(mean Phi)^T   (batchwise, (7.53); X_q alone for 'none')

within the DOF blocks: the IV information (7.50)-(7.53) when the instruments have converged to
the regressors of the ship as it is (the iterated IV simulates its instruments with its estimate),
so M_q is symmetric positive semi-definite and every criterion below is concave in the fractions
w. The whole-experiment subtraction (7.57) is relaxed to (7.53), as in the local design's convex
step. The library's inputs are fixed: a zig-zag whose rudder switches on the nominal ship's
heading is replayed, not re-steered, for each draw.

* local-D: the design ``--criterion D`` produces (expdesign.api: the profile's values, its own
  instruments and mean subtraction), scored on the draws' matrices beside the robust mix.
* bayes-D: max (1/K) sum_k log det M(w; theta_k) (Chaloner & Verdinelli 1995, section 2.2: the
  expected log det over the prior; a sum of concave functions, still convex to solve).
* maximin-D: max min_k eff_k(w), eff_k(w) = (det M(w; theta_k) / det M(w_k*; theta_k))^(1/p) with
  w_k* the D-optimal mix at theta_k (Pronzato & Walter 1988, "Robust experiment design via
  maximin optimization"); in epigraph form max t s.t. (log det M(w; theta_k) - log det M(w_k*;
  theta_k)) / p >= t for every k: concave constraints, a convex program.

Each draw's own optimum w_k* comes from the multiplicative algorithm (Silvey, Titterington &
Torsney 1978) run on all draws at once, to a D-efficiency certificate p / max_q tr(M^-1 M_q) of
1 - 1e-4 or better; the efficiencies reported are against it. The robust programs are solved by
SLSQP with analytic gradients d log det M / d w_q = tr(M^-1 M_q) under the design's linear
constraints; bayes-D carries the certificate p / max_w' g.w' (g the mean gradient; AM-GM and Jensen).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from expdesign.constraints import minimize_slsqp
from expdesign.dopt import ROBUST, Constraints
from expdesign.errors import DesignError
from expdesign.prior import ParameterPrior
from primitives import jitloop
from primitives.library import Primitive
from primitives.regkernel import block_moments
from primitives.regressors import regressor_signals, signal_regressors
from primitives.ship import ShipProfile
from primitives.simulate import signals_read, simulate

OPTIMUM_TOL = 1e-4  # each draw's own optimum to a D-efficiency certificate of 1 - this
_MAX_MULTIPLICATIVE = 20_000
_EXPLODED = 1e6  # a draw whose states exceed this many times the nominal ones has diverged


@dataclass
class DrawInformation:
    """Symmetric information matrices of the primitives ``names`` at the profile's values
    (``centre`` (Q, p, p)) and at each kept draw (``M`` (K, Q, p, p)), each draw scaled by its own
    uniform-mix diagonal (log det shifts by a constant per draw, which no efficiency sees);
    ``optimum`` (K,): log det of each draw's own D-optimal mix; ``dropped``: draws left out and why."""

    names: list[str]
    centre: np.ndarray
    M: np.ndarray
    optimum: np.ndarray
    optimum_bound: float
    dropped: list[str] = field(default_factory=list)
    held_out: DrawInformation | None = None  # the same primitives at fresh draws, for scoring

    @property
    def evaluated_on(self) -> str:
        """Which draws :meth:`score` reports on, for the report."""
        if self.held_out is not None:
            return f"held out: {self.held_out.n_draws} fresh draws from an independent seed stream"
        return f"in-sample: the {self.n_draws} draws the robust mix was optimised on (a file's fixed draws)"

    def score(self, w: np.ndarray) -> dict[str, float]:
        """:meth:`summary` on the held-out draws when there are, else in-sample."""
        return (self.held_out or self).summary(w)

    @property
    def n_params(self) -> int:
        return self.M.shape[-1]

    @property
    def n_draws(self) -> int:
        return self.M.shape[0]

    def logdets(self, w: np.ndarray) -> np.ndarray:
        """log det M(w; theta_k) (K,), -inf where singular."""
        sign, ld = np.linalg.slogdet(np.einsum("q,kqij->kij", np.asarray(w, float), self.M))
        return np.where(sign > 0, ld, -np.inf)

    def efficiencies(self, w: np.ndarray) -> np.ndarray:
        """D-efficiency of the mix w at every draw against that draw's own optimum (K,)."""
        return np.exp((self.logdets(w) - self.optimum) / self.n_params)

    def value(self, w: np.ndarray, mean_subtraction: str | None = None, criterion: str = "bayes-D") -> float:
        """The robust criterion (``mean_subtraction`` is fixed by the matrices; accepted so this
        object stands where an :class:`expdesign.dopt.InfoSet` does): bayes-D, mean log det;
        maximin-D, min_k (log det M(w; theta_k) - optimum_k), p log of the worst efficiency;
        local-D, log det at the profile's values."""
        if criterion == "D":
            sign, ld = np.linalg.slogdet(np.einsum("q,qij->ij", np.asarray(w, float), self.centre))
            return float(ld) if sign > 0 else -np.inf
        if criterion not in ROBUST:
            raise DesignError(f"criterion over parameter draws must be D, bayes-D or maximin-D, got {criterion!r}")
        ld = self.logdets(w)
        return float(ld.mean()) if criterion == "bayes-D" else float(np.min(ld - self.optimum))

    def subset(self, keep: list[int]) -> DrawInformation:
        """The same draws for the primitives ``keep`` only; efficiencies stay against the whole
        library's optimum (what a mix of fewer manoeuvres loses shows)."""
        idx = np.asarray(keep, int)
        return DrawInformation(
            [self.names[i] for i in idx],
            self.centre[idx],
            self.M[:, idx],
            self.optimum,
            self.optimum_bound,
            list(self.dropped),
            None if self.held_out is None else self.held_out.subset(keep),
        )

    def restrict(self, keep: np.ndarray) -> DrawInformation:
        """The same draws and primitives for the parameters ``keep`` (a boolean mask) only, the
        others held at known values: each matrix's principal submatrix (the held regressors move to
        the left-hand side, no Schur complement), each draw's own optimum found again over those."""
        ix = np.flatnonzero(keep)
        sub = np.ix_(ix, ix)
        m = np.ascontiguousarray(self.M[:, :, sub[0], sub[1]])
        opt_w, bound = draw_optima(m)
        optimum = np.linalg.slogdet(np.einsum("kq,kqij->kij", opt_w, m))[1]
        held_out = None if self.held_out is None else self.held_out.restrict(keep)
        centre = self.centre[:, sub[0], sub[1]]
        return DrawInformation(list(self.names), centre, m, optimum, bound, list(self.dropped), held_out)

    def summary(self, w: np.ndarray) -> dict[str, float]:
        """Median, 10th percentile and minimum of the D-efficiency over the draws."""
        e = self.efficiencies(w)
        return {"median": float(np.median(e)), "p10": float(np.percentile(e, 10)), "min": float(e.min())}


def _moment_matrices(phi: np.ndarray, blocks: list[slice], mean_subtraction: str) -> np.ndarray:
    """(B, p, p) mean Phi Phi^T within the DOF ``blocks`` (zero between them, as the block-diagonal
    predictor's X), minus mean Phi mean Phi^T within them unless 'none'."""
    n, p = phi.shape[1], phi.shape[2]
    x = np.zeros((phi.shape[0], p, p))
    mu = phi.mean(axis=1)
    for s in blocks:  # only the blocks: a third of the products of the full Phi^T Phi for three equal DOFs
        f = phi[:, :, s]
        x[:, s, s] = np.matmul(np.swapaxes(f, 1, 2), f) / n
        if mean_subtraction != "none":
            x[:, s, s] -= mu[:, s, None] * mu[:, None, s]
    return 0.5 * (x + np.swapaxes(x, 1, 2))


def _draw_moments(
    profile: ShipProfile, nu: np.ndarray, inputs: np.ndarray, psi: np.ndarray | None, blocks: list[slice], mean_subtraction: str
) -> np.ndarray:
    """:func:`_moment_matrices` of the predictor's regressors of ``nu`` (B, N+1, 3): summed in one
    compiled pass that never stores Phi when the compiled code is loaded (:func:`primitives.regkernel.block_moments`;
    for kvlcc2's library at 201 draws Phi is about 400 MB), else from Phi. The two differ by the
    order of the sums only (tests/test_robust_speed.py)."""
    sig, shape = regressor_signals(profile, nu, inputs, psi)
    sums = block_moments(profile.predictor, sig, shape, blocks)
    if sums is None:  # the signals already built, Phi from them
        return _moment_matrices(signal_regressors(profile.predictor, sig, shape), blocks, mean_subtraction)
    xx, ss = sums
    n = shape[-1]
    x, mu = xx / n, ss / n
    if mean_subtraction != "none":
        for s in blocks:
            x[:, s, s] -= mu[:, s, None] * mu[:, None, s]
    return x


def draw_information(
    profile: ShipProfile,
    primitives: list[Primitive],
    prior: ParameterPrior,
    mean_subtraction: str = "batchwise",
    held_out: bool = False,
) -> DrawInformation:
    """The matrices of every primitive at the profile's values and at each draw (module doc):
    one simulation of each primitive's inputs batched over the draws. Draws whose simulation
    diverges, or at which the library as a whole cannot identify the model, are left out (said in
    ``dropped``); a DesignError when fewer than half are left. ``held_out``: also the matrices at
    as many fresh draws of the prior (:meth:`ParameterPrior.held_out`), to score the mixes on."""
    fresh = prior.held_out() if held_out else None
    evaluation = None if fresh is None else draw_information(profile, primitives, fresh, mean_subtraction)
    thetas = np.vstack([prior.centre[None], prior.draws])
    b = thetas.shape[0]
    blocks = [profile.predictor.dof_slice(i) for i in range(profile.predictor.n_dof)]
    heading = "psi" in signals_read(profile.predictor) or "psi" in signals_read(profile.model)
    mats, ok = [], np.ones(b, bool)
    for prim in primitives:
        with np.errstate(all="ignore"):
            res = simulate(
                profile, prim.inputs, thetas, nu0=np.tile(np.asarray(prim.nu0, float), (b, 1)), batch=b, positions=heading
            )
            scale = max(float(np.abs(res.nu[0]).max()), 1e-9)
            ok &= np.isfinite(res.nu).all(axis=(1, 2)) & (np.abs(res.nu).max(axis=(1, 2)) < _EXPLODED * scale)
            nu = np.where(ok[:, None, None], res.nu, 0.0)
            psi = np.where(ok[:, None], res.eta[..., 2], 0.0) if heading else None
            mats.append(
                _draw_moments(profile, nu, np.broadcast_to(prim.inputs, (b,) + prim.inputs.shape), psi, blocks, mean_subtraction)
            )
    m = np.stack(mats, axis=1)  # (B, Q, p, p)
    if not ok[0]:
        raise DesignError(f"ship {profile.name!r}: the library's simulation at the profile's values diverges; check the profile")
    d = np.sqrt(np.abs(np.einsum("bqii->bi", m)) / m.shape[1])
    d = np.where(d > 0, d, 1.0)
    m = m / (d[:, None, :, None] * d[:, None, None, :])
    ev = np.linalg.eigvalsh(m.mean(axis=1))  # of the equal-shares mix, once
    live = ev[:, 0] > 1e-12 * np.maximum(np.abs(ev[:, -1]), 1e-300)
    dropped = []
    if (~ok[1:]).any():
        dropped.append(f"{int((~ok[1:]).sum())} draw(s) whose simulation diverges")
    if (ok[1:] & ~live[1:]).any():
        dropped.append(f"{int((ok[1:] & ~live[1:]).sum())} draw(s) at which the library cannot identify every parameter")
    keep = ok[1:] & live[1:]
    if keep.sum() < max(2, b // 2):
        raise DesignError(
            f"only {int(keep.sum())} of {b - 1} parameter draws give a usable ship ({'; '.join(dropped)}): narrow the prior"
        )
    centre_w, _ = draw_optima(m[:1])
    # the draws' optima lie near the profile's: started there (every share kept positive) they
    # converge in a fraction of the iterations equal shares need
    opt_w, bound = draw_optima(m[1:][keep], start=0.5 * centre_w[0] + 0.5 / m.shape[1])
    optimum = np.linalg.slogdet(np.einsum("kq,kqij->kij", opt_w, m[1:][keep]))[1]
    return DrawInformation([p.name for p in primitives], m[0], m[1:][keep], optimum, bound, dropped, evaluation)


def draw_optima(m: np.ndarray, tol: float = OPTIMUM_TOL, start: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """D-optimal fractions (K, Q) of every draw's matrices ``m`` (K, Q, p, p) on the simplex by the
    multiplicative algorithm w_q <- w_q tr(M^-1 M_q) / p, all draws at once (a draw leaves the
    batch once certified), and the worst D-efficiency certificate p / max_q tr(M^-1 M_q) reached
    (module doc). ``start`` (Q,), all positive (the algorithm never revives a zero weight): the
    first fractions of every draw, default equal shares. Once numba is loaded the same iterations run
    draw by draw in machine code (:func:`_optima_compiled`; the sums in another order, rounding only)."""
    k, q, p = m.shape[0], m.shape[1], m.shape[2]
    w = np.tile(np.full(q, 1.0 / q) if start is None else np.asarray(start, float) / np.sum(start), (k, 1))
    bound = np.zeros(k)
    if jitloop.loaded():  # draw by draw in machine code (no per-iteration gathering and calls): the same steps
        w_c = w.copy()
        _optima_compiled(np.ascontiguousarray(m, float), w_c, float(tol), _MAX_MULTIPLICATIVE, bound)
        if not np.isnan(bound).any():
            return w_c, float(bound.min())
    active = np.arange(k)
    # M(w) and tr(M^-1 M_q) as products with the flattened matrices (tr(A M_q) = sum A_ij (M_q)_ij for
    # a symmetric M_q); the draws still active are gathered only when one leaves
    ma, wa = m.reshape(k, q, p * p), w.copy()
    for _ in range(_MAX_MULTIPLICATIVE):
        mw = (wa[:, None, :] @ ma)[:, 0].reshape(-1, p, p)
        g = (ma @ np.linalg.inv(mw).reshape(-1, p * p, 1))[..., 0]
        bound[active] = p / g.max(axis=1)
        left = bound[active] < 1.0 - tol
        wa = wa * g / p
        wa /= wa.sum(axis=1, keepdims=True)
        w[active[left]] = wa[left]
        if not left.all():
            active, ma, wa = active[left], ma[left], wa[left]
        if not active.size:
            break
    return w, float(bound.min())


@jitloop.compiled
def _optima_compiled(m, w, tol, max_iter, bound):
    """:func:`draw_optima`'s iterations for one draw after another, in place on ``w`` (K, Q) and
    ``bound`` (K,); M(w)^-1 by Cholesky (M(w) is positive definite while the library identifies the model;
    a draw where it is not gets a NaN bound)."""
    k, q, p = m.shape[0], m.shape[1], m.shape[2]
    a = np.empty((p, p))
    inv = np.empty((p, p))
    g = np.empty(q)
    for d in range(k):
        for _ in range(max_iter):
            for i in range(p):  # M(w), lower triangle
                for c in range(i + 1):
                    acc = 0.0
                    for j in range(q):
                        acc += w[d, j] * m[d, j, i, c]
                    a[i, c] = acc
            singular = False
            for c in range(p):  # Cholesky M = L L^T in place (lower triangle)
                x = a[c, c]
                for t in range(c):
                    x -= a[c, t] * a[c, t]
                if not x > 0.0:
                    singular = True
                    break
                x = math.sqrt(x)
                a[c, c] = x
                for i in range(c + 1, p):
                    y = a[i, c]
                    for t in range(c):
                        y -= a[i, t] * a[c, t]
                    a[i, c] = y / x
            if singular:  # the caller runs the numpy iterations, which say so
                bound[d] = math.nan
                break
            for c in range(p):  # M^-1 column by column: L y = e_c, L^T x = y
                for i in range(p):
                    y = 1.0 if i == c else 0.0
                    for t in range(i):
                        y -= a[i, t] * inv[t, c]
                    inv[i, c] = y / a[i, i]
                for i in range(p - 1, -1, -1):
                    y = inv[i, c]
                    for t in range(i + 1, p):
                        y -= a[t, i] * inv[t, c]
                    inv[i, c] = y / a[i, i]
            top = 0.0
            for j in range(q):  # tr(M^-1 M_q)
                acc = 0.0
                for i in range(p):
                    for c in range(p):
                        acc += inv[i, c] * m[d, j, i, c]
                g[j] = acc
                top = max(top, acc)
            bound[d] = p / top
            if bound[d] >= 1.0 - tol:
                break
            total = 0.0
            for j in range(q):
                w[d, j] *= g[j] / p
                total += w[d, j]
            for j in range(q):
                w[d, j] /= total


def _gradients(m: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """log det M(w; theta_k) (K,) and d/dw_q (K, Q), for matrices (K, Q, p, p); -inf and 0 where singular."""
    mw = np.einsum("q,kqij->kij", w, m)
    sign, ld = np.linalg.slogdet(mw)
    good = sign > 0
    g = np.zeros(m.shape[:2])
    if good.any():
        g[good] = np.einsum("kij,kqji->kq", np.linalg.inv(mw[good]), m[good])
    return np.where(good, ld, -np.inf), g


@dataclass
class RobustSolution:
    """Fractions, the solver and its notes, and for bayes-D the
    concavity certificate (a lower bound on the D-efficiency against its optimum)."""

    weights: np.ndarray
    solver: str
    notes: list[str]
    efficiency_bound: float | None = None


_FLOOR = -1e3  # log det given to a singular mix inside SLSQP (a finite number it can step away from)


def solve_robust(info: DrawInformation, criterion: str, cons: Constraints, start: np.ndarray | None = None) -> RobustSolution:
    """bayes-D or maximin-D (module doc) from ``start`` (default equal shares, projected)."""
    if criterion not in ROBUST:
        raise DesignError(f"robust criterion must be one of {list(ROBUST)}, got {criterion!r}")
    q = len(info.names)
    w0 = cons.project(np.full(q, 1.0 / q) if start is None else np.asarray(start, float))
    bayes = _solve_bayes(info.M, cons, w0, "bayes-D")
    if criterion == "bayes-D":
        return bayes
    return _solve_maximin(info, cons, [w0, bayes.weights])


def _slsqp_constraints(cons: Constraints, n_extra: int = 0) -> list[dict]:
    pad = np.zeros(n_extra)
    out = [{"type": "eq", "fun": lambda x: x[: len(cons.lo)].sum() - 1.0, "jac": lambda x: np.r_[np.ones(len(cons.lo)), pad]}]
    if cons.A.size:
        out.append(
            {
                "type": "ineq",
                "fun": lambda x: cons.b - cons.A @ x[: len(cons.lo)],
                "jac": lambda x: np.hstack([-cons.A, np.zeros((cons.A.shape[0], n_extra))]),
            }
        )
    return out


def _solve_bayes(m: np.ndarray, cons: Constraints, w0: np.ndarray, label: str) -> RobustSolution:
    """max mean_k log det M(w; theta_k) by SLSQP, with the concavity certificate."""

    def f(w: np.ndarray) -> tuple[float, np.ndarray]:
        ld, g = _gradients(m, np.clip(w, 0.0, None))
        ld = np.where(np.isfinite(ld), ld, _FLOOR)
        return -float(ld.mean()), -g.mean(axis=0)

    r = minimize_slsqp(
        f,
        w0,
        jac=True,
        bounds=list(zip(cons.lo, cons.hi)),
        constraints=_slsqp_constraints(cons),
        options={"maxiter": 500, "ftol": 1e-12},
    )
    w = cons.project(np.clip(r.x, cons.lo, cons.hi))
    w = np.where(w < 1e-7, 0.0, w)
    w /= w.sum()
    ld, g = _gradients(m, w)
    grad = g.mean(axis=0)
    # Phi* - Phi(w) <= mean_k p log(tr(M_k(w)^-1 M_k(w*)) / p) (AM-GM) <= p log(g.w* / p) (Jensen)
    # <= p log(max_feasible g.w' / p): efficiency >= p / max g.w', tighter than exp(-(max - p) / p)
    top = cons.max_linear(grad)
    notes = [] if r.success else [f"SLSQP stopped early ({r.message})"]
    bound = float(min(1.0, m.shape[-1] / top)) if np.all(np.isfinite(ld)) and top > 0 else None
    return RobustSolution(w, f"{label}: SLSQP", notes, bound)


def _solve_maximin(info: DrawInformation, cons: Constraints, starts: list[np.ndarray]) -> RobustSolution:
    """max t s.t. (log det M(w; theta_k) - optimum_k) / p >= t (epigraph form) by SLSQP from the
    best of ``starts``; the best point seen is returned (the worst efficiency never falls)."""
    p, q = info.n_params, len(info.names)

    def worst(w: np.ndarray) -> float:
        return float(np.min(info.logdets(w) - info.optimum)) / p

    w0 = max(starts, key=worst)

    def margins(x: np.ndarray) -> np.ndarray:
        ld, _ = _gradients(info.M, np.clip(x[:q], 0.0, None))
        return np.where(np.isfinite(ld), ld, _FLOOR) / p - info.optimum / p - x[q]

    def margins_jac(x: np.ndarray) -> np.ndarray:
        _, g = _gradients(info.M, np.clip(x[:q], 0.0, None))
        return np.hstack([g / p, -np.ones((info.n_draws, 1))])

    r = minimize_slsqp(
        lambda x: (-x[q], np.r_[np.zeros(q), -1.0]),
        np.r_[w0, worst(w0)],
        jac=True,
        bounds=list(zip(cons.lo, cons.hi)) + [(None, None)],
        constraints=[{"type": "ineq", "fun": margins, "jac": margins_jac}, *_slsqp_constraints(cons, 1)],
        options={"maxiter": 500, "ftol": 1e-12},
    )
    w = cons.project(np.clip(r.x[:q], cons.lo, cons.hi))
    w = np.where(w < 1e-7, 0.0, w)
    w /= w.sum()
    notes = [] if r.success else [f"SLSQP stopped early ({r.message})"]
    if worst(w) < worst(w0):
        notes.append("SLSQP ended below its start; the start (the bayes-D mix or equal shares) is returned")
        w = w0
    return RobustSolution(w, "maximin-D: SLSQP (epigraph form)", notes, None)


@dataclass
class RobustDesign:
    """What :func:`expdesign.api.run_design` needs of a robust design: the fractions, the
    criterion's efficiency bound, its certificate record and the report section (each design's
    D-efficiency over the draws, the local and robust mixes side by side)."""

    weights: np.ndarray
    efficiency_bound: float | None
    certificate: dict
    section: dict
    notes: list[str]


def robust_design(
    info: DrawInformation,
    criterion: str,
    cons: Constraints,
    prior: ParameterPrior,
    mean_subtraction: str,
    local_weights: np.ndarray,
) -> RobustDesign:
    """The robust mix started from ``local_weights`` and the report section, where both are scored
    on the draws. ``local_weights``: the mix ``--criterion D`` designs with the same options (its
    own information, instruments and mean subtraction, with the refinement the local design runs),
    the design a user compares with, not a local-D optimum of the draws' relaxed matrices."""
    local_weights = np.asarray(local_weights, float)
    sol = solve_robust(info, criterion, cons, local_weights)
    relaxed = "batchwise (7.53)" if mean_subtraction == "complete" else mean_subtraction
    notes = [
        f"{criterion} over {info.n_draws} parameter draws ({prior.source}); information of the converged IV "
        f"(instruments = regressors of each draw), {relaxed} mean subtraction; {sol.solver}",
        *[f"parameter draws left out: {d}" for d in info.dropped],
        *sol.notes,
    ]
    section = {
        "criterion": criterion,
        "prior": prior.to_dict(),
        "draws_used": info.n_draws,
        "dropped": list(info.dropped),
        "mean_subtraction": relaxed,
        "optimum_certificate": info.optimum_bound,
        "local_weights": {n: float(w) for n, w in zip(info.names, local_weights)},
        "evaluated_on": info.evaluated_on,
        "d_efficiency": {"local-D": info.score(local_weights), criterion: info.score(sol.weights)},
    }
    certificate = {
        "criterion": criterion,
        "n_params": info.n_params,
        "efficiency_bound": sol.efficiency_bound,
        "relaxation": f"symmetric information of the converged IV, {relaxed} mean subtraction",
    }
    return RobustDesign(sol.weights, sol.efficiency_bound, certificate, section, notes)
