"""The model-based figures of the adaptive-trial benchmark (:mod:`benchmarks.bench_adaptive`):
computed from information matrices at the truth, never from a simulated trial, and printed
beside the measured errors, never instead of them.

- the CEILING: the D-efficiency at the truth of the fixed plan's rest against the best rest there,
  both counting the first third sailed (Ljungberg 2022, (7.58); :func:`expdesign.adaptive.rest_efficiency`);
- the predicted error: the asymptotic rms relative parameter error of the IV estimate
  (:func:`error_model`);
- the criterion gap: what the scored metric's own criterion (relative A) would gain over the D
  rest, and over its own fixed rest (:func:`criterion_gap`).

Each function takes the first third and the rest of the fixed plan as lists of primitives.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence

import numpy as np

from expdesign import adaptive as ad

ZERO_NOISE = (0.0, 0.0, 0.0)


def ceiling(prof, lib, first: list, rest: list, truth: np.ndarray, ms: str):
    """What any re-design could gain at ``truth``: the rest re-designed at the true parameters
    from the noise-free ``first`` runs (the oracle), and the D-efficiency there of the fixed
    ``rest`` against the oracle's continuous optimum, the same seconds and both counting the
    sailed runs (Ljungberg 2022, (7.58)). Returns (oracle re-design, the fixed rest's efficiency,
    the noise-free sailed runs, the rest's seconds)."""
    sailed = ad.sail(prof, first, truth, ZERO_NOISE, np.random.default_rng(0))
    left = float(sum(p.duration_s for p in rest))
    reid = ad.Reidentification(np.asarray(truth, float), prof.predictor_param_names, {})
    oracle = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms, reid=reid)
    eff = ad.rest_efficiency(prof, lib, sailed, truth, Counter(p.name for p in rest), left, oracle.logdet_continuous, ms)
    return oracle, eff, sailed, left


def error_model(
    prof, lib, sailed, truth: np.ndarray, left: float, ms: str, noise: Sequence[float]
) -> tuple[Callable[[np.ndarray], float], Callable[[dict], float]]:
    """The asymptotic rms relative parameter error at ``truth`` of the trial sailed + a rest of
    time fractions w, up to a factor common to every rest of that length: sqrt(sum_i s_i^2
    (Gamma^-1)_ii / theta_i^2 / p), Gamma the (7.58) information at the truth (symmetric part),
    s_i the ``noise`` std of parameter i's equation: the IV covariance with converged instruments
    and white equation error (Ljungberg 2022, ch. 7). The differenced measurement noise is not
    white: a model-based figure. Returns the function of w and the function of whole-manoeuvre
    counts."""
    lib = [p for p in lib if p.kind == "informative"]
    _, _, info, _ = ad.rest_problem(prof, lib, sailed, truth, left, ms)
    dof = np.zeros(len(truth), int)
    for i in range(prof.predictor.n_dof):
        dof[prof.predictor.dof_slice(i)] = i
    c = (np.asarray(noise, float)[dof] / np.where(truth != 0, truth, np.inf)) ** 2

    def of_w(w: np.ndarray) -> float:
        g = info.gamma(w, ms)
        return float(np.sqrt(np.sum(c * np.diag(np.linalg.inv((g + g.T) / 2))) / np.count_nonzero(c)))

    total = left / prof.sample_time
    return of_w, lambda counts: of_w(np.array([counts.get(p.name, 0) * p.n_samples / total for p in lib]))


def error_optimum(of_w: Callable[[np.ndarray], float], q: int) -> np.ndarray:
    """The continuous rest minimising ``of_w`` (the scored metric's model, an A-criterion in
    relative units) over the simplex: softmax weights, three seeded starts."""
    from scipy.optimize import minimize

    def f(z):
        return np.log(of_w(np.exp(z - z.max()) / np.exp(z - z.max()).sum()))

    best = min((minimize(f, np.random.default_rng(k).normal(size=q), method="L-BFGS-B") for k in range(3)), key=lambda r: r.fun)
    return np.exp(best.x - best.x.max()) / np.exp(best.x - best.x.max()).sum()


def criterion_gap(prof, lib, first: list, rest: list, truth, th0, ms: str, noise: Sequence[float]) -> tuple[float, float]:
    """The predicted error of the rest optimal for the scored metric at the truth, over (a) the
    fixed D ``rest``'s and (b) the rest optimal for that metric at the profile's values ``th0``
    (a fixed plan in the scored metric, its first third the same). (b) is that criterion's
    ceiling of re-design, (a) also counts what changing the criterion gains."""
    lib = [p for p in lib if p.kind == "informative"]
    left = float(sum(p.duration_s for p in rest))
    sailed = ad.sail(prof, first, truth, ZERO_NOISE, np.random.default_rng(0))
    of_w, of_counts = error_model(prof, lib, sailed, truth, left, ms, noise)
    best = of_w(error_optimum(of_w, len(lib)))
    nominal = ad.sail(prof, first, th0, ZERO_NOISE, np.random.default_rng(0))
    w_nom = error_optimum(error_model(prof, lib, nominal, th0, left, ms, noise)[0], len(lib))
    return best / of_counts(Counter(p.name for p in rest)), best / of_w(w_nom)
