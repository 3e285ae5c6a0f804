"""The design step of the planning chain: which manoeuvres, how many times (Ljungberg 2022, chapter 7 -> 8).

The D/A/E-optimal mix of the ship's library (:func:`expdesign.api.run_design`, the same
criterion and mean-subtraction options as ``shiptrial design``) is rounded to *whole manoeuvres*
that fit the trial length (efficient rounding and exchanges, :func:`expdesign.rounding.round_design`
with one unit = one whole primitive): the lattice planner's counters d_q (8.4) are those counts.
A primitive that fits nowhere on the map is dropped and the design redone without it; the
criterion efficiency lost against the full library's optimum is stated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from expdesign.api import Design, mean_subtraction_warnings, run_design
from expdesign.dopt import DEDICATED, ROBUST, InfoSet, canonical_criterion
from expdesign.errors import DesignError
from expdesign.prior import ParameterPrior
from expdesign.robust import DrawInformation, draw_information
from expdesign.rounding import criterion_efficiency, round_design
from maps.searoom import SeaRoom, held_parameters, held_records, with_short_forms
from maps.sizing import Needs, km, water_text
from primitives.information import PrimitiveInfo, library_information, reduced_profile, restrict
from primitives.library import Primitive, build_library, library_notes, thesis_primitives
from primitives.ship import ShipProfile


@dataclass
class TrialDesign:
    """Whole-manoeuvre counts from the design, and what the plan states about them.

    ``record`` is the plan's ``design`` field: criterion, mean subtraction, continuous weights,
    rounded counts, D-efficiency of the rounded design against the continuous optimum and the
    primitives dropped because they fit nowhere on the map.
    """

    counts: dict[str, int]
    primitives: list[Primitive]  # the library the design ran on (informative)
    record: dict[str, Any]
    design: Design  # of the final (possibly re-done) design
    notes: list[str] = field(default_factory=list)

    def support(self) -> list[Primitive]:
        return [p for p in self.primitives if self.counts.get(p.name, 0) > 0]


UNUSED_WEIGHT = 1e-4  # a continuous weight below this is the optimiser's zero
# The dedicated simplex solver first: the planner designs on every call and importing cvxpy costs
# over a second of it; it gives cvxpy's weights wherever it applies (tests/test_simplexsolver.py).
SOLVERS = (DEDICATED, "CLARABEL", "SCS")


class NoFitError(DesignError):
    """The design's manoeuvres fit nowhere on the map (the CLI exits 1: the map, not the input, is short)."""


class TrialTooShort(DesignError):
    """The trial length cannot hold one of each manoeuvre the design needs, or even one
    manoeuvre (what fits a small map may need fewer or shorter: :func:`design_for_map` tries
    that before it says so). ``support``: the manoeuvres the design needs one of each, ``need_s``:
    the trial length they take, ``held``: the parameters that design held (empty: none)."""

    def __init__(self, msg: str, support: tuple[str, ...] = (), need_s: float = 0.0, held: tuple[str, ...] = ()):
        super().__init__(msg)
        self.support, self.need_s, self.held = tuple(support), float(need_s), tuple(held)


def ship_library(profile: ShipProfile) -> list[Primitive]:
    """The informative primitives the design chooses from: the profile's thesis dictionary (what
    ``shiptrial design`` uses), else every informative manoeuvre of its library."""
    lib = thesis_primitives(profile)
    if not lib:
        lib = [p for p in build_library(profile, basic=False) if p.kind == "informative"]
    if not lib:
        raise DesignError(f"profile {profile.name!r}: its library has no informative manoeuvre to design with")
    return lib


def _whole_manoeuvres(
    weights: np.ndarray,
    prims: list[Primitive],
    info: InfoSet,
    trial_s: float,
    criterion: str,
    mean_subtraction: str,
    draws: DrawInformation | None = None,
) -> tuple[np.ndarray, float, float]:
    """Counts of whole primitives for the trial length, the D-efficiency of the rounded mix
    against the continuous optimum (exp((log det M(n) - log det M(w)) / p)) and its efficiency
    in the design's own criterion (a robust one over ``draws``, its values log dets: D-type)."""
    ts = prims[0].profile.sample_time
    units = np.array([p.n_samples for p in prims])
    total = int(round(trial_s / ts))
    if total < units.min():
        short = min(prims, key=lambda p: p.n_samples)
        raise TrialTooShort(
            f"--trial-length {trial_s:g} s is shorter than one manoeuvre (the shortest, {short.name}, "
            f"lasts {short.duration_s:.0f} s): give --trial-length >= {short.duration_s:.0f}"
        )
    crit = draws if criterion in ROBUST else info  # the object that scores the design's own criterion
    kind = "D" if criterion in ROBUST else criterion
    rnd = round_design(
        weights, units, total, lambda s: crit.value(s / total, mean_subtraction, criterion), info.n_params, criterion=kind
    )
    counts = rnd.counts
    sel = weights > 1e-9
    if not np.isfinite(info.value(counts * units / max(1, counts @ units), mean_subtraction, "D")):
        need = float(units[sel].sum() * ts)
        names = tuple(p.name for p, s in zip(prims, sel) if s)
        raise TrialTooShort(
            f"--trial-length {trial_s:g} s cannot hold one of each manoeuvre the design needs "
            f"({', '.join(names)}): give --trial-length >= {need:.0f}",
            names,
            need,
        )
    real = counts * units / (counts @ units)
    d_eff = criterion_efficiency(
        info.value(real, mean_subtraction, "D"), info.value(weights, mean_subtraction, "D"), info.n_params, "D"
    )
    own = criterion_efficiency(
        crit.value(real, mean_subtraction, criterion), crit.value(weights, mean_subtraction, criterion), info.n_params, kind
    )
    return counts, d_eff, own


def design_counts(
    profile: ShipProfile,
    library: list[Primitive] | None = None,
    *,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length_s: float | None = None,
    seed: int = 0,
    exclude: dict[str, tuple[float, float]] | None = None,
    infos: list[PrimitiveInfo] | None = None,
    baseline: float | None = None,
    parameter_prior: ParameterPrior | None = None,
    draws: DrawInformation | None = None,
) -> TrialDesign:
    """Design the mix of ``library`` (default :func:`ship_library`) without the primitives in
    ``exclude`` ({name: (along, cross) metres of water it needs}) and round it to whole manoeuvres.

    ``trial_length_s`` defaults to every primitive of the library once (as ``shiptrial design``).
    ``baseline``: criterion value of the full library's optimum, for the efficiency lost by the
    exclusions (computed here when None). ``criterion`` bayes-D or maximin-D designs over the
    draws of ``parameter_prior`` (``draws``: their matrices for ``library``, computed already).
    """
    criterion = canonical_criterion(criterion)
    lib = [p for p in (library if library is not None else ship_library(profile)) if p.kind == "informative"]
    if infos is None:
        infos = library_information(profile, lib)
    if criterion in ROBUST and draws is None and parameter_prior is not None:
        draws = draw_information(profile, lib, parameter_prior, mean_subtraction, held_out=True)
    exclude = dict(exclude or {})
    trial_s = float(trial_length_s) if trial_length_s is not None else float(sum(p.duration_s for p in lib))
    if trial_s <= 0:
        raise DesignError(f"--trial-length must be > 0 s, got {trial_s:g}")
    keep = [i for i, p in enumerate(lib) if p.name not in exclude]
    prims, sub = [lib[i] for i in keep], [infos[i] for i in keep]
    sub_draws = draws.subset(keep) if draws is not None else None
    d = _design_kept(profile, prims, sub, exclude, criterion, mean_subtraction, trial_s, seed, parameter_prior, sub_draws)
    info = InfoSet.from_infos(sub)
    w = np.array([d.weights[p.name] for p in prims])
    counts, d_eff, c_eff = _whole_manoeuvres(w, prims, info, trial_s, criterion, mean_subtraction, sub_draws)
    notes, dropped = [], []
    if exclude:
        wf = np.zeros(len(lib))
        wf[keep] = w
        loss = _exclusion_loss(
            profile, lib, infos, wf, baseline, criterion, mean_subtraction, trial_s, seed, parameter_prior, draws
        )
        dropped = [
            {"primitive": name, "needs_m": [float(need[0]), float(need[1])], "efficiency_loss": float(max(0.0, loss))}
            | (need.record() if isinstance(need, Needs) else {})
            for name, need in exclude.items()
        ]
        why = "fits nowhere on the map" + (
            ", or not with the rest of the mix" if any(getattr(n, "apart", False) for n in exclude.values()) else ""
        )
        notes.append(
            f"design redone without {', '.join(exclude)} ({why}): {criterion}-efficiency "
            f"{100 * (1 - loss):.1f} % of the full library's optimum"
        )
    record = _record(prims, w, counts, criterion, mean_subtraction, d_eff, c_eff, dropped, trial_s)
    if d.robust:  # each mix's D-efficiency over the draws, "rounded" now the whole manoeuvres sailed
        sailed_w = counts * np.array([p.n_samples for p in prims], float)
        # the unit-rounded rows of run_design give way to the whole manoeuvres sailed (the local
        # mix's whole-manoeuvre rounding is not computed here)
        eff = {k: v for k, v in d.robust["d_efficiency"].items() if k != "local-D rounded"}
        eff["rounded"] = sub_draws.score(sailed_w / sailed_w.sum())
        record["robust"] = d.robust | {"d_efficiency": eff}
    sailed = counts * np.array([p.n_samples for p in prims], float)
    notes += [f"warning: {w}" for w in mean_subtraction_warnings(profile, info, sailed / sailed.sum(), mean_subtraction)]
    notes += library_notes(profile)  # a manoeuvre family the ship's library lacks (pods aft: no steady sway)
    notes.insert(
        0,
        f"counts from the {criterion}-optimal design ({mean_subtraction} mean subtraction) over "
        f"{len(prims)} primitives, rounded to whole manoeuvres for {trial_s:.0f} s: "
        f"{', '.join(f'{k} x{v}' for k, v in record['counts'].items())} ({criterion}-efficiency {c_eff:.3f} of the continuous optimum)",
    )
    return TrialDesign(record["counts"], prims, record, d, notes)


def _design_kept(
    profile: ShipProfile,
    prims: list[Primitive],
    infos: list[PrimitiveInfo],
    exclude: dict[str, tuple[float, float]],
    criterion: str,
    mean_subtraction: str,
    trial_s: float,
    seed: int,
    parameter_prior: ParameterPrior | None = None,
    draws: DrawInformation | None = None,
) -> Design:
    """The continuous design of the primitives kept (``prims``, their moments ``infos``); when
    the exclusions leave nothing, or nothing that identifies the model, a :class:`NoFitError`
    that says what was dropped and why."""
    if not prims:
        raise NoFitError(
            f"all {len(exclude)} manoeuvres of {profile.name}'s library fit nowhere in the water reachable "
            f"from the start: {_needs(exclude)}; {_what_helps(exclude)}"
        )
    try:
        return run_design(
            profile,
            prims,
            criterion=criterion,
            mean_subtraction=mean_subtraction,
            trial_length_s=trial_s,
            seed=seed,
            infos=infos,
            convex_solvers=SOLVERS,
            parameter_prior=parameter_prior,
            draw_info=draws,
        )
    except DesignError as exc:
        if exclude:  # the remaining library cannot identify the model: say what was dropped and why
            dead = _dead_count(str(exc))
            raise NoFitError(
                f"{len(exclude)} manoeuvre(s) fit nowhere in the water reachable from the start: {_needs(exclude)}; "
                f"without them the rest of {profile.name}'s library cannot identify the model{dead}; "
                f"{_what_helps(exclude)}"
            ) from None
        raise


def _exclusion_loss(
    profile: ShipProfile,
    lib: list[Primitive],
    infos: list[PrimitiveInfo],
    wf: np.ndarray,
    baseline: float | None,
    criterion: str,
    mean_subtraction: str,
    trial_s: float,
    seed: int,
    parameter_prior: ParameterPrior | None = None,
    draws: DrawInformation | None = None,
) -> float:
    """The criterion efficiency the mix ``wf`` (over the whole library, zero on the exclusions)
    loses against the full library's optimum ``baseline`` (designed here when None)."""
    full = draws if criterion in ROBUST else InfoSet.from_infos(infos)
    if baseline is None:
        base = run_design(
            profile,
            lib,
            criterion=criterion,
            mean_subtraction=mean_subtraction,
            trial_length_s=trial_s,
            seed=seed,
            infos=infos,
            convex_solvers=SOLVERS,
            parameter_prior=parameter_prior,
            draw_info=draws,
        )
        baseline = full.value(np.array([base.weights[p.name] for p in lib]), mean_subtraction, criterion)
    kind = "D" if criterion in ROBUST else criterion
    return 1.0 - criterion_efficiency(full.value(wf, mean_subtraction, criterion), baseline, full.n_params, kind)


def _record(
    prims: list[Primitive],
    w: np.ndarray,
    counts: np.ndarray,
    criterion: str,
    mean_subtraction: str,
    d_eff: float,
    c_eff: float,
    dropped: list[dict[str, Any]],
    trial_s: float,
) -> dict[str, Any]:
    """The plan's ``design`` field (:attr:`TrialDesign.record`)."""
    # the support only: a primitive the optimum gives (next to) no weight is listed once, as not used
    used = [x > UNUSED_WEIGHT or c > 0 for x, c in zip(w, counts)]
    return {
        "criterion": criterion,
        "mean_subtraction": mean_subtraction,
        "weights": {p.name: float(x) for p, x, u in zip(prims, w, used) if u},
        "counts": {p.name: int(c) for p, c in zip(prims, counts) if c > 0},
        "not_used": [p.name for p, u in zip(prims, used) if not u],
        "d_efficiency": float(d_eff),
        "efficiency": float(c_eff),
        "dropped": dropped,
        "trial_length_s": trial_s,
        "planned_s": float(sum(c * p.duration_s for p, c in zip(prims, counts))),
    }


def _what_helps(exclude: dict[str, tuple[float, float]]) -> str:
    """What would let the design plan: a map with the open water the smallest excluded manoeuvre
    takes (at least that when it is larger than the water, more when its move has no placement
    reachable: :class:`maps.sizing.Needs`), e.g. the open-sea map shipped with the package (60 x 60 km)."""
    need = min(exclude.values(), key=lambda ac: ac[0] * ac[1])
    how = "more than" if getattr(need, "reach", False) else "at least"
    return (
        f"plan on a map with {how} {km(need[0])} x {km(need[1])} of open water around the start, e.g. the package's "
        "open-sea map: --map open-sea"
    )


def _needs(exclude: dict[str, tuple[float, float]], show: int = 2) -> str:
    """One short clause: the manoeuvres that fit nowhere, smallest first, each with the open water
    it needs or the move that has no reachable placement (:func:`maps.sizing.water_text`); past
    ``show`` of them only a count."""
    items = sorted(exclude.items(), key=lambda kv: kv[1][0] * kv[1][1])
    head = ", ".join(water_text(n, need) for n, need in items[:show])
    more = len(items) - show
    return head + (f" (and {more} more, each larger)" if more > 0 else "")


def _dead_count(msg: str) -> str:
    """' (N parameters unidentifiable)' from a check_identifiable message, else ''."""
    import re

    hit = re.search(r"cannot identify \[([^\]]*)\]", msg)
    return f" ({len(hit.group(1).split(','))} parameters unidentifiable)" if hit else ""


@dataclass
class FirstDesign:
    """The design of the whole library, before the map is consulted (:func:`first_design`):
    what :func:`design_for_map` starts from. It depends on the ship and the design options only,
    so it can be computed beside the map work (``plan-trial`` has it made in its drawer process)."""

    library: list[Primitive]  # informative
    infos: list[PrimitiveInfo]
    design: TrialDesign
    baseline: float  # criterion value of the full library's optimum
    draws: DrawInformation | None = None  # a robust criterion's matrices over the prior's draws


def first_design(
    profile: ShipProfile,
    library: list[Primitive] | None = None,
    *,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length_s: float | None = None,
    seed: int = 0,
    parameter_prior: ParameterPrior | None = None,
    infos: list[PrimitiveInfo] | None = None,
) -> FirstDesign:
    """Design ``library`` (default :func:`ship_library`) and round it to whole manoeuvres
    (``parameter_prior``: the draws of a robust criterion; ``infos``: the informative primitives'
    :func:`primitives.information.library_information`, computed already)."""
    criterion = canonical_criterion(criterion)
    if library is None:  # the ship's own library: kept between commands (maps.librarycache)
        from maps.librarycache import kept_library

        lib, infos = kept_library(profile)
    else:
        lib = [p for p in library if p.kind == "informative"]
        infos = library_information(profile, lib) if infos is None else infos
    draws = (
        draw_information(profile, lib, parameter_prior, mean_subtraction, held_out=True)
        if criterion in ROBUST and parameter_prior
        else None
    )
    td = design_counts(
        profile,
        lib,
        criterion=criterion,
        mean_subtraction=mean_subtraction,
        trial_length_s=trial_length_s,
        seed=seed,
        infos=infos,
        parameter_prior=parameter_prior,
        draws=draws,
    )
    full = draws if draws is not None else InfoSet.from_infos(infos)
    baseline = full.value(np.array([td.design.weights[p.name] for p in lib]), mean_subtraction, criterion)
    return FirstDesign(lib, infos, td, baseline, draws)


def design_for_map(
    profile: ShipProfile,
    fits_nowhere: Callable[[list[Primitive], dict[str, int]], dict[str, tuple[float, float]]],
    library: list[Primitive] | None = None,
    *,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length_s: float | None = None,
    seed: int = 0,
    first: FirstDesign | None = None,
    parameter_prior: ParameterPrior | None = None,
) -> TrialDesign:
    """Design, check the support against the map, redesign without what fits nowhere.

    ``fits_nowhere(primitives, counts) -> {name: (along, cross)}`` tells which of the designed
    primitives have no place on the map (e.g. ``build_lattice(...).fits_nowhere``). ``first``:
    :func:`first_design` of the same profile, library and options, computed already.
    """
    criterion = canonical_criterion(criterion)
    too_short: TrialTooShort | None = None
    if first is None:
        kw = dict(criterion=criterion, mean_subtraction=mean_subtraction, seed=seed, parameter_prior=parameter_prior)
        try:
            first = first_design(profile, library, trial_length_s=trial_length_s, **kw)
        except TrialTooShort as exc:  # the whole library's mix needs more time: what fits the map may need less
            too_short = exc
            first = first_design(profile, library, **kw)
    room = SeaRoom(list(first.library), list(first.infos), {}, set())
    td, draws = first.design, first.draws
    # the trial length of the redesigns: the one asked for, else the first design's (the ship's library once)
    lengths = [trial_length_s if trial_length_s is not None else first.design.record["trial_length_s"]]
    lengths.append(first.design.record["trial_length_s"])  # to learn the support when the asked one is too short for it
    while True:
        bad = fits_nowhere(td.support(), td.counts)
        if not bad:
            if too_short is not None:
                raise too_short
            return td
        room.exclude.update(bad)
        if with_short_forms(profile, room, fits_nowhere) and draws is not None:  # the draws' matrices of the new ones too
            draws = draw_information(profile, room.library, parameter_prior, mean_subtraction, held_out=True)
        for i, trial_s in enumerate(lengths):
            try:
                td = _redesign(profile, room, first, trial_s, criterion, mean_subtraction, seed, parameter_prior, draws)
                too_short = None if i == 0 else too_short  # only the length asked for clears it
                break
            except TrialTooShort as exc:
                if i == len(lengths) - 1:
                    raise
                too_short = exc


def _redesign(
    profile: ShipProfile,
    room: SeaRoom,
    first: FirstDesign,
    trial_s: float,
    criterion: str,
    mean_subtraction: str,
    seed: int,
    parameter_prior: ParameterPrior | None,
    draws: DrawInformation | None,
) -> TrialDesign:
    """The design over what fits the map so far; the parameters it cannot identify held."""
    opts = dict(criterion=criterion, mean_subtraction=mean_subtraction, trial_length_s=trial_s, seed=seed)
    try:
        return design_counts(
            profile, room.library, **opts, exclude=room.exclude, infos=room.infos, baseline=first.baseline,
            parameter_prior=parameter_prior, draws=draws,
        )  # fmt: skip
    except NoFitError:
        held = held_parameters(profile, room, mean_subtraction)
        if not room.fitting or not held:
            raise
        if criterion in ROBUST and draws is None:  # the draws' matrices over every parameter, restricted below
            draws = draw_information(profile, room.library, parameter_prior, mean_subtraction, held_out=True)
        return _held_design(profile, room, held, opts, parameter_prior, draws)


def _held_design(
    profile: ShipProfile,
    room: SeaRoom,
    held: list[str],
    opts: dict[str, Any],
    parameter_prior: ParameterPrior | None = None,
    draws: DrawInformation | None = None,
) -> TrialDesign:
    """The design over the parameters what fits can identify, the others held at the profile's
    values; its record lists them (:func:`maps.searoom.held_records`). A robust criterion's draws
    keep varying the held parameters (the ship is not the profile there either), and each draw's
    information is restricted to the parameters estimated (:meth:`DrawInformation.restrict`)."""
    keep = np.array([n not in held for n in profile.predictor_param_names])
    reduced = reduced_profile(profile, held)
    robust = {} if draws is None else dict(parameter_prior=parameter_prior, draws=draws.restrict(keep))
    try:
        td = design_counts(reduced, room.library, **opts, exclude=room.exclude, infos=restrict(room.infos, keep), **robust)
    except TrialTooShort as exc:
        exc.held = tuple(held)
        raise
    rows, notes = held_records(profile, room, held, opts["mean_subtraction"])
    td.record["held_parameters"] = rows
    td.notes[1:1] = notes
    return td
