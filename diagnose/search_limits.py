"""What the search holds, bounds and regularises (:mod:`diagnose.search`): the baseline's bounds and
prior, the parameters the --fit-on runs determine (held as fitted there), the candidates a
refitted baseline already covers and each candidate's physical bounds. Moved from
:mod:`diagnose.search`, which still exports every name."""

from __future__ import annotations

import numpy as np

from diagnose import plausible
from diagnose.candidates import STEADY_WIND, Candidate, canonical_term
from diagnose.describe import surge_base_index
from diagnose.heldout import Parts, gram_sums
from diagnose.model import AugmentedModel, Prepared
from diagnose.significance import inflation
from diagnose.uncertainty import sensitivities

PRIOR_REL = 0.3  # prior std of a baseline parameter, relative to its profile value
OWN_DAMPING = {(0, "u_r*|u_r|"), (1, "v_r*|v_r|"), (2, "r*|r|")}


def base_bounds(ref: np.ndarray, idx: list[int], model: AugmentedModel | None = None) -> dict[int, tuple[float, float]]:
    """Baseline parameters keep their sign and stay within a factor 2 of the profile (damping
    stays dissipative, inertia within a factor 2); a structure term the profile lacks (value 0)
    is free, except a DOF's own quadratic damping, which stays dissipative (<= 0)."""
    out = {}
    for j in idx:
        a, b = 0.5 * ref[j], 2.0 * ref[j]
        if ref[j] != 0:
            out[j] = (min(a, b), max(a, b))
        elif model is not None and j < model.n_base and tuple(model.base[j][:2]) in OWN_DAMPING:
            out[j] = (-np.inf, 0.0)
    return out


def prior_sd(ref: np.ndarray, idx: list[int], level: float, n_params: int) -> np.ndarray:
    """Prior std per parameter (inf = no prior): PRIOR_REL of the profile value, in units of the
    data's effective residual level so that the prior weighs like PRIOR_REL on one effective
    sample block of the data."""
    sd = np.full(n_params, np.inf)
    for j in idx:
        if ref[j] != 0:
            sd[j] = PRIOR_REL * abs(ref[j]) / max(level, 1e-12)
    return sd


def _marginal_var(
    model: AugmentedModel, preps: list[Prepared], w: np.ndarray, ref: np.ndarray, idx: list[int]
) -> np.ndarray | None:
    """Marginal variance of the parameters ``idx`` fitted on ``preps`` alone (Gauss-Newton about
    ``ref``, the noise-weighted Gram matrix scaled by the residual level and colour as an
    output-error covariance, Källström (1977)); None when the runs cannot be simulated there.
    The Gram matrix by forward sensitivities where they apply (``ref`` is the baseline, no
    candidate on: one pass a run instead of a simulated member a column). They differ from the
    finite differences' variances by the differences' truncation error: 3.8e-4 relative on
    ``tests/test_diagnose_reuse.py``'s model ship (tested below 1e-3), up to 2.5e-3 on the
    KVLCC2 battery's cases of ``benchmarks/bench_diagnose_size``, whose two variances
    :func:`held_by_fit_on` compares lie 26 % or more apart (|log ratio| >= 0.23): the same set held."""
    parts = Parts(list(range(len(preps))), [np.ones(p.n, bool) for p in preps], [p.rec.source for p in preps], [], [])
    pairs = sensitivities(model, preps, ref, idx, w, analytic=True)
    g = gram_sums(pairs, preps, parts, idx, w)
    r = np.concatenate([R for R, _J in pairs])  # the weighted residual at ref, sample 0 left out
    if not (np.all(np.isfinite(g.G)) and np.all(np.isfinite(r))):
        return None
    scale = float(np.mean(r**2)) * inflation(r.ravel())  # residual variance per sample, colour-corrected
    var = np.diag(np.linalg.pinv(g.G.sum(axis=(0, 1)))) * scale
    return np.where(np.isfinite(var) & (var > 0), var, np.inf)


def held_by_fit_on(
    model: AugmentedModel, calm: list[Prepared], diag: list[Prepared], w: np.ndarray, ref: np.ndarray, idx: list[int]
) -> list[int]:
    """The baseline parameters the --fit-on runs determine at least as well as the diagnosed
    runs do (marginal variances of a fit on each alone, :func:`_marginal_var`). They are held as
    fitted on the --fit-on runs: refitted on the diagnosed runs they would absorb the effect
    there (a thrust loss into the thrust coefficient, a delay into the rudder derivatives) and
    leave the candidate nothing to explain. The others, which only the diagnosed runs excite
    (say the turning circle's), are refitted as before."""
    if not calm or not idx:
        return []
    v_calm, v_diag = _marginal_var(model, calm, w, ref, idx), _marginal_var(model, diag, w, ref, idx)
    if v_calm is None or v_diag is None:
        return []
    return [j for j, a, b in zip(idx, v_calm, v_diag) if a <= b]


def base_term_index(model: AugmentedModel, dof: int | None, term: str | None) -> int | None:
    """Position in P of the baseline parameter of ``term`` in ``dof`` (None when the model has none)."""
    if term is None:
        return None
    key = canonical_term(term)
    return next((j for j, (i, t, *_r) in enumerate(model.base) if i == dof and canonical_term(t) == key), None)


def refitted_alias(model: AugmentedModel, base_free: list[int]) -> set[str]:
    """Keys of the candidates that only add a term the baseline refits: the same regressor as a
    free baseline parameter, told apart from it by nothing but the prior, so the refit already
    takes such a change (a candidate changing a term is a finding against a baseline that holds it)."""
    free = set(base_free)
    return {
        c.key
        for c in model.candidates
        if len(c.slots) == 1 and c.slots[0].kind == "term" and base_term_index(model, c.slots[0].dof, c.slots[0].term) in free
    }


def slot_bounds(model: AugmentedModel, c: Candidate, P: np.ndarray) -> dict[int, tuple[float, float]]:
    """Physical bounds of a candidate's parameters."""
    new = model.slot_of[c.key]
    if c.effect == "actuator_delay":
        return {new[0]: (-model.half_sample, 50 * model.profile.sample_time)}
    if c.key == STEADY_WIND:  # the lateral load's centroid within the ship's length, the frontal area 0.5-4 x the box's
        return {new[2]: (-0.5, 0.5), new[3]: (-0.5, 3.0)}
    if c.effect == "inertia_change":
        f = plausible.MAX_INERTIA_FACTOR
        return {new[0]: (1.0 / f - 1.0, f - 1.0)}
    if c.slots[0].kind == "thrust":  # a thrust change beyond the plausible limit stays visible at the bound
        return {new[0]: (-1.0, 0.95)}
    if c.key.startswith("resistance_change:"):
        term = c.slots[0].term
        j = surge_base_index(model, term)
        if j is not None and P[j] != 0:
            lo, hi = sorted((-0.5 * P[j], 1.0 * P[j]))
            return {new[0]: (lo, hi)}
    if c.effect == "quadratic_damping" and (c.dof, c.slots[0].term) in OWN_DAMPING:
        j = base_term_index(model, c.dof, c.slots[0].term)  # a change of the model's own: the sum stays dissipative
        return {new[0]: (-np.inf, -min(P[j], 0.0) if j is not None else 0.0)}
    return {}
