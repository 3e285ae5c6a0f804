"""The diagnosis pipeline: simulate, locate, name, model and refit, show (issues 6, 13)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache, partial

import numpy as np
from threadpoolctl import threadpool_limits

from diagnose import plausible
from diagnose.baseline import (  # noqa: F401  (fit_baseline, fit_declared, fit_structure, loo_misfit, term_scales: the library API)
    cannot_tell,
    check_simulable,
    fit_baseline,
    fit_declared,
    fit_on_cov,
    fit_reference,
    fit_structure,
    loo_misfit,
    noise_scale,
    term_scales,
)
from diagnose.candidates import build_library
from diagnose.describe import (
    add_wind_means,
    confirmed_by_heldout,
    includes_no_effect,
    indistinct,
    interval_note,
    with_interval,
    z_score,
)
from diagnose.evidence import evidence, structural
from diagnose.heldout_interval import with_heldout
from diagnose.locate import locate
from diagnose.magnitude import heldout_worse, implausible, ml_refit
from diagnose.model import AugmentedModel, Prepared, fit, fit_percent, noise_std_coloured, prepare
from diagnose.perrun import guard, noise_spread, without
from diagnose.recording import Recording, RecordingError
from diagnose.recording_checks import rudder_in_profile_sign, with_conventions
from diagnose.reference import ReferencedModel
from diagnose.search import SearchResult, select
from diagnose.uncertainty import FindingCov, finding_cov, finding_pairs, with_reference
from diagnose.within_interval import with_within
from primitives.ship import DOFS, ShipProfile


@dataclass
class Diagnosis:
    profile: ShipProfile
    theta: np.ndarray  # baseline parameters (profile set, file, or fitted with --fit-on)
    model: AugmentedModel
    P: np.ndarray  # final parameters [baseline (refitted where declared) | augmentations | initial states]
    findings: list[dict]
    untestable: list[dict]
    fit_before: dict[str, float]
    fit_after: dict[str, float]
    fit_on: str  # "validation" or "diagnosed"
    location: dict
    baseline_source: str
    sigma: np.ndarray
    preps: list[Prepared]
    val_preps: list[Prepared]
    screened: list[dict] = field(default_factory=list)
    fit_before_diag: dict[str, float] = field(default_factory=dict)
    fit_after_diag: dict[str, float] = field(default_factory=dict)
    elapsed_s: float = 0.0
    per_run: list[dict] = field(default_factory=list)  # held-out fit before/after per run and channel
    per_run_method: str = ""
    rejected: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    refit_parameters: list[str] = field(default_factory=list)
    structure: list[dict] = field(default_factory=list)  # findings the --fit-on reference runs show too
    # the findings' magnitudes are the maximum-likelihood refit's (diagnose.magnitude), not the search's
    magnitudes_refitted: bool = False
    # why no effect is named whatever the data show (the --fit-on runs do not pin the baseline on some run)
    cannot_tell: str = ""
    # (run, first-order std of the baseline's simulation there, the most the search tells from an effect; noise units) behind cannot_tell
    unpinned: list[tuple[str, float, float]] = field(default_factory=list)

    @property
    def explained(self) -> bool:
        """No finding, residuals at the (coloured-noise robust) noise level and a baseline the
        --fit-on runs pin (no ``cannot_tell``)."""
        return (
            not self.cannot_tell
            and not self.findings
            and not self.structure
            and max(self.location["rms_over_noise"].values()) < 2.0
        )

    @property
    def unexplained_dofs(self) -> list[str]:
        """DOFs whose final residual is still well above the noise (more than twice)."""
        r = np.concatenate([p.y[1:] - self.model.simulate(p, self.P)[0][1:] for p in self.preps])
        return [dof for i, dof in enumerate(DOFS) if np.sqrt(np.mean(r[:, i] ** 2)) > 2.0 * max(self.sigma[i], 1e-12)]


def _fits(model: AugmentedModel, preps: list[Prepared], P: np.ndarray) -> dict[str, float]:
    y = np.concatenate([p.y for p in preps])
    yh = np.concatenate([model.simulate(p, P)[0] for p in preps])
    return dict(zip(DOFS, fit_percent(y, yh).tolist()))


def _check_sample_times(profile: ShipProfile, recs: list[Recording]) -> None:
    """Every recording holds the profile's inputs and is sampled at its sample time."""
    ts = profile.sample_time
    for r in recs:
        r.inputs_for(profile.inputs)
        if abs(r.sample_time - ts) > 1e-6 * ts:
            raise RecordingError(
                f"{r.source}: sample time {r.sample_time:g} s differs from the ship's {ts:g} s; "
                f"resample the recording or add '# sample_time: {ts:g}'"
            )


@dataclass
class _Setup:
    """What the search starts from: the baseline (fitted on --fit-on runs or as given), the
    augmented model and the prepared runs."""

    profile: ShipProfile
    theta0: np.ndarray
    source: str
    notes: list[str]
    own: list[int] | None  # the profile's own parameters (the search may refit them); None: joint fit
    model: AugmentedModel
    untestable: list[dict]
    preps: list[Prepared]
    val_preps: list[Prepared]
    calm_preps: list[Prepared]  # the --fit-on runs inside a joint fit
    # diagnosed/validation runs the --fit-on runs do not pin
    unpinned: list[tuple[str, float, float]] = field(default_factory=list)


def _setup(
    recordings: list[Recording],
    profile: ShipProfile,
    theta0: np.ndarray,
    fit_on: list[Recording] | None,
    validate: list[Recording] | None,
    joint_reference: bool,
) -> _Setup:
    """Fit the baseline (with --fit-on), build the candidates and the augmented model."""
    source, notes, own, unpinned = "profile", [], None, []
    if fit_on:
        profile, theta0, source, notes, own, unpinned = fit_reference(
            profile, theta0, fit_on, list(recordings), joint_reference, validate
        )
    cands, untestable = build_library(profile, recordings)
    preps = [prepare(profile, r, i) for i, r in enumerate(recordings)]
    val_preps = [prepare(profile, r) for r in validate] if validate else []
    calm_preps: list[Prepared] = []
    if fit_on and joint_reference:
        calm_preps = [prepare(profile, r, len(preps) + i) for i, r in enumerate(fit_on)]
        model: AugmentedModel = ReferencedModel(profile, theta0, cands, n_rec=len(preps) + len(calm_preps), reference=calm_preps)
    else:
        model = AugmentedModel(profile, theta0, cands, n_rec=len(preps))
    # Sampled inputs act half a sample late on a baseline that has its own timing (the profile's
    # parameters); a baseline fitted on --fit-on runs learnt their timing, half sample included, so a
    # delay is then measured against those runs as it is.
    if not fit_on and any(str(r.meta.get("input_hold", "sampled")).lower() != "zoh" for r in recordings):
        model.half_sample = 0.5 * profile.sample_time
    check_simulable(model, preps + val_preps, "fitted" if fit_on else "given")
    return _Setup(profile, theta0, source, notes, own, model, untestable, preps, val_preps, calm_preps, unpinned)


# BLAS runs on one thread during a diagnosis: the refits' products of a tall Jacobian (136,500 x 40
# for 13 runs of 3,500 samples) spent 0.05 to 2.9 s of CPU each on two threads of a shared machine,
# the second thread spinning while it waited for a core (one thread: the same products, 0.05 s).
# The limit is process-wide while run() runs: other threads of the process (a Dask worker's, a
# library caller's) get one BLAS thread too, and two run() calls overlapping in two threads may
# leave the process at one thread when they end; no caller in the project runs it in threads.
@threadpool_limits.wrap(limits=1, user_api="blas")
def run(
    recordings: list[Recording],
    profile: ShipProfile,
    *,
    theta: np.ndarray | None = None,
    fit_on: list[Recording] | None = None,
    validate: list[Recording] | None = None,
    max_rounds: int = 5,
    joint_reference: bool = False,
    environment: str | None = None,
    rudder_sign: str | None = None,
) -> Diagnosis:
    """Diagnose ``recordings`` against ``profile`` (parameters ``theta`` or the simulation set).

    With ``fit_on`` the baseline is fitted on those runs first. With ``joint_reference`` as well
    (experimental, issue 13) its structure is extended (:mod:`diagnose.reference`) and refitted
    jointly on the ``fit_on`` runs and the diagnosed runs, every candidate acting on the
    diagnosed runs only. ``environment`` and ``rudder_sign`` stand for every recording's
    ``# environment:`` and ``# rudder_sign:`` header lines; a rudder in the other convention is
    converted to the profile's (or refused when it turns the ship the other way), as the CLI does.
    When the ``fit_on`` runs do not pin the baseline on a diagnosed or validation run
    (:func:`diagnose.baseline.unpinned_runs`) no candidate is tried and ``cannot_tell`` says why.
    BLAS runs on one thread meanwhile, for the whole process (see the comment above)."""
    t0 = time.perf_counter()
    if not recordings:
        raise RecordingError("no recording given: pass at least one CSV or .dat file")
    recordings, fit_on, validate = (
        rudder_in_profile_sign(with_conventions(rs, environment, rudder_sign), profile) if rs else rs
        for rs in (list(recordings), fit_on, validate)
    )
    _check_sample_times(profile, list(recordings) + list(fit_on or []) + list(validate or []))
    given = (profile, profile.params(theta if theta is not None else None))
    S = _setup(recordings, *given, fit_on, validate, joint_reference)
    why_not = cannot_tell(S.unpinned, fit_on or [], recordings, validate or []) if S.unpinned else ""
    max_rounds = 0 if why_not else max_rounds  # no candidate is tried: nothing could be named
    model, preps, val_preps = S.model, S.preps, S.val_preps
    y_all = np.concatenate([r.y for r in recordings])
    sigma = noise_std_coloured(y_all)
    w = 1.0 / noise_scale(y_all)
    P0 = model.p0()
    res0 = [p.y - model.simulate(p, P0)[0] for p in preps]
    location = locate(S.profile, preps, res0, S.theta0, np.maximum(sigma, 0.02 * np.std(y_all, axis=0)))
    # the declared structure terms stay as fitted on the calm runs: the search refits only the profile's own
    base_free = (S.own if S.own is not None else list(range(model.n_base))) if fit_on else []
    inputs = np.concatenate([p.inputs for p in preps])
    # the --fit-on runs hold the baseline refit on the diagnosed runs (a joint fit has them among the runs already)
    held_by = [prepare(S.profile, r) for r in fit_on] if fit_on and not joint_reference else None
    result = select(
        model,
        preps + S.calm_preps,
        w,
        val_preps=val_preps,
        base_free=base_free,
        max_rounds=max_rounds,
        inputs=inputs,
        calm_preps=held_by,
    )
    spread = {p.rec.source: noise_spread(p, w) for p in val_preps}  # what a held-out fit point is worth in noise
    held_fit = cache(partial(fit_on_cov, given, fit_on, S.profile, S.theta0, S.own))  # the same on every pass
    calm = [prepare(S.profile, r) for r in fit_on or []]
    for _pass in range(len(result.steps) + 1):  # one finding dropped a pass at most
        P, P0x, free, steps, per_run, method, w_fit, refitted = _magnitudes(
            model, preps + S.calm_preps, val_preps, result, w, P0, inputs
        )
        cov, pairs = FindingCov(np.zeros((0, 0)), np.zeros((0, 0)), 0), None
        if steps:  # the per-run guard's set too: its findings get an interval and face the rule below
            cov, pairs = _cov(S, held_fit, fit_on, w_fit, P, free, result.prior_std)
            cov = _model_error(cov, model, calm, preps + S.calm_preps, val_preps, w_fit, P, free, steps, result.prior_std, pairs)
        findings = [_finding(st, model, P, cov, free, inputs) for st in steps]
        for f in findings:
            f["heldout_confirmed"] = confirmed_by_heldout(f, spread)
        if not _drop_indistinct(model, preps + S.calm_preps, result, steps, findings, cov, w):
            break
    add_wind_means(findings, model, preps, P, cov, free)
    structure = structural(model, calm, w, P, findings)
    findings = [f for f in findings if f not in structure]
    fit_on_name = "validation" if val_preps else "diagnosed"
    fbd, fad = _fits(model, preps, P0x), _fits(model, preps, P)
    fb, fa = (_fits(model, val_preps, P0x), _fits(model, val_preps, P)) if val_preps else (dict(fbd), dict(fad))
    for f in findings + structure:
        f["evidence"] = evidence(f, location, fb, fa, fit_on_name)
    names = [n for dof in S.profile.parameter_names for n in dof]
    d = Diagnosis(
        S.profile,
        S.theta0,
        model,
        P,
        findings,
        S.untestable,
        fb,
        fa,
        fit_on_name,
        location,
        S.source,
        sigma,
        preps,
        val_preps,
        result.screened,
        fbd,
        fad,
        0.0,
        per_run,
        method,
        result.rejected,
        S.notes + result.notes,
        [names[j] for j in result.base_free] if findings else [],
    )
    d.structure = structure
    d.magnitudes_refitted = refitted
    d.cannot_tell, d.unpinned = why_not, S.unpinned
    d.elapsed_s = time.perf_counter() - t0
    return d


def _model_error(
    cov: FindingCov,
    model: AugmentedModel,
    calm: list[Prepared],
    preps: list[Prepared],
    val_preps: list[Prepared],
    w_fit: np.ndarray,
    P: np.ndarray,
    free: list[int],
    steps: list,
    prior_std,
    pairs,
) -> FindingCov:
    """The findings' covariance ``cov`` (noise and run-to-run misfit) with the model-error parts the
    reported interval holds (:mod:`diagnose.uncertainty`): the error common to every run that the
    ``--fit-on`` runs show, the misfit within the runs, and the error the held-out runs show. The
    rule on indistinct findings judges this whole interval, the one the report prints."""
    if not len(cov.noise):
        return cov
    keys = [st.candidate.key for st in steps]
    if calm:
        cov = with_reference(cov, model, calm, w_fit, free, keys, prior_std)
    # the covariance's sensitivities at the same P and weights (``pairs``): its first columns are free's
    cov = with_within(cov, model, preps, w_fit, P, free, prior_std, pairs)
    if val_preps:  # a bias common to the diagnosed runs too
        cov = with_heldout(cov, model, val_preps, w_fit, P, free, keys, prior_std)
    return cov


def _magnitudes(
    model: AugmentedModel,
    preps: list[Prepared],
    val_preps: list[Prepared],
    result: SearchResult,
    w: np.ndarray,
    P0: np.ndarray,
    inputs: np.ndarray,
):
    """The final magnitudes of what the search kept (``result``, a :class:`diagnose.search.SearchResult`;
    its notes and rejections are extended): the maximum-likelihood refit
    (:func:`diagnose.magnitude.ml_refit`) unless it fits the held-out runs worse than the search's
    estimate (:func:`diagnose.magnitude.heldout_worse`) or makes a finding implausible; a finding
    implausible at the search's estimate too is dropped. Then the per-run guard against the
    baseline P0 with the final initial states. Returns (P, that baseline, free, steps, per-run
    table, its method, the weights P was fitted with, refitted?)."""
    chosen = [st.candidate for st in result.steps]
    P_ml, w_ml, sd_ml, note = ml_refit(model, preps, result.P, result.free, chosen, result.base_free, w, result.prior_std)
    why = ""
    if not note and chosen:
        why = heldout_worse(model, preps, val_preps, w, result.P, P_ml, w_ml, result.free)
        why = f"it fits a held-out run worse than the search's estimate: {why}" if why else ""
        bad = [] if why else implausible(model, chosen, P_ml, result.free, inputs)
        why = why or "; ".join(f"{c.key} becomes implausible: {r}" for c, r in bad)
    refitted = bool(chosen) and not note and not why
    if refitted:
        result.P, w_fit, result.prior_std = P_ml, w_ml, sd_ml
    else:
        w_fit = w
        note = note or (
            f"the maximum-likelihood refit of the findings' magnitudes was not kept ({why}): the search's estimate is reported"
            if why
            else ""
        )
    result.notes += [note] if note else []
    steps = _drop_implausible(model, preps, result, w_fit, inputs)
    P0x = P0.copy()
    P0x[model.x0_params()] = result.P[model.x0_params()]  # the initial state is not physics: same in both
    P, free, steps, per_run, method, dropped = guard(
        model, preps, val_preps, w, P0x, result.P, result.free, steps, result.base_free, w_fit
    )
    result.rejected += dropped
    return P, P0x, free, steps, per_run, method, w_fit, refitted and bool(steps)


def _drop_indistinct(
    model: AugmentedModel,
    preps: list[Prepared],
    result: SearchResult,
    steps: list,
    findings: list[dict],
    cov: FindingCov,
    w: np.ndarray,
) -> bool:
    """Drop the one finding with the smallest |estimate / std| when it is not told apart from no
    effect (:func:`diagnose.describe.indistinct`): the 95 % interval of its noise and run-to-run
    misfit (two or more runs) includes zero, or its whole reported interval (those and the
    model-error parts of :func:`_model_error`, Student-t at their degrees of freedom) does and no
    held-out run confirms it. Such a term improves the fit by no more than
    the model's misfit moves it from run to run: with few runs, a damping term beside a delay that
    absorbs what the baseline lacks (issue 26). One at a time: a delay and a damping term competing
    for the same misfit both get wide intervals while both are in; without the weaker, the other's
    interval narrows. The rest are refitted (``result`` changed in place) and the caller recomputes
    the covariance and asks again; True when one was dropped. ``steps``: the kept steps after the
    per-run guard (``result.steps`` may hold more)."""
    if cov.n_runs < 2:
        return False  # one run: the +- holds noise only, no model-error term to judge by
    weak = [f for f in findings if indistinct(f)]
    if not weak:
        return False
    f = min(weak, key=z_score)
    kept = {st.candidate.key for st in steps} - {f["key"]}
    for st in result.steps:  # the weakest, and what the implausibility check or the per-run guard took out
        if st.candidate.key not in kept:
            result.P, result.free = without(model, result.P, result.free, st.candidate.key)
    result.steps = [st for st in steps if st.candidate.key in kept]
    refit = [j for j in result.free if j not in result.base_free]
    if refit:
        result.P, _c, _rss = fit(model, preps, result.P, refit, w, max_iter=6, need_cov=False)
    misfit = not cov.misfit_failed and bool(np.any(np.asarray(cov.model) != 0.0))
    covers = "noise and run-to-run model misfit" if misfit else "noise; the run-to-run misfit came out zero"
    result.rejected.append(
        {
            "key": f["key"],
            "effect": f["effect"],
            "reason": f"its 95 % interval ({_judged(f, covers)}) includes no effect (|estimate/std| = {z_score(f):.2f}): "
            + ("not told apart from the model's misfit" if misfit else "not told apart from the noise"),
        }
    )
    return True


def _judged(f: dict, covers: str) -> str:
    """Which interval of ``f`` :func:`_drop_indistinct` found to include no effect, in words."""
    if includes_no_effect(f) and not f.get("heldout_confirmed"):
        return f"{covers} and the model-error parts; no held-out run confirms it"
    return covers


def _drop_implausible(
    model: AugmentedModel, preps: list[Prepared], result: SearchResult, w: np.ndarray, inputs: np.ndarray
) -> list:
    """The kept steps less those implausible at the final estimate (the search judged each at its
    own refit; later rounds refit it again): each is moved to ``result.rejected`` with the
    reason, its slots zeroed and the rest refitted (weights ``w``)."""
    steps = list(result.steps)
    for c, why in implausible(model, [st.candidate for st in steps], result.P, result.free, inputs):
        steps = [st for st in steps if st.candidate.key != c.key]
        result.P, result.free = without(model, result.P, result.free, c.key)
        result.rejected.append({"key": c.key, "effect": c.effect, "reason": f"implausible estimate: {why}"})
    if len(steps) < len(result.steps) and steps:
        result.P, _c, _rss = fit(
            model, preps, result.P, [j for j in result.free if j not in result.base_free], w, max_iter=6, need_cov=False
        )
    return steps


def _cov(
    S: _Setup,
    held_fit: Callable[[], np.ndarray],
    fit_on: list[Recording] | None,
    w: np.ndarray,
    P: np.ndarray,
    free: list[int],
    prior_std: np.ndarray | None,
) -> tuple[FindingCov, list[tuple[np.ndarray, np.ndarray]]]:
    """Covariance of the free parameters at P (:func:`diagnose.uncertainty.finding_cov`); with a
    baseline fitted on --fit-on runs alone, the covariance of that fit carried in as well; and
    the findings' run-to-run misfit over the diagnosed runs. Also the runs' sensitivities it was
    computed from (:func:`diagnose.uncertainty.finding_pairs`: ``free``'s columns first)."""
    model = S.model
    fitted = bool(fit_on) and S.own is not None and not S.source.endswith("(rejected)")
    held = [j for j in range(model.n_base) if j not in free] if fitted else []
    held_cov = held_fit()[np.ix_(held, held)] if held else None
    pairs = finding_pairs(model, S.preps + S.calm_preps, w, P, free, held, held_cov)
    return finding_cov(model, S.preps + S.calm_preps, w, P, free, prior_std, held, held_cov, pairs), pairs


def _finding(st, model: AugmentedModel, P: np.ndarray, cov: FindingCov, free: list[int], inputs: np.ndarray) -> dict:
    """The reported finding of a kept search step (``diagnose.search.Step``)."""
    c = st.candidate
    dof = DOFS[c.dof] if c.dof is not None else DOFS[int(np.argmax(st.dof_gain))]
    params = with_interval(c, model, P, cov, free)
    _ok, why = plausible.check(c.effect, params, model.profile, inputs)
    return {
        "effect": c.effect,
        "dof": dof,
        "key": c.key,
        "parameters": params,
        "f_statistic": float(st.f_stat),
        "p_value": float(st.p_value),
        "heldout_delta_aic": float(st.delta_aic),
        "cv_gain": float(st.cv_gain),
        "rss_drop": float((st.rss_before - st.rss_after) / max(st.rss_before, 1e-300)),
        "rss_drop_per_dof": dict(zip(DOFS, (st.dof_gain / max(st.rss_before, 1e-300)).tolist())),
        "signature_correlation": float(st.correlation),
        "description": c.description,
        "plausibility": why or "no ship-scaled limit applies",
        "heldout_per_run": st.heldout,
        # each held-out run's own estimate as a multiple of this one (diagnose.heldout_interval.with_heldout)
        "heldout_along": getattr(cov, "heldout_along", {}).get(c.key),
        "interval": interval_note(cov, c.key) if len(cov.noise) else None,
    }
