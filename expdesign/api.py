"""Library entry point of the design step: :func:`run_design` (used by the planner and ``plan-trial``).

Pipeline: primitive library -> information moments X, Y, Z (7.50), (7.51), (7.55) -> identifiability
check -> convex design (7.18)/(7.53) with its efficiency certificate -> for complete mean
subtraction the non-convex design (7.57) started from it -> rounding to whole repetitions of the
primitives' pieces for the trial length.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from expdesign.dopt import (
    CRITERIA,
    ROBUST,
    Constraints,
    InfoSet,
    canonical_criterion,
    lost_to_mean_subtraction,
    solve_convex,
    varying_primitives,
)
from expdesign.errors import DesignError
from expdesign.nonconvex import solve_nonconvex
from expdesign.prior import ParameterPrior
from expdesign.robust import DrawInformation, draw_information, robust_design
from expdesign.rounding import Rounded, criterion_efficiency, round_design
from primitives.information import (
    MEAN_SUBTRACTION,
    PrimitiveInfo,
    excitation_hint,
    library_information,
    unidentified_parameters,
)
from primitives.library import Primitive, design_dictionary, model_ship_thesis
from primitives.ship import ShipProfile, load_profile
from primitives.simulate import Disturbances


@dataclass
class Design:
    """A designed mix of primitives.

    weights: time fraction per primitive; logdet: log|det Gamma| of the design for its mean
    subtraction ((7.18)/(7.53)/(7.57), per-sample information); efficiency_vs_uniform: criterion
    efficiency against equal shares (> 1: better; D: (det Gamma / det Gamma_uniform)^(1/p));
    efficiency_bound: guaranteed efficiency of the convex solution from the equivalence theorem;
    rounded: whole units (pieces of the primitive, see ``unit_s``) per primitive for the trial.
    warnings: what the design cannot do, one sentence each (a parameter the instrument-mean
    subtraction leaves unidentifiable, :func:`mean_subtraction_warnings`).
    """

    profile: str
    criterion: str
    mean_subtraction: str
    weights: dict[str, float]
    logdet: float
    efficiency_vs_uniform: float
    efficiency_bound: float | None
    rounded: dict[str, int]
    unit_s: dict[str, float]
    trial_length_s: float
    rounded_fractions: dict[str, float]
    rounding_efficiency: float
    convex_weights: dict[str, float]
    certificate: dict[str, Any]
    solver_notes: list[str] = field(default_factory=list)
    starts: list[dict] = field(default_factory=list)
    winner: str | None = None
    n_params: int = 0
    references: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    robust: dict[str, Any] | None = None  # bayes-D / maximin-D: the prior and each mix's D-efficiency over its draws

    def to_dict(self) -> dict[str, Any]:
        return {
            "profile": self.profile,
            "criterion": self.criterion,
            "mean_subtraction": self.mean_subtraction,
            "weights": dict(self.weights),
            "logdet": self.logdet,
            "efficiency_vs_uniform": self.efficiency_vs_uniform,
            "efficiency_bound": self.efficiency_bound,
            "rounded": dict(self.rounded),
            "unit_s": dict(self.unit_s),
            "trial_length_s": self.trial_length_s,
            "rounded_fractions": dict(self.rounded_fractions),
            "rounding_efficiency": self.rounding_efficiency,
            "rounding_efficiency_loss": max(0.0, 1.0 - self.rounding_efficiency),
            "convex_weights": dict(self.convex_weights),
            "certificate": dict(self.certificate),
            "solver_notes": list(self.solver_notes),
            "starts": list(self.starts),
            "winner": self.winner,
            "n_params": self.n_params,
            "reference_efficiency": dict(self.references),
            "warnings": list(self.warnings),
            "robust": self.robust,
        }


def default_library(profile: ShipProfile, psi_switch: float | None = None) -> list[Primitive]:
    """The thesis dictionary of the profile; ``psi_switch`` (rad) sets the model-ship zig-zag period."""
    if psi_switch is not None and profile.library == "thesis-model-ship":
        return model_ship_thesis(profile, psi_switch=psi_switch)
    return design_dictionary(profile)


def check_identifiable(profile: ShipProfile, info: InfoSet, mean_subtraction: str) -> None:
    """Raise a DesignError naming the parameters no mix of the library can identify."""
    w = np.full(len(info.names), 1.0 / len(info.names))
    dead = unidentified_parameters(profile, info.gamma(w, mean_subtraction))
    if dead:
        raise DesignError(
            f"the primitive library {info.names} cannot identify {dead} (mean subtraction {mean_subtraction!r}); "
            f"add a manoeuvre that excites them: {excitation_hint(profile, dead)}"
        )


def mean_subtraction_warnings(profile: ShipProfile, info: InfoSet, w: np.ndarray, mean_subtraction: str) -> list[str]:
    """One sentence per parameter that the instrument-mean subtraction leaves unidentifiable
    (:func:`expdesign.dopt.lost_to_mean_subtraction`), in the library as a whole (equal shares) or
    in the design ``w`` only, naming the parameter, why and what would help."""
    names = profile.predictor_param_names
    everywhere = lost_to_mean_subtraction(info, np.full(len(info.names), 1.0 / len(info.names)), mean_subtraction)
    out = []
    for i, frac in lost_to_mean_subtraction(info, w, mean_subtraction).items():
        batch = "each primitive" if mean_subtraction == "batchwise" else "the whole trial"
        why = (
            f"{names[i]} is not identifiable with {mean_subtraction} instrument-mean subtraction: its instrument is "
            f"(nearly) constant over {batch}, so only {frac:.1e} of its information survives the subtraction "
            f"(rounding noise)"
        )
        varying = varying_primitives(info, i, mean_subtraction)
        if i in everywhere:
            out.append(
                f"{why} in every mix of this library; use --mean-subtraction none, or add a manoeuvre that excites it: "
                f"{excitation_hint(profile, [names[i]])}"
            )
        else:
            out.append(
                f"{why} in this design, which gives no time to the primitives in which it varies "
                f"({', '.join(varying) or 'none'}); use --mean-subtraction none, or --min-frac to keep them"
            )
    return out


def _informative_library(
    profile: ShipProfile,
    primitives: list[Primitive] | None,
    psi_switch: float | None,
    criterion: str,
    mean_subtraction: str,
    notes: list[str],
) -> list[Primitive]:
    """The options checked and the informative primitives to design with (default: the profile's
    thesis dictionary), with unique names; what is ignored goes into ``notes``."""
    if criterion not in CRITERIA:
        raise DesignError(f"criterion must be one of {list(CRITERIA)}, got {criterion!r}")
    if mean_subtraction not in MEAN_SUBTRACTION:
        raise DesignError(f"mean subtraction must be one of {list(MEAN_SUBTRACTION)}, got {mean_subtraction!r}")
    if primitives is None:
        primitives = default_library(profile, psi_switch)
    elif psi_switch is not None:
        notes.append("psi_switch ignored: an explicit primitive library was given")
    prims = [p for p in primitives if p.kind == "informative"]
    if not prims:
        raise DesignError("the primitive library has no informative primitives; give zig-zags, spirals, speed changes ...")
    names = [p.name for p in prims]
    if len(set(names)) != len(names):
        raise DesignError(f"primitive names must be unique, got {names}")
    return prims


def _moments(profile: ShipProfile, prims: list[Primitive], disturbed_realisations: int, seed: int) -> list[PrimitiveInfo]:
    """X, Y, Z of every primitive: from the nominal states, or averaged over
    ``disturbed_realisations`` noisy, disturbed simulations (the profile's disturbances, seeded)."""
    kw: dict[str, Any] = {}
    if disturbed_realisations > 0:
        kw = dict(disturbances=Disturbances.from_profile(profile), realisations=disturbed_realisations, seed=seed)
    return library_information(profile, prims, **kw)


def _optimise(
    info: InfoSet,
    cons: Constraints,
    criterion: str,
    mean_subtraction: str,
    convex_solvers: tuple[str, ...],
    n_random_starts: int,
    seed: int,
    notes: list[str],
) -> tuple[Any, np.ndarray, list[dict], str | None, float | None]:
    """The convex design (7.18)/(7.53) and, for complete mean subtraction or a relaxation that
    misrepresents the library, the non-convex one started from it: (convex result, final
    weights with the optimiser's zeros set to 0, non-convex starts, winner, efficiency bound)."""
    convex = solve_convex(info, criterion, mean_subtraction, cons, convex_solvers)
    notes += [f"convex: {convex.solver}"] + convex.notes
    final, starts, winner = convex.weights, [], "convex"
    bound = convex.efficiency_bound
    uniform_w = np.full(len(info.names), 1.0 / len(info.names))
    relaxed_mode = "batchwise" if mean_subtraction == "complete" else mean_subtraction
    relaxation_ok = info.value(convex.weights, relaxed_mode, criterion) >= info.value(uniform_w, relaxed_mode, criterion)
    if mean_subtraction == "complete" and not relaxation_ok:
        bound = None
        notes.append("the convex relaxation scored below the uniform mix on its exact objective: no efficiency bound")
    if mean_subtraction != "complete" and not relaxation_ok:
        # The symmetric relaxation misrepresents this library (the IV Gamma's symmetric part is
        # far from Gamma, e.g. crude instruments): optimise the exact objective instead.
        nc = solve_nonconvex(
            info,
            cons,
            criterion=criterion,
            mean_subtraction=mean_subtraction,
            convex_start=convex.weights,
            n_random=n_random_starts,
            seed=seed,
        )
        final, starts, winner, bound = nc.weights, nc.starts, nc.winner, None
        notes += [
            "the convex relaxation (symmetric part of Gamma) scored below the uniform mix on the exact objective; "
            "solved log|det Gamma| directly by multi-start SLSQP: no efficiency bound"
        ] + nc.notes
    if mean_subtraction == "complete":
        nc = solve_nonconvex(
            info,
            cons,
            criterion=criterion,
            mean_subtraction="complete",
            convex_start=convex.weights,
            n_random=n_random_starts,
            seed=seed,
        )
        final, starts, winner = nc.weights, nc.starts, nc.winner
        notes += nc.notes
    final = np.where(final < 1e-6, 0.0, final)
    return convex, final / final.sum(), starts, winner, bound


def _reference_efficiencies(
    references: dict[str, dict[str, float]] | None,
    names: list[str],
    value: Callable[[np.ndarray], float],
    val: float,
    n_params: int,
    criterion: str,
) -> dict[str, float]:
    """Criterion efficiency of each reference mix (label -> {primitive: share}) against the design's value ``val``."""
    refs = {}
    for label, shares in (references or {}).items():
        unknown = sorted(set(shares) - set(names))
        if unknown:
            raise DesignError(f"reference design {label!r} names unknown primitives {unknown}")
        rw = np.array([float(shares.get(n, 0.0)) for n in names])
        refs[label] = criterion_efficiency(value(rw / rw.sum()), val, n_params, criterion)
    return refs


def unit_samples(prim: Primitive) -> int:
    """Samples of one unit of a primitive: a piece between natural split points (mean length)."""
    return max(1, int(round(prim.n_samples / max(1, len(prim.pieces())))))


@dataclass
class _Step:
    """The optimisation step of :func:`run_design`: final fractions, their efficiency bound, the
    criterion as a function of the fractions and the kind of efficiency it gives (D for the robust
    criteria, whose values are log dets), the certificate record, notes, the non-convex starts and
    winner, and for a robust design its report section and matrices over the draws."""

    weights: np.ndarray
    bound: float | None
    value: Callable[[np.ndarray], float]
    eff_kind: str
    convex_weights: np.ndarray
    certificate: dict[str, Any]
    notes: list[str]
    starts: list[dict] = field(default_factory=list)
    winner: str | None = None
    section: dict[str, Any] | None = None
    draws: DrawInformation | None = None


def _local_step(
    info: InfoSet,
    cons: Constraints,
    criterion: str,
    mean_subtraction: str,
    convex_solvers: tuple[str, ...],
    n_random_starts: int,
    seed: int,
) -> _Step:
    """The design at the profile's values: :func:`_optimise` and its certificate."""
    notes: list[str] = []
    convex, final, starts, winner, bound = _optimise(
        info, cons, criterion, mean_subtraction, convex_solvers, n_random_starts, seed, notes
    )
    certificate = {
        "criterion": criterion,
        "n_params": info.n_params,
        "gradient": None if convex.gradient is None else {n: float(g) for n, g in zip(info.names, convex.gradient)},
        "max_over_feasible": convex.max_gradient,
        "efficiency_bound": bound,
        "relaxation": "symmetric part of Gamma, batchwise mean subtraction"
        if mean_subtraction == "complete"
        else "symmetric part of Gamma",
    }
    return _Step(
        final,
        bound,
        lambda w: info.value(w, mean_subtraction, criterion),
        criterion,
        convex.weights,
        certificate,
        notes,
        starts,
        winner,
    )


def _robust_step(
    profile: ShipProfile,
    prims: list[Primitive],
    cons: Constraints,
    criterion: str,
    mean_subtraction: str,
    prior: ParameterPrior,
    draw_info: DrawInformation | None,
    local_weights: np.ndarray,
) -> _Step:
    """bayes-D or maximin-D over the prior's draws (:mod:`expdesign.robust`), beside the local
    design ``local_weights`` (what ``--criterion D`` gives with the same options)."""
    dinfo = draw_info if draw_info is not None else draw_information(profile, prims, prior, mean_subtraction, held_out=True)
    rd = robust_design(dinfo, criterion, cons, prior, mean_subtraction, local_weights)
    return _Step(
        rd.weights,
        rd.efficiency_bound,
        lambda w: dinfo.value(w, criterion=criterion),
        "D",
        rd.weights,
        rd.certificate,
        rd.notes,
        winner=criterion,
        section=rd.section,
        draws=dinfo,
    )


def _rounded_rows(section: dict, local: dict, robust: dict, criterion: str, notes: list[str]) -> None:
    """The rounded local and robust mixes' D-efficiencies in the report section, and a note when
    rounding leaves the robust mix's 10th percentile no better than the local one's."""
    section["d_efficiency"]["local-D rounded"] = local
    section["d_efficiency"]["rounded"] = robust
    if robust["p10"] <= local["p10"]:
        notes.append(
            f"rounded to whole units, the {criterion} mix's 10th-percentile D-efficiency ({robust['p10']:.3f}) is no "
            f"better than the rounded local mix's ({local['p10']:.3f}): rounding removes the robust gain at this trial length"
        )


def _check_prior_options(
    criterion: str, parameter_prior: ParameterPrior | None, disturbed_realisations: int, prior: PrimitiveInfo | None
) -> None:
    """Refuse what a criterion cannot use: a robust one (bayes-D, maximin-D) needs the parameter prior's draws and
    no noisy moments or data already collected (its information at each draw is noise-free); a local one takes no
    parameter prior."""
    robust = criterion in ROBUST
    if robust and parameter_prior is None:
        raise DesignError(
            f"--criterion {criterion} designs over parameter draws: give --prior-spread FRACTION or --prior-file PATH"
        )
    if robust and (disturbed_realisations or prior is not None):
        given = "--noisy-moments (disturbed_realisations)" if disturbed_realisations else "data already collected (prior)"
        raise DesignError(
            f"{given} is not used by --criterion {criterion} (its information at each draw is noise-free, "
            "with no data counted in): drop it, or design with --criterion D"
        )
    if parameter_prior is not None and not robust:
        raise DesignError(
            f"a parameter prior is for the robust criteria: give --criterion bayes-D or maximin-D (got {criterion!r})"
        )


def _trial_seconds(trial_length_s: float | None, prims: list[Primitive]) -> float:
    """The trial length the rounding and cost budgets use: ``trial_length_s``, by default every primitive once."""
    total_s = float(trial_length_s) if trial_length_s is not None else float(sum(p.duration_s for p in prims))
    if total_s <= 0:
        raise DesignError(f"trial length must be > 0 seconds, got {trial_length_s}")
    return total_s


def _rounded(
    step: _Step,
    info: InfoSet,
    prims: list[Primitive],
    total_samples: int,
    criterion: str,
    mean_subtraction: str,
    notes: list[str],
) -> tuple[np.ndarray, Rounded]:
    """Each primitive's unit (samples between natural split points) and ``step``'s shares rounded to
    whole units of a ``total_samples`` trial (:func:`expdesign.rounding.round_design`). For a robust
    criterion the local-D design is rounded too and both are scored on the draws (rows of ``step.section``):
    rounding can take the robust gain away."""
    value, p, names = step.value, info.n_params, [pr.name for pr in prims]
    units = np.array([unit_samples(pr) for pr in prims])
    rnd = round_design(step.weights, units, total_samples, lambda s: value(s / total_samples), p, criterion=step.eff_kind)
    if step.section is not None:
        lw = np.array([step.section["local_weights"][n] for n in names])
        lrnd = round_design(lw, units, total_samples, lambda s: info.value(s / total_samples, mean_subtraction), p)
        _rounded_rows(step.section, step.draws.score(lrnd.fractions), step.draws.score(rnd.fractions), criterion, notes)
    return units, rnd


def run_design(
    profile: ShipProfile | str,
    primitives: list[Primitive] | None = None,
    *,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length_s: float | None = None,
    min_frac: float | dict[str, float] | None = None,
    max_frac: float | dict[str, float] | None = None,
    seed: int = 0,
    psi_switch: float | None = None,
    costs: dict[str, dict[str, float]] | None = None,
    budgets: dict[str, float] | None = None,
    disturbed_realisations: int = 0,
    prior: PrimitiveInfo | None = None,
    prior_samples: int = 0,
    n_random_starts: int = 4,
    infos: list[PrimitiveInfo] | None = None,
    references: dict[str, dict[str, float]] | None = None,
    convex_solvers: tuple[str, ...] = ("CLARABEL", "SCS"),
    parameter_prior: ParameterPrior | None = None,
    draw_info: DrawInformation | None = None,
) -> Design:
    """Design the mix of ``primitives`` (default: the profile's thesis dictionary).

    ``trial_length_s`` (default: every primitive once) sets the rounding and cost budgets;
    ``min_frac``/``max_frac`` (number or {name: fraction}); ``costs``/``budgets`` per resource
    (per-second rates by primitive, total budget); ``disturbed_realisations`` > 0 estimates the
    moments from that many noisy, current-disturbed simulations (seeded) instead of the nominal
    states; ``prior``/``prior_samples``: data already collected (7.58); ``infos`` skips the
    moment computation (precomputed moments in the order of ``primitives``); ``references``
    (label -> {primitive: share}) are scored by their criterion efficiency relative to the result;
    ``convex_solvers``: the solvers of the convex step in order (see :func:`expdesign.dopt.solve_convex`).
    ``criterion`` "bayes-D" or "maximin-D" designs over the draws of ``parameter_prior``
    (:mod:`expdesign.robust`; ``draw_info``: its matrices computed already for ``primitives``);
    "local-D" is "D".
    """
    if isinstance(profile, str):
        profile = load_profile(profile)
    criterion = canonical_criterion(criterion)
    robust = criterion in ROBUST
    _check_prior_options(criterion, parameter_prior, disturbed_realisations, prior)
    notes: list[str] = []
    prims = _informative_library(profile, primitives, psi_switch, "D" if robust else criterion, mean_subtraction, notes)
    names = [p.name for p in prims]
    if infos is None:
        infos = _moments(profile, prims, disturbed_realisations, seed)
    total_s = _trial_seconds(trial_length_s, prims)
    prior_w = prior_samples * profile.sample_time / total_s if prior is not None else 0.0
    info = InfoSet.from_infos(infos, prior, prior_w)
    check_identifiable(profile, info, mean_subtraction)
    cons = Constraints.build(names, min_frac, max_frac, costs, budgets, total_s)
    if robust:
        local = _local_step(info, cons, "D", mean_subtraction, convex_solvers, n_random_starts, seed)
        step = _robust_step(profile, prims, cons, criterion, mean_subtraction, parameter_prior, draw_info, local.weights)
    else:
        step = _local_step(info, cons, criterion, mean_subtraction, convex_solvers, n_random_starts, seed)
    final, bound, value, eff_kind, section = step.weights, step.bound, step.value, step.eff_kind, step.section
    notes += step.notes
    p = info.n_params
    val = value(final)
    uni = value(np.full(len(names), 1.0 / len(names)))
    ts = profile.sample_time
    units, rnd = _rounded(step, info, prims, int(round(total_s / ts)), criterion, mean_subtraction, notes)
    refs = _reference_efficiencies(references, names, value, val, p, eff_kind)
    return Design(
        profile=profile.name,
        criterion=criterion,
        mean_subtraction=mean_subtraction,
        weights={n: float(w) for n, w in zip(names, final)},
        logdet=info.logdet(final, mean_subtraction),
        efficiency_vs_uniform=criterion_efficiency(val, uni, p, eff_kind),
        efficiency_bound=bound,
        rounded={n: int(c) for n, c in zip(names, rnd.counts)},
        unit_s={n: float(u * ts) for n, u in zip(names, units)},
        trial_length_s=total_s,
        rounded_fractions={n: float(f) for n, f in zip(names, rnd.fractions)},
        rounding_efficiency=rnd.efficiency,
        convex_weights={n: float(w) for n, w in zip(names, step.convex_weights)},
        certificate=step.certificate,
        solver_notes=notes,
        starts=step.starts,
        winner=step.winner,
        n_params=p,
        references=refs,
        warnings=[*profile.load_warnings, *mean_subtraction_warnings(profile, info, final, mean_subtraction)],
        robust=section,
    )
