"""Reference (calm-water) runs and the baseline structure they let the diagnosis refit (issue 13).

A baseline made from other data (another basin, another model) misfits a ship's recordings by
more than a concealed effect moves them: whatever is screened first soaks the structural
misfit up. With ``--fit-on`` runs of the ship as it was made (no current, no wind, no fault),
the diagnosis can separate the two, following the multi-experiment form of output-error
identification (Källström 1977: one model, experiment-specific disturbance parameters):

- the baseline is *extended* by hull and rudder terms its structure may lack: the structure its
  profile declares in a [diagnosis] table (``ShipProfile.structure_terms``; e.g. kvlcc2's MMG-shaped hull,
  propeller and rudder terms, fitted on the --fit-on runs alone by ``diagnose.api.fit_structure``)
  or, for the experimental joint fit, generic ones (speed loss in turns v r, cross-flow drag
  v|v| and r|r|, rudder force growing with inflow speed delta u^2 and slipstream delta n^2 - the
  nonlinear terms of the MMG and Abkowitz models);
- the baseline is refitted jointly on the reference runs and the diagnosed runs, with every
  candidate's slots switched OFF on the reference runs: a candidate can only explain what
  differs between the runs with the condition and the runs without it, so the structural
  misfit (shared by all runs) stays with the baseline.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from diagnose.candidates import canonical_term, thrust_signal
from diagnose.model import AugmentedModel, Prepared
from primitives.ship import DOFS, ShipProfile
from primitives.terms import signals_used


def structure_terms(profile: ShipProfile) -> tuple[tuple[str, ...], ...]:
    """Hull and actuator terms a 3-DOF manoeuvring model of this ship may need (per DOF), in the
    profile's own signals: steering input s and thrust signal n."""
    s, n = profile.steering_input, thrust_signal(profile)
    surge = ("u_r*|u_r|", f"{n}^2", "v_r*r", "v_r^2", "r^2", f"{s}^2*u_r^2")
    lateral = (
        "u_r*v_r",
        "u_r*r",
        "v_r*|v_r|",
        "r*|r|",
        "v_r*|r|",
        "r*|v_r|",
        f"{s}*u_r^2",
        f"{s}*{n}^2",
        f"{s}*u_r*{n}",
        f"{s}^3*u_r^2",
    )
    return surge, lateral, lateral


def extend(profile: ShipProfile, declared: bool = False) -> tuple[ShipProfile, list[str]]:
    """The profile with the structure terms it lacks appended (coefficients 0), and their
    names ("<dof>:<term>"): the profile's declared [diagnosis] structure with ``declared``
    (nothing when it declares none), else the generic hull and actuator terms of
    :func:`structure_terms`."""
    if declared and not profile.structure_terms:
        return profile, []
    terms, names, added = [], [], []
    want_all = profile.structure_terms if declared else None
    # a generic term only where the ship has its signals (no rudder term for a generalized-force ship)
    has = {"u_r", "v_r", "r", *profile.inputs}
    for i, (have, want) in enumerate(zip(profile.model_terms, want_all or structure_terms(profile))):
        canon = {canonical_term(t) for t in have}
        extra = [t for t in want if canonical_term(t) not in canon and (want_all is not None or signals_used([[t]]) <= has)]
        terms.append(tuple(have) + tuple(extra))
        names.append(tuple(profile.parameter_names[i]) + tuple(f"S{'xyn'[i]}[{t}]" for t in extra))
        added += [f"{DOFS[i]}:{t}" for t in extra]
    if not added:
        return profile, []
    sets = {profile.simulation_set: padded_params(profile, profile.params(), terms)}
    return dataclasses.replace(
        profile,
        model_terms=tuple(terms),
        parameter_names=tuple(names),
        parameter_sets=sets,
        simulation_set=profile.simulation_set,
        instrument_set=profile.simulation_set,
        predictor_terms=None,
        predictor_names=None,
        structure_terms=None,
        prior_std=None,  # the spread is of the profile's own terms; the extended model's has more
    ), added


def padded_params(profile: ShipProfile, theta: np.ndarray, terms: tuple[tuple[str, ...], ...]) -> np.ndarray:
    """``theta`` of ``profile`` with zeros for the terms ``terms`` (the extended model's, see
    :func:`extend`) appends to each DOF."""
    return np.concatenate(
        [
            np.concatenate([theta[profile.model.dof_slice(i)], np.zeros(len(terms[i]) - len(have))])
            for i, have in enumerate(profile.model_terms)
        ]
    )


class ReferencedModel(AugmentedModel):
    """The augmented model whose candidate slots act on every run except the reference runs."""

    def __init__(
        self, profile: ShipProfile, theta0: np.ndarray, candidates: list, n_rec: int = 0, reference: list[Prepared] | None = None
    ):
        super().__init__(profile, theta0, candidates, n_rec)
        self.reference_ids = {id(p) for p in reference or []}

    def simulate_many(self, preps: list[Prepared], P: np.ndarray | list[np.ndarray]) -> list[np.ndarray]:
        if not any(id(p) in self.reference_ids for p in preps):
            return super().simulate_many(preps, P)
        Ps = [np.atleast_2d(np.asarray(q, float)) for q in (P if isinstance(P, list) else [P] * len(preps))]
        for k, p in enumerate(preps):
            if id(p) in self.reference_ids:
                Ps[k] = Ps[k].copy()
                Ps[k][:, self.n_base : self.n_slots_end] = 0.0  # the reference runs are without the condition
        return super().simulate_many(preps, Ps)
