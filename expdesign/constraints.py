"""Linear resource constraints on a design's time fractions (Ljungberg 2022, ch. 7): bounds per
primitive and cost budgets, with their feasibility check, the support function used by the
convex certificate and the projection onto the feasible set. Used by :mod:`expdesign.dopt`. Every design's
SLSQP runs through :func:`minimize_slsqp` (one BLAS thread: the same bits whatever the thread count)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from expdesign.errors import DesignError
from primitives.threads import one_blas_thread


@dataclass
class Constraints:
    """Linear resource constraints on the fractions w: sum w = 1, lo <= w <= hi, A w <= b.

    A cost budget (distance, fuel) per trial becomes a row ``trial_length_s * rate_q`` of A with
    bound ``budget``: sum_q w_q T rate_q <= budget.
    """

    lo: np.ndarray
    hi: np.ndarray
    A: np.ndarray
    b: np.ndarray
    labels: list[str] = field(default_factory=list)

    @classmethod
    def build(
        cls,
        names: list[str],
        min_frac: float | dict[str, float] | None = None,
        max_frac: float | dict[str, float] | None = None,
        costs: dict[str, dict[str, float]] | None = None,
        budgets: dict[str, float] | None = None,
        trial_length_s: float | None = None,
    ) -> Constraints:
        """``costs`` maps a resource (e.g. 'distance_m') to per-second rates by primitive name,
        ``budgets`` maps it to the limit for the whole trial of ``trial_length_s`` seconds."""
        q = len(names)

        def vec(v, default, what):
            if v is None:
                return np.full(q, default)
            if isinstance(v, dict):
                unknown = sorted(set(v) - set(names))
                if unknown:
                    raise DesignError(f"{what} names unknown primitives {unknown}; the library has {names}")
                return np.array([float(v.get(n, default)) for n in names])
            return np.full(q, float(v))

        lo, hi = vec(min_frac, 0.0, "min_frac"), vec(max_frac, 1.0, "max_frac")
        if np.any(lo < 0) or np.any(hi > 1) or np.any(lo > hi):
            bad = [n for n, a, c in zip(names, lo, hi) if a < 0 or c > 1 or a > c]
            raise DesignError(f"infeasible constraints: fractions of {bad} need 0 <= min_frac <= max_frac <= 1")
        rows, bs, labels = [], [], []
        for res, rates in (costs or {}).items():
            if budgets is None or res not in budgets:
                raise DesignError(f"cost {res!r} has per-primitive rates but no budget; add budgets[{res!r}]")
            if not trial_length_s or trial_length_s <= 0:
                raise DesignError("a cost budget needs trial_length_s > 0 (seconds) to turn fractions into costs")
            rows.append(float(trial_length_s) * vec(rates, 0.0, f"costs[{res!r}]"))
            bs.append(float(budgets[res]))
            labels.append(res)
        A = np.array(rows).reshape(-1, q)
        c = cls(lo, hi, A, np.array(bs), labels)
        c.check(names)
        return c

    @classmethod
    def simplex(cls, q: int) -> Constraints:
        return cls(np.zeros(q), np.ones(q), np.zeros((0, q)), np.zeros(0))

    @property
    def is_simplex(self) -> bool:
        return not self.A.size and not self.lo.any() and np.all(self.hi >= 1)

    def check(self, names: list[str]) -> None:
        """Raise a DesignError naming the conflict when no fractions satisfy the constraints."""
        if self.lo.sum() > 1 + 1e-9:
            raise DesignError(f"infeasible constraints: the minimum fractions add up to {self.lo.sum():.3g} > 1; lower min_frac")
        if self.hi.sum() < 1 - 1e-9:
            raise DesignError(f"infeasible constraints: the maximum fractions add up to {self.hi.sum():.3g} < 1; raise max_frac")
        if self.A.size:
            from scipy.optimize import linprog  # only constrained designs: not imported by every plan

            # the mixes: fractions within their bounds summing to 1; one budget's cheapest mix says what it needs
            mixes = dict(A_eq=np.ones((1, len(names))), b_eq=[1.0], bounds=list(zip(self.lo, self.hi)), method="highs")
            r = linprog(np.zeros(len(names)), A_ub=self.A, b_ub=self.b, **mixes)
            if r.status != 0:
                cheapest = [float(self.A[i] @ linprog(self.A[i], **mixes).x) for i in range(len(self.b))]
                detail = ", ".join(f"{lab}: needs >= {c:.4g}, budget {b:.4g}" for lab, c, b in zip(self.labels, cheapest, self.b))
                raise DesignError(
                    f"infeasible constraints: no mix meets the budgets ({detail}); raise a budget or shorten the trial"
                )

    def feasible(self, w: np.ndarray, tol: float = 1e-6) -> bool:
        return bool(
            abs(w.sum() - 1) < tol
            and np.all(w >= self.lo - tol)
            and np.all(w <= self.hi + tol)
            and (not self.A.size or np.all(self.A @ w <= self.b + tol * (1 + np.abs(self.b))))
        )

    def max_linear(self, g: np.ndarray) -> float:
        """max g.w over the feasible set (a linear program; the vertex max_q g_q on the simplex)."""
        if self.is_simplex:
            return float(np.max(g))
        from scipy.optimize import linprog

        r = linprog(
            -g,
            A_ub=self.A if self.A.size else None,
            b_ub=self.b if self.A.size else None,
            A_eq=np.ones((1, len(g))),
            b_eq=[1.0],
            bounds=list(zip(self.lo, self.hi)),
            method="highs",
        )
        return float(-r.fun)

    def project(self, w0: np.ndarray) -> np.ndarray:
        """Nearest feasible point (Euclidean) to w0."""
        w = np.clip(w0, self.lo, self.hi)
        w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))
        if self.feasible(w):
            return w
        cons = [{"type": "eq", "fun": lambda x: x.sum() - 1.0, "jac": lambda x: np.ones_like(x)}]
        if self.A.size:
            cons.append({"type": "ineq", "fun": lambda x: self.b - self.A @ x, "jac": lambda x: -self.A})
        r = minimize_slsqp(
            lambda x: 0.5 * np.sum((x - w0) ** 2),
            w,
            jac=lambda x: x - w0,
            bounds=list(zip(self.lo, self.hi)),
            constraints=cons,
            options={"maxiter": 200, "ftol": 1e-12},
        )
        return np.clip(r.x, self.lo, self.hi)


def minimize_slsqp(fun: Callable[..., Any], x0: np.ndarray, **options: Any) -> Any:
    """``scipy.optimize.minimize(fun, x0, method="SLSQP", **options)`` on one BLAS thread: every design's
    SLSQP (local, robust, :meth:`Constraints.project`'s). SLSQP's own products run on scipy's OpenBLAS and
    round differently with its thread count, which the environment (``OMP_NUM_THREADS``,
    ``OPENBLAS_NUM_THREADS``) and the machine's cores set: the first design's weights were 1e-13 apart on one
    and on two threads for the default ship, 1.2e-7 for kvlcc2 (stop 59), so a design kept in the move cache by a run on one
    thread was not the one a run on two made. On one thread the same inputs give the same bits in every
    process and on every machine of a kind (:func:`maps.movecache.machine`). The problems are a few dozen
    weights: one thread is no slower (the default ship's first design, 5 alternated pairs in one process at
    load 5: 0.037-0.062 s of CPU on one thread, 0.043-0.068 s on two)."""
    from scipy.optimize import minimize  # before the limit: it loads scipy's BLAS, which the limit must find

    with one_blas_thread():
        return minimize(fun, x0, method="SLSQP", **options)
