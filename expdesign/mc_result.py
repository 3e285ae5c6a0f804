"""Per-run results of a Monte Carlo evaluation and what is read off them (Ljungberg 2022, section 9.1.2).

Metrics of one run (section 9.1.2): the normalized parameter error
``sqrt(mean(((theta_hat - theta0) / theta0)^2))`` (Fig. 9.1, threshold 1.5) and the cross-validation
simulation error: the RMSE per DOF between the estimated model and the true system, both simulated
noise-free on a validation input unlike any primitive (Fig. 9.2), and the norm of the three (Fig. 9.3,
threshold 0.15).

A run whose estimate is not finite or whose validation simulation explodes is *diverged*: it is
counted (and fails both thresholds) but kept out of every percentile, so the percentiles are
numbers of usable models, not of overflow.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

PARAM_THRESHOLD = 1.5
SIM_THRESHOLD = 0.15
# Section 9.1.2 (text beside Figs 9.1 and 9.3): share of 500 runs below the thresholds.
THESIS_FRACTIONS = {"optimized": {"param": 0.99, "sim": 0.99}, "random": {"param": 0.46, "sim": 0.69}}


@dataclass
class MCResult:
    """Per-run results of one design, sorted by run index.

    runs (R,) run indices; theta (R, p) estimates; param_rmse (R,) normalized parameter error (NaN
    when the predictor structure differs from the true model); sim_rmse (R, 3) validation RMSE of
    u, v, r (inf for a diverged run); diverged (R,) bool; requested: runs asked for (R < requested
    for a partial result); theta0 / param_names: the true parameters the errors refer to;
    estimator: the estimator of theta ('oe', 'iv'); reference: the same runs' result with the
    thesis's estimator (IV) when ``estimator`` is another one, else None.
    """

    name: str
    runs: np.ndarray
    theta: np.ndarray
    param_rmse: np.ndarray
    sim_rmse: np.ndarray
    diverged: np.ndarray
    requested: int
    param_names: list[str] = field(default_factory=list)
    theta0: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    estimator: str = ""
    reference: MCResult | None = None

    @property
    def sim_norm(self) -> np.ndarray:
        return np.sqrt(np.sum(self.sim_rmse**2, axis=1))

    @property
    def partial(self) -> bool:
        return len(self.runs) < self.requested

    def digest(self) -> str:
        """SHA-256 of every per-run array: equal digests mean bit-identical results."""
        h = hashlib.sha256()
        for a in (self.runs.astype(np.int64), self.theta, self.param_rmse, self.sim_rmse, self.diverged.astype(np.uint8)):
            h.update(np.ascontiguousarray(a).tobytes())
        if self.reference is not None:
            h.update(self.reference.digest().encode())
        return h.hexdigest()

    def summary(self, param_threshold: float = PARAM_THRESHOLD, sim_threshold: float = SIM_THRESHOLD) -> dict[str, Any]:
        """Runs finished and diverged, medians and 90th percentiles over the runs that did not
        diverge, and the fractions of all finished runs below the thresholds (diverged = above)."""
        ok = ~self.diverged
        has_p = self.theta0 is not None
        pr, sn = self.param_rmse, self.sim_norm
        out = {
            "estimator": self.estimator,
            "runs": int(len(self.runs)),
            "runs_requested": int(self.requested),
            "partial": self.partial,
            "diverged": int(self.diverged.sum()),
            "param_rmse_p50": _pct(pr[ok], 50) if has_p else None,
            "param_rmse_p90": _pct(pr[ok], 90) if has_p else None,
            _frac_key("param", param_threshold): _frac(pr, ok, param_threshold) if has_p else None,
            "sim_rmse_p50": _pct(sn[ok], 50),
            "sim_rmse_p90": _pct(sn[ok], 90),
            _frac_key("sim", sim_threshold): _frac(sn, ok, sim_threshold),
            "sim_rmse_dof_p50": {k: _pct(self.sim_rmse[ok, i], 50) for i, k in enumerate("uvr")},
            "digest": self.digest(),
        }
        if self.reference is not None:
            out["reference"] = self.reference.summary(param_threshold, sim_threshold)
        return out

    def parameter_table(self, tolerance: float = PARAM_THRESHOLD) -> list[dict[str, Any]]:
        """Per parameter, over the runs that did not diverge: true value, bias and spread (mean
        and std of the normalized error (theta_hat - theta0)/|theta0|), median |error|, and the
        fraction of all finished runs with |error| < ``tolerance`` (diverged runs count as outside).
        Shows which parameter limits a design. Empty when theta0 is not defined."""
        if self.theta0 is None or not len(self.runs):
            return []
        ok = ~self.diverged
        with np.errstate(all="ignore"):
            err = (self.theta - self.theta0) / np.abs(self.theta0)
        rows = []
        for j, name in enumerate(self.param_names):
            e = err[ok, j]
            rows.append(
                {
                    "parameter": name,
                    "true": float(self.theta0[j]),
                    "bias": float(np.mean(e)) if e.size else None,
                    "spread": float(np.std(e)) if e.size else None,
                    "median_abs_error": float(np.median(np.abs(e))) if e.size else None,
                    "frac_within_tolerance": float(np.mean(ok & (np.abs(err[:, j]) < tolerance))),
                    "tolerance": tolerance,
                }
            )
        return rows


def _frac_key(kind: str, threshold: float) -> str:
    return f"frac_{kind}_rmse_below_{str(threshold).replace('.', '_')}"


def _frac(x: np.ndarray, ok: np.ndarray, threshold: float) -> float | None:
    return float(np.mean(ok & (x < threshold))) if len(x) else None


def _pct(x: np.ndarray, q: float) -> float | None:
    return float(np.percentile(x, q)) if len(x) else None


def merge_results(parts: list[dict[str, MCResult]]) -> dict[str, MCResult]:
    """Join chunk results (any order, designs may be missing from a chunk) into one result per
    design, sorted by run index."""
    names = list(dict.fromkeys(n for p in parts for n in p))
    out: dict[str, MCResult] = {}
    for name in names:
        rs = [p[name] for p in parts if name in p]
        runs = np.concatenate([r.runs for r in rs])
        if len(np.unique(runs)) != len(runs):
            raise ValueError(f"design {name!r}: a run appears in two chunks")
        o = np.argsort(runs, kind="stable")
        r0 = rs[0]
        refs = [r.reference for r in rs]
        if any(r is not None for r in refs) and not all(r is not None for r in refs):
            raise ValueError(f"design {name!r}: some chunks carry a reference estimate and some do not")
        out[name] = MCResult(
            name,
            runs[o],
            np.concatenate([r.theta for r in rs])[o],
            np.concatenate([r.param_rmse for r in rs])[o],
            np.concatenate([r.sim_rmse for r in rs])[o],
            np.concatenate([r.diverged for r in rs])[o],
            r0.requested,
            r0.param_names,
            r0.theta0,
            list(dict.fromkeys(n for r in rs for n in r.notes)),
            r0.estimator,
            merge_results([{name: r} for r in refs])[name] if refs[0] is not None else None,
        )
    return out
