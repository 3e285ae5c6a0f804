"""The diagnosis pipeline: simulate, locate, name, model and refit, show (issues 6, 13)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from diagnose import plausible
from diagnose.candidates import build_library
from diagnose.describe import describe
from diagnose.heldout import RUN_RISE, Parts, fit_pct, grams, heldout_rss, insample_rss, make_parts
from diagnose.locate import locate
from diagnose.model import (
    AugmentedModel,
    Prepared,
    diverges,
    escaped,
    fit,
    fit_percent,
    noise_std,
    noise_std_coloured,
    prepare,
)
from diagnose.recording import Recording, RecordingError
from diagnose.reference import ReferencedModel, extend, padded_params
from diagnose.search import MUCH_WORSE, base_bounds, prior_sd, select
from diagnose.uncertainty import baseline_cov, finding_cov
from primitives.ship import DEFAULT_STRUCTURE_PRIOR, DOFS, ShipProfile
from primitives.simulate import relative_signals


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

    @property
    def explained(self) -> bool:
        """No finding and residuals at the (coloured-noise robust) noise level."""
        return not self.findings and not self.structure and max(self.location["rms_over_noise"].values()) < 2.0

    @property
    def unexplained_dofs(self) -> list[str]:
        """DOFs whose final residual is still well above the noise (more than twice)."""
        r = np.concatenate([p.y[1:] - self.model.simulate(p, self.P)[0][1:] for p in self.preps])
        return [dof for i, dof in enumerate(DOFS) if np.sqrt(np.mean(r[:, i] ** 2)) > 2.0 * max(self.sigma[i], 1e-12)]


def _fits(model: AugmentedModel, preps: list[Prepared], P: np.ndarray) -> dict[str, float]:
    y = np.concatenate([p.y for p in preps])
    yh = np.concatenate([model.simulate(p, P)[0] for p in preps])
    return dict(zip(DOFS, fit_percent(y, yh).tolist()))


def _noise_scale(y: np.ndarray) -> np.ndarray:
    """Residual scale per output: the noise where there is noise; quantised real data get a
    floor (2 % of the signal)."""
    return np.maximum(noise_std(y), 0.02 * np.std(y, axis=0))


def fit_baseline(profile: ShipProfile, theta0: np.ndarray, recs: list[Recording],
                 new: list[int] | None = None, new_prior: float = DEFAULT_STRUCTURE_PRIOR) -> tuple[np.ndarray, str]:
    """Output-error fit of the baseline parameters on the --fit-on recordings. Returns
    (theta, note); a refit that diverges is rejected and the profile kept.

    In the profile's own structure (``new`` None) each parameter stays within a factor 2 of the
    profile and keeps its sign (damping stays dissipative), regularised towards it.

    With a declared structure (``new``: the indices of the terms :func:`diagnose.reference.extend`
    added, value 0) the model is re-expressed rather than corrected: the declared terms share
    the physics of the profile's own (delta*u_r*n and delta*u_r^2 split the rudder force the
    profile gave to delta*u_r^2 and delta*n^2; v_r^3*U^-1 takes over from v_r*|v_r|), so the
    profile's own parameters move with them. Every parameter is held by a Gaussian prior of std
    ``new_prior`` x :func:`term_scales` (a ridge, the own towards the profile's value, the
    declared towards zero) and keeps its sign (the declared ones: a DOF's own quadratic damping
    stays dissipative), with no factor-2 bound. A term that is zero throughout the --fit-on runs
    is not determined by them and is kept as it is (zero for a declared term)."""
    preps = [prepare(profile, r, i) for i, r in enumerate(recs)]
    model = AugmentedModel(profile, theta0, [], n_rec=len(preps))
    w = 1.0 / _noise_scale(np.concatenate([r.y for r in recs]))
    idx, sd, bounds = _baseline_prior(model, preps, w, recs, new, new_prior)
    P, _cov, rss = fit(model, preps, model.p0(), idx + model.x0_params(), w, max_iter=30, tol=1e-7, bounds=bounds,
                       prior=(model.p0(), sd))
    if not np.isfinite(rss):
        return theta0, "the baseline refit on the --fit-on runs diverged: rejected, the profile's parameters are used"
    return P[: model.n_base], ""


def _baseline_prior(model: AugmentedModel, preps: list[Prepared], w: np.ndarray, recs: list[Recording],
                    new: list[int] | None, new_prior: float) -> tuple[list[int], np.ndarray, dict]:
    """(fitted indices, prior std per parameter, bounds) of :func:`fit_baseline`."""
    idx = list(range(model.n_base))
    P0 = model.p0()
    if new is None:
        r0 = np.concatenate([(p.y[1:] - model.simulate(p, P0)[0][1:]) * w for p in preps]).ravel()
        level = np.sqrt(np.mean(r0**2)) if np.all(np.isfinite(r0)) else 1.0
        return idx, prior_sd(P0, idx, level, model.n_params), base_bounds(P0, idx, model)
    scale = term_scales(model.profile, recs)
    idx = [j for j in idx if np.isfinite(scale[j])]
    sd = np.full(model.n_params, np.inf)
    sd[idx] = new_prior * scale[idx]
    bounds = base_bounds(P0, [j for j in idx if P0[j] == 0.0], model)
    bounds |= {j: ((0.0, np.inf) if P0[j] > 0 else (-np.inf, 0.0)) for j in idx if P0[j] != 0.0}
    return idx, sd, bounds


def loo_misfit(profile: ShipProfile, theta0: np.ndarray, theta: np.ndarray, recs: list[Recording],
               new: list[int] | None = None, new_prior: float = DEFAULT_STRUCTURE_PRIOR) -> float:
    """Noise-weighted mean square misfit of the baseline ``theta`` (fitted by :func:`fit_baseline`
    from ``theta0`` on ``recs``, same ``new`` and prior) on each of ``recs`` left out in turn:
    refitted on the others by a Gauss-Newton step from ``theta`` with the same prior
    (:mod:`diagnose.heldout`). inf when a run cannot be simulated."""
    preps = [prepare(profile, r) for r in recs]
    model = AugmentedModel(profile, theta0, [])
    w = 1.0 / _noise_scale(np.concatenate([r.y for r in recs]))
    idx, sd, _b = _baseline_prior(model, preps, w, recs, new, new_prior)
    P = model.p0()
    P[: model.n_base] = theta
    with np.errstate(all="ignore"):
        if any(escaped(p, model.simulate(p, P)[0]) for p in preps):
            return float("inf")
        parts = make_parts(preps, [])
        g = grams(model, preps, parts, P, idx, w, model.steps(preps, P))
    fin = np.isfinite(sd[idx])
    D = np.where(fin, 1.0 / np.where(fin, sd[idx], 1.0) ** 2, 0.0)
    pg = D * (P[idx] - model.p0()[idx])
    rss = heldout_rss(g, parts, list(range(len(idx))), D, pg)
    return float(rss.sum() / max(3 * g.n_rows.sum(), 1)) if np.all(np.isfinite(rss)) else float("inf")


def term_scales(profile: ShipProfile, recs: list[Recording]) -> np.ndarray:
    """Per model term, the coefficient that alone would explain the spread of its DOF's
    one-step increments on ``recs``: std(dy_i) / rms(term) (the unit of a structure prior);
    inf for a term that is zero throughout ``recs``."""
    sig: dict[str, np.ndarray] = {}
    parts = [dict(profile.generalized_forces(r.inputs_for(profile.inputs)[:-1]), psi=r.psi[:-1]) for r in recs]
    for k in parts[0]:
        sig[k] = np.concatenate([q[k] for q in parts])
    relative_signals(np.concatenate([r.y[:-1] for r in recs]), into=sig, speed=True)
    dy = np.concatenate([np.diff(r.y, axis=0) for r in recs])
    out = []
    for i in range(3):
        phi = profile.model.evaluate_dof(i, sig)
        rms = np.sqrt(np.mean(phi**2, axis=0))
        with np.errstate(divide="ignore"):
            out.append(np.where(rms > 0.0, np.std(dy[:, i]) / rms, np.inf))
    return np.concatenate(out)


def _extended(profile: ShipProfile, theta: np.ndarray, declared: bool = False) -> tuple[ShipProfile, np.ndarray, list[str]]:
    """The profile with the structure terms it lacks (:func:`diagnose.reference.extend`) and
    ``theta`` with zeros for them."""
    ext, added = extend(profile, declared)
    if not added:
        return profile, theta, []
    return ext, padded_params(profile, theta, ext.model_terms), added


def _misfit(profile: ShipProfile, theta: np.ndarray, recs: list[Recording]) -> float:
    """Noise-weighted mean square open-loop misfit over ``recs`` (inf when a run diverges)."""
    model = AugmentedModel(profile, theta, [])
    preps = [prepare(profile, r) for r in recs]
    with np.errstate(all="ignore"):
        sims = [model.simulate(p, model.p0())[0] for p in preps]  # one simulation per run: the test and the misfit
    if any(escaped(p, yh) for p, yh in zip(preps, sims)):
        return float("inf")
    w = 1.0 / _noise_scale(np.concatenate([r.y for r in recs]))
    r = np.concatenate([(p.y[1:] - yh[1:]) * w for p, yh in zip(preps, sims)])
    return float(np.mean(r**2))


def fit_declared(profile: ShipProfile, theta0: np.ndarray, fit_on: list[Recording]
                 ) -> tuple[ShipProfile, np.ndarray, str, list[str]]:
    """The profile extended by its declared [diagnosis] structure and fitted on the --fit-on
    runs, every term held by the profile's structure prior (:func:`fit_baseline`): (profile,
    theta, note, added) as :func:`fit_baseline` and :func:`_extended`; the profile unchanged
    when it adds nothing."""
    ext, th_ext, added = _extended(profile, theta0, declared=True)
    if not added:
        return profile, theta0, "", []
    new = [j for i in range(3) for j in range(ext.model.offsets[i] + len(profile.model_terms[i]), ext.model.offsets[i + 1])]
    th_fit, note = fit_baseline(ext, th_ext, fit_on, new, profile.structure_prior)
    return ext, th_fit, note, added


def fit_structure(profile: ShipProfile, theta0: np.ndarray, fit_on: list[Recording], recordings: list[Recording]
                  ) -> tuple[ShipProfile, np.ndarray, str, list[str], bool]:
    """Fit the baseline on the --fit-on runs, with the structure the profile declares for it
    ([diagnosis] structure) when it has one. The extended model is kept only when it simulates
    the diagnosed runs at least as well as the baseline refitted in its own structure (its
    extrapolation from the calm run to other manoeuvres is the risk). Returns (profile, theta,
    source, notes, rejected): ``rejected`` when the refit diverged and the profile's parameters
    are kept."""
    theta, note = fit_baseline(profile, theta0, fit_on)
    source = "fitted on " + ", ".join(r.source for r in fit_on)
    if note or not profile.structure_terms:
        return profile, theta, source, [note] if note else [], bool(note)
    ext, th_fit, note_ext, added = fit_declared(profile, theta0, fit_on)
    if not added:
        return profile, theta, source, [], False
    if len(fit_on) >= 2:  # judged on --fit-on runs left out in turn: the diagnosed runs hold the effect sought
        m0 = loo_misfit(profile, theta0, theta, fit_on)
        m1 = float("inf") if note_ext else loo_misfit(ext, padded_params(profile, theta0, ext.model_terms), th_fit, fit_on,
                                                    [j for j in range(ext.model.n_params) if j not in _own(profile, ext)],
                                                    profile.structure_prior)
        where = "the --fit-on runs, each left out in turn"
    else:
        m0, m1 = _misfit(profile, theta, recordings), (_misfit(ext, th_fit, recordings) if not note_ext else float("inf"))
        where = "the diagnosed runs"
    if m1 <= m0:
        return ext, th_fit, f"{source}, structure extended by the profile's [diagnosis] terms ({len(added)})", [], False
    why = "diverges" if not np.isfinite(m1) else f"weighted mean square misfit {m1:.3g} vs {m0:.3g}"
    return profile, theta, source, [f"the profile's [diagnosis] structure fitted on the --fit-on runs simulates "
                                    f"{where} worse than the baseline's own ({why}): not used"], False


def _own(profile: ShipProfile, ext: ShipProfile) -> list[int]:
    """Indices in ``ext`` (the profile extended by :func:`_extended`) of the profile's own terms."""
    return [j for i in range(3) for j in range(ext.model.offsets[i], ext.model.offsets[i] + len(profile.model_terms[i]))]


def _check_sample_times(profile: ShipProfile, recs: list[Recording]) -> None:
    """Every recording holds the profile's inputs and is sampled at its sample time."""
    ts = profile.sample_time
    for r in recs:
        r.inputs_for(profile.inputs)
        if abs(r.sample_time - ts) > 1e-6 * ts:
            raise RecordingError(f"{r.source}: sample time {r.sample_time:g} s differs from the ship's {ts:g} s; "
                                 f"resample the recording or add '# sample_time: {ts:g}'")


def _fit_on(profile: ShipProfile, theta0: np.ndarray, fit_on: list[Recording], recordings: list[Recording],
            joint_reference: bool) -> tuple[ShipProfile, np.ndarray, str, list[str], list[int] | None]:
    """The baseline fitted on the --fit-on runs (jointly with the diagnosed runs with
    ``joint_reference``): (profile, theta, source, notes, own), ``own`` the indices of the
    profile's own parameters in a structure-extended model (None after a joint fit)."""
    _check_simulable(AugmentedModel(profile, theta0, []), [prepare(profile, r) for r in fit_on], "given")
    own: list[int] | None = None
    if joint_reference:
        profile, theta0, added = _extended(profile, theta0)
        theta0, note = fit_baseline(profile, theta0, list(fit_on) + recordings)
        source = ("fitted jointly on the reference run(s) " + ", ".join(r.source for r in fit_on) + " and the diagnosed "
                  "runs" + (f", structure extended by {', '.join(added)}" if added else ""))
        fit_notes, rejected = [note] if note else [], bool(note)
    else:
        n_own = [len(t) for t in profile.model_terms]
        profile, theta0, source, fit_notes, rejected = fit_structure(profile, theta0, fit_on, recordings)
        own = [j for i in range(3) for j in range(profile.model.offsets[i], profile.model.offsets[i] + n_own[i])]
    source += " (rejected)" if rejected else ""
    return profile, theta0, source, fit_notes, own


def _check_simulable(model: AugmentedModel, preps: list[Prepared], what: str) -> None:
    for p in preps:
        if diverges(model, [p], model.p0()):
            raise RecordingError(f"{p.rec.source}: the {what} baseline model cannot be simulated on this recording "
                                 "(the simulation diverges or is not finite); check the ship profile and --params, or "
                                 "refit it with --fit-on on a calm-water run")


def run(
    recordings: list[Recording],
    profile: ShipProfile,
    *,
    theta: np.ndarray | None = None,
    fit_on: list[Recording] | None = None,
    validate: list[Recording] | None = None,
    max_rounds: int = 5,
    joint_reference: bool = False,
) -> Diagnosis:
    """Diagnose ``recordings`` against ``profile`` (parameters ``theta`` or the simulation set).

    With ``fit_on`` the baseline is fitted on those runs first. With ``joint_reference`` as well
    (experimental, issue 13) its structure is extended (:mod:`diagnose.reference`) and refitted
    jointly on the ``fit_on`` runs and the diagnosed runs, every candidate acting on the
    diagnosed runs only."""
    t0 = time.perf_counter()
    if not recordings:
        raise RecordingError("no recording given: pass at least one CSV or .dat file")
    ts = profile.sample_time
    _check_sample_times(profile, list(recordings) + list(fit_on or []) + list(validate or []))
    theta0 = profile.params(theta if theta is not None else None)
    source = "profile"
    notes: list[str] = []
    calm_preps: list[Prepared] = []
    own: list[int] | None = None
    given = (profile, theta0)
    if fit_on:
        profile, theta0, source, notes, own = _fit_on(profile, theta0, fit_on, list(recordings), joint_reference)
    cands, untestable = build_library(profile, recordings)
    preps = [prepare(profile, r, i) for i, r in enumerate(recordings)]
    val_preps = [prepare(profile, r) for r in validate] if validate else []
    if fit_on and joint_reference:
        calm_preps = [prepare(profile, r, len(preps) + i) for i, r in enumerate(fit_on)]
        model: AugmentedModel = ReferencedModel(profile, theta0, cands, n_rec=len(preps) + len(calm_preps),
                                                reference=calm_preps)
    else:
        model = AugmentedModel(profile, theta0, cands, n_rec=len(preps))
    # Sampled inputs act half a sample late on a baseline that has its own timing (the profile's
    # parameters); a baseline fitted on --fit-on runs learnt their timing, half sample included, so a
    # delay is then measured against those runs as it is.
    if not fit_on and any(str(r.meta.get("input_hold", "sampled")).lower() != "zoh" for r in recordings):
        model.half_sample = 0.5 * ts
    _check_simulable(model, preps + val_preps, "fitted" if fit_on else "given")
    y_all = np.concatenate([r.y for r in recordings])
    sigma = noise_std_coloured(y_all)
    w = 1.0 / _noise_scale(y_all)
    P0 = model.p0()
    res0 = [p.y - model.simulate(p, P0)[0] for p in preps]
    location = locate(profile, preps, res0, theta0, np.maximum(sigma, 0.02 * np.std(y_all, axis=0)))
    # the declared structure terms stay as fitted on the calm runs: the search refits only the profile's own
    base_free = (own if own is not None else list(range(model.n_base))) if fit_on else []
    inputs = np.concatenate([p.inputs for p in preps])
    # the --fit-on runs hold the baseline refit on the diagnosed runs (a joint fit has them among the runs already)
    held_by = [prepare(profile, r) for r in fit_on] if fit_on and not joint_reference else None
    result = select(model, preps + calm_preps, w, val_preps=val_preps, base_free=base_free, max_rounds=max_rounds, inputs=inputs,
                    calm_preps=held_by)
    notes += result.notes
    P, free, steps = result.P, result.free, list(result.steps)
    P0x = P0.copy()
    P0x[model.x0_params()] = P[model.x0_params()]  # the initial state is not physics: same in both
    P, free, steps, per_run, method, dropped = _guard(model, preps + calm_preps, val_preps, w, P0x, P, free, steps, result.base_free)
    result.rejected += dropped
    findings = []
    cov = np.zeros((0, 0))
    if steps and free == result.free:
        held = [j for j in range(model.n_base) if j not in free] if fit_on and own is not None else []
        held_cov = _fit_on_cov(given, fit_on, profile, theta0, own)[np.ix_(held, held)] if held else None
        cov = finding_cov(model, preps + calm_preps, w, P, free, result.prior_std, held, held_cov)
    for st in steps:
        c = st.candidate
        dof = DOFS[c.dof] if c.dof is not None else DOFS[int(np.argmax(st.dof_gain))]
        params = describe(c, model, P, cov, free)
        _ok, why = plausible.check(c.effect, params, profile, inputs)
        findings.append({
            "effect": c.effect, "dof": dof, "key": c.key, "parameters": params,
            "f_statistic": float(st.f_stat), "p_value": float(st.p_value), "heldout_delta_aic": float(st.delta_aic),
            "cv_gain": float(st.cv_gain), "rss_drop": float((st.rss_before - st.rss_after) / max(st.rss_before, 1e-300)),
            "rss_drop_per_dof": dict(zip(DOFS, (st.dof_gain / max(st.rss_before, 1e-300)).tolist())),
            "signature_correlation": float(st.correlation), "description": c.description,
            "plausibility": why or "no ship-scaled limit applies", "heldout_per_run": st.heldout,
        })
    structure = _structural(model, [prepare(profile, r) for r in fit_on or []], w, P, findings)
    findings = [f for f in findings if f not in structure]
    fit_on_name = "validation" if val_preps else "diagnosed"
    fbd, fad = _fits(model, preps, P0x), _fits(model, preps, P)
    fb, fa = (_fits(model, val_preps, P0x), _fits(model, val_preps, P)) if val_preps else (dict(fbd), dict(fad))
    for f in findings + structure:
        f["evidence"] = _evidence(f, location, fb, fa, fit_on_name)
    names = [n for dof in profile.parameter_names for n in dof]
    d = Diagnosis(profile, theta0, model, P, findings, untestable, fb, fa, fit_on_name, location, source, sigma, preps,
                  val_preps, result.screened, fbd, fad, 0.0, per_run, method, result.rejected, notes,
                  [names[j] for j in result.base_free] if findings else [])
    d.structure = structure
    d.elapsed_s = time.perf_counter() - t0
    return d


def _fit_on_cov(given: tuple[ShipProfile, np.ndarray], fit_on: list[Recording], profile: ShipProfile,
                theta: np.ndarray, own: list[int]) -> np.ndarray:
    """Covariance (n_base x n_base) of the baseline ``theta`` as :func:`fit_baseline` fitted it
    on the --fit-on runs (its prior and weights; ``given`` the profile and parameters it started
    from, ``own`` their indices in ``profile``, which may be extended by its declared structure);
    zero for a parameter that fit did not move (a term zero throughout the runs)."""
    prof0, theta_given = given
    extended = len(own) < len(theta)
    ref = padded_params(prof0, theta_given, profile.model_terms) if extended else theta_given
    new = [j for j in range(len(theta)) if j not in own] if extended else None
    preps = [prepare(profile, r, i) for i, r in enumerate(fit_on)]
    w = 1.0 / _noise_scale(np.concatenate([r.y for r in fit_on]))
    idx, sd, _b = _baseline_prior(AugmentedModel(profile, ref, [], n_rec=len(preps)), preps, w, fit_on, new,
                                  prof0.structure_prior)
    out = np.zeros((len(theta), len(theta)))
    out[np.ix_(idx, idx)] = baseline_cov(AugmentedModel(profile, theta, [], n_rec=len(preps)), preps, w, idx, sd)
    return out


def _structural(model: AugmentedModel, calm: list[Prepared], w: np.ndarray, P: np.ndarray, findings: list[dict]) -> list[dict]:
    """Findings the --fit-on (reference) runs show too: refitting the baseline with the
    candidate on the reference runs (linearised, from the baseline as fitted there) lowers their
    residual by more than 1 % with a coefficient of the same sign and at least half the size.
    They are a deficiency of the baseline's structure, not a condition of the diagnosed runs
    (a current, a fault), and are reported apart; they stay in the model."""
    if not calm or not findings:
        return []
    base = list(range(model.n_base))
    P0 = model.p0()
    fit_parts = list(range(len(calm)))
    parts = Parts(fit_parts, [np.ones(p.n, bool) for p in calm], [p.rec.source for p in calm], [], [])
    out = []
    for f in findings:
        own = model.slot_of[f["key"]]
        g = grams(model, calm, parts, P0, base + own, w, model.steps(calm, P))
        zero = np.zeros(len(base) + len(own))
        rss0, _ = insample_rss(g, parts, list(range(len(base))), zero, zero, fit_parts)
        rss1, step = insample_rss(g, parts, list(range(len(base) + len(own))), zero, zero, fit_parts)
        est, val = step[len(base):], P[own]
        same = float(est @ val) > 0 and np.linalg.norm(est) >= 0.5 * np.linalg.norm(val)
        if rss1 < 0.99 * rss0 and same:
            f["reference_fit_gain"] = float(1.0 - rss1 / max(rss0, 1e-300))
            out.append(f)
    return out


def _table(labels: list[str], roles: list[str], f0: np.ndarray, f1: np.ndarray, den: np.ndarray) -> list[dict]:
    """Rows of the per-run table; ``den`` (runs, 3) the noise-weighted spread of each output,
    from which the fit gives the run's weighted misfit (summed over the channels)."""
    rows = []
    for lab, role, a, b, dn in zip(labels, roles, f0, f1, den):
        w0, w1 = (float(np.sum((1 - f / 100.0) ** 2 * dn)) for f in (a, b))
        rows.append({"run": lab, "role": role, "before": dict(zip(DOFS, a.tolist())), "after": dict(zip(DOFS, b.tolist())),
                     "weighted_misfit_before": w0, "weighted_misfit_after": w1})
    return rows


def _den(preps: list[Prepared], w: np.ndarray) -> np.ndarray:
    return np.array([np.sum(((p.y - p.y.mean(axis=0)) * w) ** 2, axis=0) for p in preps])


def per_run_fits(model: AugmentedModel, preps: list[Prepared], val_preps: list[Prepared], w: np.ndarray,
                 P0: np.ndarray, P: np.ndarray, free: list[int]) -> tuple[list[dict], str]:
    """Fit before/after per run and channel. With validation runs: by simulation. Otherwise each
    diagnosed run is held out in turn: the model refitted without it (a Gauss-Newton step of the
    free parameters from the final fit) is simulated on it (leave one run out, linearised)."""
    if val_preps:
        f0 = np.array([fit_percent(p.y, model.simulate(p, P0)[0]) for p in val_preps])
        f1 = np.array([fit_percent(p.y, model.simulate(p, P)[0]) for p in val_preps])
        return (_table([p.rec.source for p in val_preps], ["validation"] * len(val_preps), f0, f1, _den(val_preps, w)),
                "validation runs, simulated")
    f0 = np.array([fit_percent(p.y, model.simulate(p, P0)[0]) for p in preps])
    cols = [j for j in free if j < model.n_slots_end]
    if len(preps) < 2 or not cols:
        f1 = np.array([fit_percent(p.y, model.simulate(p, P)[0]) for p in preps])
        return _table([p.rec.source for p in preps], ["diagnosed"] * len(preps), f0, f1, _den(preps, w)), "diagnosed runs, in-sample"
    parts = make_parts(preps, [])
    g = grams(model, preps, parts, P, cols, w, model.steps(preps, P))
    rss = heldout_rss(g, parts, list(range(len(cols))), np.zeros(len(cols)), np.zeros(len(cols)))
    f1 = fit_pct(rss, g.den)
    return _table([p.rec.source for p in preps], ["left out"] * len(preps), f0, f1, _den(preps, w)), "leave one run out (linearised refit)"


GUARD_SLACK = 1.0  # fit points a validation run may lose on one channel after the diagnosis


def _guard(model: AugmentedModel, preps: list[Prepared], val_preps: list[Prepared], w: np.ndarray, P0: np.ndarray,
           P: np.ndarray, free: list[int], steps: list, base_free: list[int]):
    """Per-run acceptance: no validation run may fit worse overall (noise-weighted misfit) nor
    lose more than GUARD_SLACK points on a channel; no left-out run may get more than RUN_RISE
    worse overall or MUCH_WORSE points on a channel. Findings are dropped, last kept first,
    until that holds. No finding left: the model is the baseline as given (no refit)."""
    rise = 0.0 if val_preps else RUN_RISE
    dropped = []
    while True:
        if not steps:
            table, method = per_run_fits(model, preps, val_preps, w, P0, P0, [])
            return P0, [], [], table, method, dropped
        table, method = per_run_fits(model, preps, val_preps, w, P0, P, free)
        worst = min(row["after"][k] - row["before"][k] for row in table for k in DOFS)
        worse_run = max(row["weighted_misfit_after"] / max(row["weighted_misfit_before"], 1e-300) - 1.0 for row in table)
        if worst >= -(GUARD_SLACK if val_preps else MUCH_WORSE) and worse_run <= rise:
            return P, free, steps, table, method, dropped
        st = steps.pop()  # the last kept is the weakest
        own = model.slot_of[st.candidate.key]
        free = [j for j in free if j not in own]
        P = P.copy()
        P[own] = 0.0
        # the baseline keeps the values fitted with the finding (a refit without its prior could diverge)
        P, _cov, rss = fit(model, preps, P, [j for j in free if j not in base_free], w, max_iter=6)
        dropped.append({"key": st.candidate.key, "effect": st.candidate.effect,
                        "reason": f"a held-out run fits worse with it ({method}: weighted misfit {100 * worse_run:+.1f} %, "
                                  f"worst channel {worst:+.1f} points)"})
        if not np.isfinite(rss):
            steps = []


SIGNATURE = {"current": ["cos psi", "sin psi"], "wind": ["wind along", "wind across"], "actuator_delay": ["change of"],
             "input_offset": ["sign", ""], "thrust_loss": ["speed u"], "quadratic_damping": ["|v|", "|r|", "v|v|", "r|r|"],
             "missing_coupling": ["|r|", "speed u", "|v|"], "sensor_bias": [""], "inertia_change": ["change of"]}


def _evidence(f: dict, location: dict, fb: dict, fa: dict, where: str) -> str:
    dof = f["dof"]
    conds = location["conditions"].get(dof, [])
    keys = SIGNATURE.get(f["effect"], [])
    hit = next((c for c in conds if any(k and k in c["signal"] for k in keys)), None)
    parts = []
    if hit:
        parts.append(f"the {dof} residual follows {hit['signal']} (correlation {hit['correlation']:+.2f})")
    parts.append(f"adding it explains {100 * f['rss_drop']:.0f} % of the weighted residual (F = {f['f_statistic']:.1f}, "
                 f"p = {f['p_value']:.2g}) and lowers the held-out residual by {100 * f['cv_gain']:.0f} %")
    parts.append(f"{dof} fit on the {where} run(s) {fb[dof]:.0f} % -> {fa[dof]:.0f} %")
    return "; ".join(parts)
