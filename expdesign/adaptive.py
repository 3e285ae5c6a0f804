"""Re-design mid-trial: the information already gathered counted in the rest of the trial.

Ljungberg (2022), section 7.5, re-planning (7.58): when part of the experiment has been sailed,
its moments enter the design as a fixed prior term, Gamma = a Gamma_sailed + sum_q w_q Gamma_q,
and the rest of the trial maximises the criterion of the whole. Here

1. the model is re-identified from the recordings of the steps sailed with the project's own
   IV estimator (:func:`expdesign.estimators.estimate`, the estimator the information matrices
   (7.50)-(7.57) describe and the Monte Carlo runs);
2. M_sailed is the moments of those recordings, with instruments simulated by the predictor at
   the re-identified parameters (:func:`expdesign.estimators.data_information`), each run's own
   mean removed under 'batchwise' (7.53), one mean over the trial under 'complete' (7.57);
3. M_rest: every library primitive's inputs replayed through the predictor at the re-identified
   parameters, regressors and instruments from that simulation (the converged IV);
4. the mix of the rest is designed with the sailed moments as the prior term
   (:func:`expdesign.api.run_design` ``prior``) and rounded to whole manoeuvres that fit the
   time left.

Pure functions over dataclasses; reading plans and recordings is :mod:`maps.resume`'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from expdesign.api import run_design
from expdesign.dopt import DEDICATED, InfoSet
from expdesign.errors import DesignError
from expdesign.estimators import Segment, data_information, estimate
from expdesign.rounding import round_design
from primitives.information import (
    PrimitiveInfo,
    information_moments,
    library_information,
    reduced_profile,
    restrict,
    same_structure,
)
from primitives.library import Primitive
from primitives.regressors import block_mask, predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import SimResult, signals_read, simulate

# A run whose simulated output (predictor at the re-identified parameters, from the run's own
# inputs and first state) misses the recorded one by more than this fraction of the recorded
# signal's size (RMS over u, v, r, each normalised by its RMS) disagrees with the model: diagnose's domain.
DISAGREE_NRMSE = 0.3
DESIGN_SOLVERS = (DEDICATED, "CLARABEL", "SCS")  # as the planner: no cvxpy import when the dedicated solver applies


@dataclass
class SailedRun:
    """The recording of one informative step sailed: inputs (N, m) in the profile's input
    order, measured body velocities y (N+1, 3) and heading psi (N+1,) (rad)."""

    step: int  # the plan's step index (0-based)
    primitive: str
    inputs: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    source: str = ""

    @property
    def n_samples(self) -> int:
        return int(self.inputs.shape[0])

    def segment(self) -> Segment:
        return Segment(self.inputs, self.y[None], self.y[0], self.psi[None])


@dataclass
class Reidentification:
    """The predictor's parameters re-identified from the runs sailed, and how well the model
    reproduces each run (normalised RMS of the simulated output; ``disagrees``: the runs beyond
    :data:`DISAGREE_NRMSE`, one line each)."""

    theta: np.ndarray
    names: list[str]
    nrmse: dict[str, float]
    disagrees: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "parameters": {n: float(v) for n, v in zip(self.names, self.theta)},
            "simulation_nrmse": self.nrmse,
            "disagrees": self.disagrees,
            "notes": self.notes,
        }


@dataclass
class Redesign:
    """Whole-manoeuvre counts of the rest of the trial, the continuous mix behind them and what
    the sailed information is worth: log det of a M_sailed alone and of the whole trial planned,
    a M_sailed + sum w_q M_q, both per sample of the time left (7.58)."""

    counts: dict[str, int]
    weights: dict[str, float]
    time_left_s: float
    planned_s: float
    logdet_sailed: float
    logdet_total: float
    reid: Reidentification
    record: dict[str, Any]
    notes: list[str] = field(default_factory=list)
    logdet_continuous: float = float("nan")  # the continuous optimum's, before rounding: the bound rounding leaves


def rest_problem(
    profile: ShipProfile,
    lib: Sequence[Primitive],
    runs: Sequence[SailedRun],
    theta: np.ndarray,
    time_left_s: float,
    mean_subtraction: str,
    keep: np.ndarray | None = None,
) -> tuple[list[PrimitiveInfo], PrimitiveInfo, InfoSet, list[str]]:
    """M_rest and M_sailed at ``theta`` and their (7.58) sum's InfoSet, the sailed term weighted
    by its samples against the time left's; ``keep``: the parameters estimated (a boolean mask),
    the others held, their rows and columns left out."""
    infos, notes = rest_information(profile, lib, theta)
    sailed = sailed_information(profile, runs, None if notes else theta, mean_subtraction)
    if keep is not None:
        infos, sailed = restrict(infos, keep), restrict([sailed], keep)[0]
    info = InfoSet.from_infos(infos, sailed, sailed.n_samples * profile.sample_time / time_left_s)
    return infos, sailed, info, notes


def rest_efficiency(
    profile: ShipProfile,
    library: Sequence[Primitive],
    runs: Sequence[SailedRun],
    theta: np.ndarray,
    counts: dict[str, int],
    time_left_s: float,
    logdet_optimum: float,
    mean_subtraction: str = "complete",
) -> float:
    """D-efficiency (det Gamma_counts / det Gamma_opt)^(1/p) at ``theta`` of the whole trial
    whose rest is ``counts`` (whole manoeuvres of ``library``), both trials counting the sailed
    ``runs`` (7.58); ``logdet_optimum``: :attr:`Redesign.logdet_continuous` of the re-design at
    ``theta``. Evaluated at the true parameters this bounds what any re-design can gain over the
    rest ``counts``: 1.0 means the rest is already the optimum there."""
    lib = [p for p in library if p.kind == "informative"]
    unknown = sorted(set(counts) - {p.name for p in lib})
    if unknown:  # a misspelt name would score a shorter rest without a word
        raise DesignError(f"rest_efficiency: {', '.join(unknown)} not an informative manoeuvre of the library")
    _, _, info, _ = rest_problem(profile, lib, runs, theta, time_left_s, mean_subtraction)
    total = int(round(time_left_s / profile.sample_time))  # as redesign's rounding counts it
    w = np.array([counts.get(p.name, 0) * p.n_samples / total for p in lib])
    return float(np.exp((info.logdet(w, mean_subtraction) - logdet_optimum) / info.n_params))


def _simulate_predictor(profile: ShipProfile, inputs: np.ndarray, theta: np.ndarray, nu0: np.ndarray) -> SimResult:
    """The predictor simulated at ``theta`` (a diverging estimate gives non-finite states, checked by the callers)."""
    with np.errstate(all="ignore"):
        return simulate(
            profile, inputs, theta, terms=profile.predictor, nu0=nu0, positions="psi" in signals_read(profile.predictor)
        )


def profile_predictor(profile: ShipProfile, prims: Sequence[Primitive]) -> np.ndarray:
    """The predictor's parameters of the profile as it stands: the least-squares fit of the
    predictor to the library's noise-free nominal simulation (the profile's own values when the
    predictor is its model structure)."""
    if same_structure(profile):
        return profile.params()
    segs = [Segment(p.inputs, p.nu[None], p.nu0, p.track[None, :, 2]) for p in prims]
    return estimate(profile, segs, method="ls", mean_subtraction="none").theta[0]


def reidentify(
    profile: ShipProfile,
    runs: Sequence[SailedRun],
    reference: np.ndarray,
    mean_subtraction: str = "batchwise",
) -> Reidentification:
    """IV estimate of the predictor from the runs sailed (each its own sub-experiment), and each
    run's simulated-output fit at the estimate. A DOF the runs cannot identify yet (its IV system
    singular: no excitation of it sailed) keeps its ``reference`` values (the profile's,
    :func:`profile_predictor`), said in the notes; never a NaN passed on."""
    if not runs:
        raise DesignError("no recordings of a sailed manoeuvre: give --recordings of at least one informative step")
    est = estimate(profile, [r.segment() for r in runs], method="iv", mean_subtraction=mean_subtraction)
    theta = est.theta[0].copy()
    names = profile.predictor_param_names
    # the estimator's own notes speak of Monte Carlo realisations: here there is one, the trial
    notes = [
        "the IV iteration kept its first instruments: the predictor simulated at an estimate diverged"
        for n in est.notes
        if "kept earlier instruments" in n
    ]
    held = np.zeros(profile.predictor.n_dof, bool)  # the DOFs kept at the reference values
    for i in range(profile.predictor.n_dof):
        sl = profile.predictor.dof_slice(i)
        if not np.all(np.isfinite(theta[sl])):
            theta[sl] = reference[sl]
            held[i] = True
            notes.append(
                f"the recordings so far cannot identify {', '.join(names[sl])}: held at the profile's values "
                "until the manoeuvres that excite them are sailed"
            )
    nrmse: dict[str, float] = {}
    disagree: list[str] = []
    if not same_structure(profile):
        notes.append("the recordings' fit to the model is not measured here: `shiptrial diagnose` checks them against it")
        return Reidentification(theta, names, nrmse, disagree, notes)
    for r in runs:
        sim = _simulate_predictor(profile, r.inputs, theta, r.y[0]).nu[0]
        spread = np.maximum(np.sqrt(np.mean(r.y**2, axis=0)), 1e-9)  # RMS: a steady surge speed is no zero
        per_dof = np.sqrt(np.mean(((sim - r.y) / spread) ** 2, axis=0)) if np.all(np.isfinite(sim)) else np.full(3, np.inf)
        key = f"step {r.step + 1} ({r.primitive})"
        nrmse[key] = float(np.sqrt(np.mean(per_dof**2)))
        # a DOF held at the profile's values misses by construction: judge the others
        e = float(np.sqrt(np.mean(per_dof[~held] ** 2))) if not held.all() else 0.0
        if not e <= DISAGREE_NRMSE:
            disagree.append(
                f"{r.source or key}: the re-identified model misses the recorded motion by {e:.2f} of its RMS "
                f"(> {DISAGREE_NRMSE}): the model structure may not fit this ship; run `shiptrial diagnose` on the recordings"
            )
    return Reidentification(theta, names, nrmse, disagree, notes)


def rest_information(
    profile: ShipProfile, prims: Sequence[Primitive], theta: np.ndarray
) -> tuple[list[PrimitiveInfo], list[str]]:
    """M_rest: :func:`information_at` the re-identified ``theta`` when the predictor is the
    simulation model and its simulation stays finite; else the library's information at the
    profile's values (:func:`primitives.information.library_information`, what the first design
    used), said in the notes."""
    if same_structure(profile):
        try:
            return information_at(profile, prims, theta), []
        except DesignError as exc:
            why = str(exc)
    else:
        why = "the ship's predictor is not its simulation model"
    return library_information(profile, list(prims)), [f"the rest's information is at the profile's values ({why})"]


def information_at(profile: ShipProfile, prims: Sequence[Primitive], theta: np.ndarray) -> list[PrimitiveInfo]:
    """Moments (7.50)-(7.55) of each primitive at the predictor parameters ``theta``: its inputs
    replayed through the predictor from its own first state; regressors and instruments both
    from that simulation (the IV's instruments once it has converged on the ship as it is)."""
    mask = block_mask(profile.predictor)
    out = []
    for p in prims:
        res = _simulate_predictor(profile, p.inputs, theta, np.asarray(p.nu0, float))
        nu, psi = res.nu[0], res.eta[0, :, 2]
        if not np.all(np.isfinite(nu)):
            raise DesignError(f"{p.name}: its simulation at the re-identified parameters diverges; run `shiptrial diagnose`")
        phi, _ = predictor_regressors(profile, nu, p.inputs, psi)
        out.append(information_moments(p.name, phi[None], phi, mask))
    return out


def sailed_information(
    profile: ShipProfile, runs: Sequence[SailedRun], theta: np.ndarray | None, mean_subtraction: str = "complete"
) -> PrimitiveInfo:
    """M_sailed: the moments of the recordings, instruments simulated by the predictor at
    ``theta`` (None: the design's instrument set, :func:`primitives.information.design_instrument_set`,
    as M_rest at the profile's values), each run its own sub-experiment as the primitives of the rest are.

    'complete' (7.57) removes one mean over the whole trial: the runs' pooled X0, Y0, Z0 enter
    its sums T, S and Z-bar. 'batchwise' (7.53) removes each run's own mean, so the prior is
    X0 = sum_r n_r (X_r - Y_r Z_r^T) / N with Y0 = Z0 = 0 (pooling would count the spread between
    the runs' means as information); 'none' (7.18) is the same sum of X_r.

    The recorded regressors carry measurement noise and M_rest's do not: the quadratic terms' X
    and Y are biased by about the noise variance, negligible at a GNSS/gyro's noise against the
    manoeuvres' velocities."""
    inst = None if theta is None else np.asarray(theta, float)[None]
    if mean_subtraction == "complete":
        return data_information(profile, [r.segment() for r in runs], inst, name="sailed")
    per_run = [data_information(profile, [r.segment()], inst, name=r.primitive) for r in runs]
    n = sum(i.n_samples for i in per_run)
    X = sum(i.n_samples * i.gamma(mean_subtraction) for i in per_run) / n
    zero = np.zeros(X.shape[0])
    return PrimitiveInfo("sailed", n, X, zero, zero.copy(), per_run[0].mask)


def redesign(
    profile: ShipProfile,
    library: Sequence[Primitive],
    runs: Sequence[SailedRun],
    time_left_s: float,
    *,
    mean_subtraction: str = "complete",
    seed: int = 0,
    reid: Reidentification | None = None,
    held: Sequence[str] = (),
) -> Redesign:
    """The D-optimal rest of the trial given the runs sailed (7.58): re-identify (unless
    ``reid``), M_sailed and M_rest at the estimate, design with M_sailed as the prior term over
    ``time_left_s`` seconds of manoeuvres, round to whole manoeuvres. ``held``: parameters held
    at the profile's values (a plan for confined water, :mod:`maps.searoom`): set to them after
    the re-identification, and the design is over the others' information (:func:`restrict`)."""
    lib = [p for p in library if p.kind == "informative"]
    shortest = min(lib, key=lambda p: p.duration_s)
    if not time_left_s >= shortest.duration_s:
        raise DesignError(
            f"--time-left {time_left_s:g} s holds no manoeuvre: the shortest, {shortest.name}, lasts "
            f"{shortest.duration_s:.0f} s; give --time-left >= {shortest.duration_s:.0f} or end the trial"
        )
    reference = profile_predictor(profile, lib)
    reid = reid if reid is not None else reidentify(profile, runs, reference)
    if held:
        hold_parameters(reid, reference, held)
    keep = np.array([n not in held for n in reid.names]) if held else None
    infos, sailed, info, info_notes = rest_problem(profile, lib, runs, reid.theta, time_left_s, mean_subtraction, keep)
    design_profile = reduced_profile(profile, list(held)) if held else profile
    d = run_design(
        design_profile,
        lib,
        criterion="D",
        mean_subtraction=mean_subtraction,
        trial_length_s=time_left_s,
        seed=seed,
        infos=infos,
        prior=sailed,
        prior_samples=sailed.n_samples,
        convex_solvers=DESIGN_SOLVERS,
    )
    ts = profile.sample_time
    w = np.array([d.weights[p.name] for p in lib])
    units = np.array([p.n_samples for p in lib])
    total = int(round(time_left_s / ts))
    rnd = round_design(w, units, total, lambda s: info.value(s / total, mean_subtraction), info.n_params)
    counts = {p.name: int(c) for p, c in zip(lib, rnd.counts) if c > 0}
    ld_sailed = info.logdet(np.zeros(len(lib)), mean_subtraction)  # the same normalisation: what the rest adds shows
    ld_total = info.logdet(rnd.counts * units / total, mean_subtraction)
    planned = float(sum(c * p.duration_s for p, c in zip(lib, rnd.counts)))
    record = {
        "criterion": "D",
        "mean_subtraction": mean_subtraction,
        "weights": {p.name: float(x) for p, x in zip(lib, w) if x > 1e-4},
        "counts": counts,
        "not_used": [p.name for p, x, c in zip(lib, w, rnd.counts) if x <= 1e-4 and c == 0],
        "d_efficiency": float(rnd.efficiency),
        "efficiency": float(rnd.efficiency),
        "dropped": [],
        "trial_length_s": float(time_left_s),
        "planned_s": planned,
        "sailed_samples": int(sailed.n_samples),
        "reidentified": reid.to_dict(),
    }
    notes = [
        f"re-designed after {len(runs)} sailed manoeuvre(s) ({sailed.n_samples * ts:.0f} s recorded), counting their "
        f"information (7.58): {', '.join(f'{k} x{v}' for k, v in counts.items())} in {time_left_s:.0f} s"
    ]
    notes += reid.notes + info_notes + [f"warning: {x}" for x in reid.disagrees]
    return Redesign(counts, record["weights"], float(time_left_s), planned, ld_sailed, ld_total, reid, record, notes, d.logdet)


def hold_parameters(reid: Reidentification, reference: np.ndarray, held: Sequence[str]) -> None:
    """Set the ``held`` parameters of ``reid`` to their ``reference`` values (the profile's), in
    place: the first plan held them because the water cannot identify them, and the recordings
    sailed in that water cannot either (their estimates would be noise). The others keep the
    joint estimate: the IV is not re-solved with the held ones on its left-hand side."""
    unknown = sorted(set(held) - set(reid.names))
    if unknown:
        raise DesignError(f"held parameter(s) {', '.join(unknown)} are not parameters of the ship's predictor")
    idx = [reid.names.index(n) for n in held]
    reid.theta[idx] = reference[idx]


def sail(
    profile: ShipProfile,
    prims: Sequence[Primitive],
    theta_true: np.ndarray,
    noise_std: Sequence[float],
    rng: np.random.Generator,
    first_step: int = 0,
) -> list[SailedRun]:
    """Simulated sailing of ``prims`` in order by a ship whose model parameters are ``theta_true``
    (the profile's model structure), each from its nominal first state, with white measurement
    noise of ``noise_std`` (u, v, r) on the velocities: the recordings a benchmark resumes from."""
    std = np.asarray(noise_std, float)
    runs = []
    for i, p in enumerate(prims):
        with np.errstate(all="ignore"):
            res = simulate(profile, p.inputs, np.asarray(theta_true, float), nu0=np.asarray(p.nu0, float))
        y = res.nu[0] + rng.standard_normal(res.nu[0].shape) * std
        runs.append(SailedRun(first_step + i, p.name, p.inputs, y, res.eta[0, :, 2], f"simulated {p.name}"))
    return runs
