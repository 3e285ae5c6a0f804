"""Non-convex design (7.57): instrument mean subtracted over the whole experiment (7.20).

``max log|det(T - S Zbar^T)|`` over the fractions w with T = sum w_q X_q, S = sum w_q Y_q,
Zbar = sum w_q Z_q / sum w_q (7.56), block-diagonal, plus a prior term (7.58). The thesis solved
it with fmincon from equal shares; here scipy SLSQP with the analytic gradient

    d/dw_q log|det Gamma| = tr(Gamma^-1 dGamma/dw_q),
    dGamma/dw_q = X_q - Y_q Zbar^T - S (Z_q - Zbar)^T / sum(w),

runs from the convex solution, equal shares and seeded random points, and the best point seen
(end points and starts alike) is returned, so the result is never worse than any start.
For criteria A and E the objective is evaluated on the symmetric part of the scaled Gamma.
"""

from __future__ import annotations

import numpy as np

from expdesign.constraints import minimize_slsqp
from expdesign.dopt import Constraints, InfoSet, SolveResult

_BAD = 1e6


def _objective(info: InfoSet, criterion: str, mean_subtraction: str):
    mask = info.mask
    sc = np.outer(info.scale, info.scale)
    offset = 2 * np.log(info.scale).sum()

    def fg(w: np.ndarray) -> tuple[float, np.ndarray]:
        if criterion != "D":
            v = info.value(w, mean_subtraction, criterion)
            if not np.isfinite(v):
                return _BAD, np.zeros_like(w)
            eps = 1e-7
            g = np.array([(info.value(w + eps * e, mean_subtraction, criterion) - v) / eps for e in np.eye(len(w))])
            return -v, -np.nan_to_num(g)
        gam = info.gamma(w, mean_subtraction)
        gs = gam * sc
        sign, ld = np.linalg.slogdet(gs)
        if sign == 0 or not np.isfinite(ld):
            return _BAD, np.zeros_like(w)
        ginv_t = (np.linalg.inv(gs) * sc).T  # (Gamma^-1)^T of the unscaled Gamma
        if mean_subtraction == "complete":
            S = w @ info.Y
            zsum, wsum = w @ info.Z, w.sum()
            if info.X0 is not None:
                S, zsum, wsum = S + info.a * info.Y0, zsum + info.a * info.Z0, wsum + info.a
            zbar = zsum / wsum
            d = info.X - (np.einsum("qi,j->qij", info.Y, zbar) + np.einsum("i,qj->qij", S, info.Z - zbar) / wsum) * mask
        else:
            d = info.per_primitive(mean_subtraction)
        g = np.einsum("ij,qij->q", ginv_t, d)
        return -(ld - offset), -g

    return fg


def solve_nonconvex(
    info: InfoSet,
    constraints: Constraints | None = None,
    *,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    convex_start: np.ndarray | None = None,
    n_random: int = 4,
    seed: int = 0,
    maxiter: int = 300,
) -> SolveResult:
    """(7.57) by multi-start SLSQP; ``starts`` lists each start's objective before and after."""
    q = len(info.names)
    cons = constraints or Constraints.simplex(q)
    fg = _objective(info, criterion, mean_subtraction)
    rng = np.random.default_rng(seed)
    starts: list[tuple[str, np.ndarray]] = []
    if convex_start is not None:
        starts.append(("convex", np.asarray(convex_start, float)))
    starts.append(("equal", np.full(q, 1.0 / q)))
    starts += [(f"random-{i + 1}", rng.dirichlet(np.ones(q))) for i in range(n_random)]
    c_list = [{"type": "eq", "fun": lambda x: x.sum() - 1.0, "jac": lambda x: np.ones_like(x)}]
    if cons.A.size:
        c_list.append({"type": "ineq", "fun": lambda x: cons.b - cons.A @ x, "jac": lambda x: -cons.A})
    bounds = list(zip(cons.lo, cons.hi))
    best_w, best_f, winner, report = None, np.inf, None, []
    for name, w0 in starts:
        w0 = cons.project(w0)
        f0 = fg(w0)[0]
        r = minimize_slsqp(fg, w0, jac=True, bounds=bounds, constraints=c_list, options={"maxiter": maxiter, "ftol": 1e-10})
        w1 = cons.project(np.clip(r.x, cons.lo, cons.hi))
        f1 = fg(w1)[0]
        for cand, fc, tag in ((w0, f0, name), (w1, f1, name)):
            if fc < best_f - 1e-12 and cons.feasible(cand):
                best_w, best_f, winner = cand, fc, tag
        report.append(
            {
                "start": name,
                "start_objective": float(-f0) if f0 < _BAD else None,
                "end_objective": float(-f1) if f1 < _BAD else None,
                "iterations": int(r.nit),
                "success": bool(r.success),
            }
        )
    what = "(7.57)" if mean_subtraction == "complete" else f"log|det Gamma| ({mean_subtraction})"
    notes = [f"{what} solved by SLSQP from {len(starts)} starts; best start: {winner}"]
    if best_w is None:
        best_w, winner = cons.project(np.full(q, 1.0 / q)), "equal"
        notes.append("every start gave a singular Gamma; returned equal shares")
    return SolveResult(best_w, float(-best_f) if best_f < _BAD else -np.inf, "scipy-SLSQP", notes, starts=report, winner=winner)
