"""The exported model (``model.json``): exactly the model that was scored, and its reader.

The file is a ship profile (loadable by ``primitives.ship.load_profile``: the baseline as
refitted, extra terms appended, a current as the mean current) plus a ``diagnosed_model``
section that holds what the profile format cannot express (delay, offsets, biases, an inertia
scale) and the exact parameter vector. :func:`load_model` rebuilds the scored model from it;
simulating the validation runs with it reproduces the reported fit.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from diagnose.candidates import Candidate, Slot
from diagnose.model import AugmentedModel
from diagnose.recording import RecordingError
from primitives.io import to_jsonable
from primitives.profile_document import profile_from_dict
from primitives.ship import DOFS

if TYPE_CHECKING:
    from diagnose.api import Diagnosis

FORMAT = "shiptrial-diagnosed-model/1"


def model_dict(d: Diagnosis) -> dict:
    """The profile part (approximate for effects a profile cannot hold) and the exact model."""
    prof, m = d.profile, d.model
    base = prof.to_dict()
    theta = d.P[: m.n_base]
    terms = [list(t) for t in prof.model_terms]
    names = [list(n) for n in prof.parameter_names]
    vals = [list(theta[prof.model.dof_slice(i)]) for i in range(3)]
    dist = dict(base.get("disturbances", {}))
    known = {"u", "v", "r", "u_r", "v_r", "psi", *prof.inputs, "tau_x", "tau_y", "tau_n"}
    kept = d.findings + d.structure
    chosen = [next(c for c in m.candidates if c.key == f["key"]) for f in kept]
    for c in chosen:
        idx = m.slot_of[c.key]
        if c.slots[0].kind == "thrust":  # every thrust term scaled by 1 - loss fraction
            for k in m.thrust_terms:
                i, t = m.base[k][:2]
                vals[i][terms[i].index(t)] *= 1.0 - float(d.P[idx[0]])
            share = float(m.thrust_share(d.P, idx[0])[0])
            for k in m.rudder_terms:  # the rudder loses its slipstream share of it
                i, t = m.base[k][:2]
                vals[i][terms[i].index(t)] *= 1.0 - share * float(d.P[idx[0]])
        elif c.effect in ("quadratic_damping", "missing_coupling", "thrust_loss", "resistance_change"):
            term = c.slots[0].term
            if term in terms[c.dof]:
                k = terms[c.dof].index(term)
                vals[c.dof][k] += float(d.P[idx[0]])
            elif {x.strip("|").split("^")[0] for x in term.split("*")} <= known:
                terms[c.dof].append(term)
                names[c.dof].append(f"{c.effect}:{term}")
                vals[c.dof].append(float(d.P[idx[0]]))
        elif c.effect == "current":
            dist["current_mean_ne"] = [float(d.P[idx[0]]), float(d.P[idx[1]])]
    base["model"] = dict(zip(DOFS, terms))
    base["parameter_names"] = dict(zip(DOFS, names))
    base["parameters"] = {"diagnosed": dict(zip(DOFS, vals))}
    base["simulation_set"] = base["instrument_set"] = "diagnosed"
    base["disturbances"] = dist
    base.pop("predictor", None)
    base.pop("predictor_names", None)
    base["name"] = f"{prof.name}-diagnosed"
    base["augmentations"] = [{"effect": f["effect"], "dof": f["dof"], "parameters": f["parameters"]} for f in kept]
    base["diagnosed_model"] = {
        "format": FORMAT,
        "note": "exact scored model: baseline profile + candidate slots; read with diagnose.model_file.load_model",
        "baseline_profile": prof.to_dict() | {"parameters": {"scored": {dof: theta[prof.model.dof_slice(i)].tolist()
                                                                      for i, dof in enumerate(DOFS)}},
                                              "simulation_set": "scored", "instrument_set": "scored"},
        "half_sample_s": m.half_sample,
        "candidates": [{"effect": c.effect, "key": c.key, "dof": c.dof, "description": c.description,
                        "slots": [asdict(s) for s in c.slots], "values": d.P[m.slot_of[c.key]].tolist()} for c in chosen],
    }
    return to_jsonable(base)


def load_model(path: str | Path) -> tuple[AugmentedModel, np.ndarray]:
    """The scored model of a ``model.json``: (model, parameter vector) for
    :meth:`AugmentedModel.simulate` (the primitives' time step with the findings around it; runs
    prepared with ``diagnose.model.prepare``)."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))["diagnosed_model"]
    except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
        raise RecordingError(f"{p}: not a diagnosed model.json (field 'diagnosed_model'): {exc}") from None
    if doc.get("format") != FORMAT:
        raise RecordingError(f"{p}: field 'diagnosed_model.format' must be {FORMAT!r}")
    prof = profile_from_dict(doc["baseline_profile"], str(p))
    cands = [Candidate(c["effect"], c["key"], tuple(Slot(**s) for s in c["slots"]), c["dof"], c.get("description", ""))
             for c in doc["candidates"]]
    model = AugmentedModel(prof, prof.params(), cands)
    model.half_sample = float(doc.get("half_sample_s", 0.0))
    P = model.p0()
    for c, raw in zip(cands, doc["candidates"]):
        P[model.slot_of[c.key]] = raw["values"]
    return model, P
