"""Monte Carlo of designs against truths drawn from a parameter prior.

A robust design is for a ship whose parameters are not the profile's: each truth theta_t is a
draw of the prior, the project's Monte Carlo engine (:func:`expdesign.montecarlo.evaluate_designs`,
Ljungberg (2022), section 9.1.2) simulates that ship (the profile with theta_t as its simulation
set; the estimator keeps the profile's instrument set, what it knows before the trial) and scores
the estimates by the normalised parameter error sqrt(mean(((theta_hat - theta_t) / theta_t)^2)).
The truth has the estimator's own model structure with other values: evidence for a design
criterion (which information the mix collects), not for the model.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from expdesign.montecarlo import evaluate_designs
from primitives.library import Primitive
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances

TRUTH_SET = "prior-truth"
RUNS = (28, 3)  # the noise of truth t: spawn key (28, 3, t), apart from the prior's streams (expdesign.prior)


def truth_profile(profile: ShipProfile, theta: np.ndarray) -> ShipProfile:
    """The profile with ``theta`` as the parameters it simulates (its instrument set unchanged)."""
    return replace(
        profile, parameter_sets={**profile.parameter_sets, TRUTH_SET: np.asarray(theta, float)}, simulation_set=TRUTH_SET
    )


def prior_monte_carlo(
    profile: ShipProfile,
    designs: dict[str, dict[str, float]],
    truths: np.ndarray,
    runs_per_truth: int,
    seed: int = 0,
    *,
    primitives: list[Primitive] | None = None,
    disturbances: Disturbances | None = None,
    **protocol: Any,
) -> dict[str, dict[str, Any]]:
    """Per design: the parameter-error fractions of ``runs_per_truth`` noisy runs at each truth
    (T, p) (median, 90th percentile, share below 0.1 and 0.3; None when failed runs reach
    that percentile; None when the parameter error is not defined, with the engine's note), runs and
    failed runs (diverged or not finite, counted as errors of infinity; only these), and the median
    validation RMSE of u, v, r. Truth t's
    runs are seeded from (seed, RUNS + (t,)), so the designs meet the same noise at the same truth."""
    errors: dict[str, list[np.ndarray]] = {d: [] for d in designs}
    val: dict[str, list[np.ndarray]] = {d: [] for d in designs}
    notes: dict[str, set[str]] = {d: set() for d in designs}
    for t, theta in enumerate(np.atleast_2d(truths)):
        run_seed = int(np.random.SeedSequence(seed, spawn_key=(*RUNS, t)).generate_state(1)[0])
        res = evaluate_designs(
            truth_profile(profile, theta),
            designs,
            runs=runs_per_truth,
            seed=run_seed,
            primitives=primitives,
            disturbances=disturbances,
            **protocol,
        )
        for d, r in res.items():
            # a diverged fit (or a non-finite estimate, inf) is a failure, never a number; NaN is
            # "not defined" (the engine's note: the predictor's structure differs from the truth's)
            errors[d].append(np.where(r.diverged, np.inf, r.param_rmse))
            val[d].append(np.where(r.diverged[:, None], np.inf, r.sim_rmse))
            notes[d].update(n for n in r.notes if "parameter error not defined" in n)
    return {d: _summary(np.concatenate(errors[d]), np.concatenate(val[d]), len(errors[d]), sorted(notes[d])) for d in designs}


def _summary(e: np.ndarray, val: np.ndarray, truths: int, notes: list[str]) -> dict[str, Any]:
    """Percentiles of the defined parameter errors (failed runs count as infinite ones), the
    median validation RMSE of u, v, r over the runs that did not fail, and the notes."""
    failed = np.isinf(e)
    defined = e[~np.isnan(e)]
    # sample quantiles (no interpolation towards a failed run's inf, which would give NaN)
    p50, p90 = np.percentile(defined, [50, 90], method="inverted_cdf") if defined.size else (np.nan, np.nan)
    ok = val[~failed]
    return {
        "truths": truths,
        "runs": int(e.size),
        "failed": int(failed.sum()),
        "param_error_p50": float(p50) if np.isfinite(p50) else None,
        "param_error_p90": float(p90) if np.isfinite(p90) else None,
        "frac_param_error_below_0_1": float(np.mean(defined < 0.1)) if defined.size else None,
        "frac_param_error_below_0_3": float(np.mean(defined < 0.3)) if defined.size else None,
        "validation_rmse_p50": [float(x) for x in np.median(ok, axis=0)] if ok.size else None,
        "notes": notes,
    }
