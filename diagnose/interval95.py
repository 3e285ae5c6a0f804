"""The 95 % interval of a finding from the parts of its covariance (:class:`diagnose.uncertainty.FindingCov`):
the Student-t quantile at the Welch-Satterthwaite degrees of freedom of their sum, and the
small-sample widening of a spread measured over few runs or blocks (moved from
:mod:`diagnose.uncertainty`, unchanged)."""

from __future__ import annotations

import numpy as np
from scipy import stats

BLOCKS_PER_RUN = 8  # an eighth of a run: a zig-zag's cycle or two, long against the residuals' AR(1) correlation


def small_sample(n: int) -> float:
    """Variance factor of a spread measured over ``n`` runs (n - 1 degrees of freedom): the
    Student-t quantile of a one-std (68 %) interval, squared (2 runs: 3.38, 3 runs: 1.746, 10 runs: 1.12)."""
    return float(stats.t.ppf(stats.norm.cdf(1.0), n - 1) ** 2) if n >= 2 else 0.0


def _var_den(comps: list[tuple[float, float]]) -> tuple[float, float]:
    """The total variance of independent parts ``(variance, degrees of freedom)`` and the
    Welch-Satterthwaite denominator ``sum v_i^2 / nu_i`` (parts of infinite degrees of freedom add none)."""
    return sum(v for v, _nu in comps), sum(v**2 / nu for v, nu in comps if np.isfinite(nu))


def _t_half(comps: list[tuple[float, float]]) -> float:
    """Half-width of a 95 % interval of a sum of independent parts ``(variance, degrees of freedom)``:
    the Student-t quantile at the Welch-Satterthwaite effective degrees of freedom
    ``nu = (sum v_i)^2 / sum (v_i^2 / nu_i)`` (Satterthwaite 1946; Welch 1947) times the
    total std."""
    var, den = _var_den(comps)
    nu = var**2 / den if den > 0 else np.inf
    return float(stats.t.ppf(0.975, nu) * np.sqrt(var)) if var > 0 else 0.0


def _topped_up(parts: list[tuple[float, float]], top_up: float, n_heldout: int) -> tuple[float, float]:
    """The model error as one part ``(variance, degrees of freedom)`` once the held-out runs' top-up
    ``top_up`` (a variance) is added to the model-error ``parts``: its degrees of freedom
    interpolated harmonically in the top-up's share ``s`` of the variance,
    ``1/nu = (1 - s)/nu_parts + s/n_heldout`` (``nu_parts`` the Welch-Satterthwaite degrees of
    freedom of the parts). This interpolation is argued here, not a published rule. What holds:
    it is continuous in ``s``, between ``nu_parts`` and ``n_heldout``, and never above the
    Satterthwaite degrees of freedom of the sum whatever the correlation of the two estimates
    (their variances ``2 v^2/nu`` add to at most ``(sigma_1 + sigma_2)^2``, and
    ``((1 - s) a + s b)^2 <= (1 - s) a^2 + s b^2``), so its t quantile is at least theirs. Not
    Welch-Satterthwaite over the top-up as one more independent part: the top-up is the excess of
    the held-out runs' measure over the parts (with_heldout), not an independent estimate, and as
    one it would lend the sum more degrees of freedom than either measure has (on
    tests/test_diagnose_uncertainty.py's quadratic misfit 85 % coverage over 200 seeds, 88 % with
    this rule, 89.5 % with the whole model error at ``n_heldout``). The variance is the parts as
    measured plus the top-up: below the held-out measure itself by the parts' small-sample
    widening (the top-up is its excess over the widened parts), so it is continuous at a zero
    top-up; :func:`half_width_95`'s floor of 1.96 printed stds still holds the held-out measure."""
    var, den = _var_den(parts)
    total = var + top_up
    inv = (var / total) * (den / var**2 if var > 0 else 0.0) + (top_up / total) / n_heldout
    return total, (1.0 / inv if inv > 0 else np.inf)


def half_width_95(
    noise: float,
    model: float = 0.0,
    within: float = 0.0,
    reference: float = 0.0,
    heldout: float = 0.0,
    n_runs: int = 0,
    n_heldout: int = 0,
) -> float:
    """Half-width of an estimate's 95 % interval from the stds of its parts (:class:`FindingCov`):
    the Student-t quantile at the Welch-Satterthwaite effective degrees of freedom of their sum
    (Satterthwaite 1946, "An approximate distribution of estimates of variance components"), each
    part's variance as measured, before the widening :func:`small_sample` gives a one-std interval.

    The noise part (an AR(1) sandwich over thousands of samples) has as many degrees of freedom as
    the data; the run-to-run misfit ``n_runs - 1``; the misfit within the runs (the excess of the
    spread over eighths of each run, :func:`diagnose.within_interval.with_within`, over the
    run-to-run part) tops it up towards ``BLOCKS_PER_RUN * n_runs - 1``, the degrees of freedom
    moving with its share of the two as the held-out top-up's (:func:`_topped_up`), so a within
    part that carries the misfit takes the blocks' and a trace of one leaves the run-to-run part's;
    the --fit-on runs' misfit on the finding is
    one draw, ``delta``: one degree of freedom; the held-out runs' top-up
    (:func:`diagnose.heldout_interval.with_heldout`: their misfit's excess over the parts before it)
    one draw a held-out run, ``n_heldout``: the model error's degrees of freedom move smoothly with
    the top-up's share of it (:func:`_topped_up`): a top-up of a few per cent of the variance leaves
    the interval as it was, one that carries the model error takes the held-out runs' few degrees of
    freedom (t 4.30 with two). (Switching the whole model error to ``n_heldout`` however small the
    top-up widened the 44 of the MMG battery's 194 topped-up intervals topped up by less than 5 % of
    their std 1.07-2.15 times; this rule 1.000-1.110 times.) Where the held-out runs have more degrees of freedom than the parts (a --fit-on
    part's single one) that could narrow the interval, so the half-width is at least the one without
    the top-up. A model-error part measured over three runs makes a 95 % interval 4.30 of its stds
    wide, not the 1.96 of a normal law: the tails of a spread measured over few units are heavy.
    Never narrower than 1.96 of the std the finding prints (whose parts :func:`small_sample`
    widened for a one-std interval)."""
    comps = [(noise**2, np.inf)]
    blocks = BLOCKS_PER_RUN * n_runs
    runs = [(model**2 / small_sample(n_runs), n_runs - 1)] if model > 0 and n_runs >= 2 else []
    if within > 0 and blocks >= 2:
        # the within part tops the run-to-run part up (its excess over it): the degrees of freedom
        # move with its share, as the held-out top-up's (:func:`_topped_up`), so that a within part
        # of 1 % of the run-to-run std does not lend that part the blocks' many degrees of freedom
        # (the MMG battery's current-0.7 seed 1 speed: within 1.9e-5 beside 2.0e-3, and a whole 95 %
        # interval narrower than its noise-and-run-to-run one)
        comps.append(_topped_up(runs, within**2 / small_sample(blocks), blocks - 1))
    else:
        comps += runs
    if reference > 0:
        comps.append((reference**2, 1))
    half = _t_half(comps)
    if heldout > 0 and n_heldout >= 1:
        half = max(half, _t_half([comps[0], _topped_up(comps[1:], heldout**2, n_heldout)]))
    # never narrower than 1.96 of the std printed beside it (widened for a one-std interval): the two
    # intervals a report states must not contradict each other
    return max(half, float(stats.norm.ppf(0.975)) * float(np.sqrt(noise**2 + model**2 + within**2 + reference**2 + heldout**2)))
