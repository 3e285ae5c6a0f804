"""The exported model (``model.json``): exactly the model that was scored, and its reader.

The file is a ship profile (loadable by ``primitives.ship.load_profile``: the baseline as
refitted, extra terms appended, a current as the mean current) plus a ``diagnosed_model``
section that holds what the profile format cannot express (delay, offsets, biases, an inertia
scale) and the exact parameter vector. :func:`load_model` rebuilds the scored model from it;
simulating the validation runs with it reproduces the reported fit.
"""

from __future__ import annotations

import json
from dataclasses import asdict, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from diagnose import windload
from diagnose.candidates import Candidate, Slot
from diagnose.model import AugmentedModel
from diagnose.recording import RecordingError
from primitives.io import to_jsonable
from primitives.profile_document import MODEL_JSON_FIX, check_diagnosed_sections, profile_from_dict
from primitives.ship import BASE_SIGNALS, DOFS, ShipProfile
from primitives.simulate import WIND_EXCESS
from primitives.terms import TermError, compile_term
from primitives.validate import check_table_keys, finite, positive

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
    base["vessel"] = prof.vessel or prof.name  # still a model of that ship: its recordings' '# ship:' header names it
    base["augmentations"] = [{"effect": f["effect"], "dof": f["dof"], "parameters": f["parameters"]} for f in kept]
    base["diagnosed_model"] = {
        "format": FORMAT,
        "note": "exact scored model: baseline profile + candidate slots; read with diagnose.model_file.load_model",
        "baseline_profile": prof.to_dict()
        | {
            "parameters": {"scored": {dof: theta[prof.model.dof_slice(i)].tolist() for i, dof in enumerate(DOFS)}},
            "simulation_set": "scored",
            "instrument_set": "scored",
        },
        "half_sample_s": m.half_sample,
        "candidates": [
            {
                "effect": c.effect,
                "key": c.key,
                "dof": c.dof,
                "description": c.description,
                "slots": [asdict(s) for s in c.slots],
                "values": d.P[m.slot_of[c.key]].tolist(),
            }
            for c in chosen
        ],
    }
    return to_jsonable(base)


def load_model(path: str | Path) -> tuple[AugmentedModel, np.ndarray]:
    """The scored model of a ``model.json``: (model, parameter vector) for
    :meth:`AugmentedModel.simulate` (the primitives' time step with the findings around it; runs
    prepared with ``diagnose.model.prepare``). A malformed file is refused in one line naming the
    file, the field and the fix (:class:`RecordingError`, or ProfileError for its baseline profile)."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise RecordingError(
            f"{p}: not a readable model.json ({type(exc).__name__}: {exc}): give the model.json "
            "`shiptrial diagnose --out DIR` wrote"
        ) from None
    if not isinstance(data, dict) or "diagnosed_model" not in data:
        raise RecordingError(
            f"{p}: not a diagnosed model.json (no field 'diagnosed_model'): give the model.json "
            "`shiptrial diagnose --out DIR` wrote"
        )
    check_diagnosed_sections(data, str(p), RecordingError)
    doc = data["diagnosed_model"]
    if doc.get("format") != FORMAT:
        raise RecordingError(
            f"{p}: field 'diagnosed_model.format' must be {FORMAT!r}, got {doc.get('format')!r}: {MODEL_JSON_FIX}"
        )
    if not isinstance(doc.get("baseline_profile"), dict):
        raise RecordingError(
            f"{p}: field 'diagnosed_model.baseline_profile' must be the scored ship profile (a table): {MODEL_JSON_FIX}"
        )
    prof = profile_from_dict(doc["baseline_profile"], f"{p} [diagnosed_model.baseline_profile]")
    if not prof.planar:
        raise RecordingError(
            f"{p}: field 'diagnosed_model.baseline_profile' is a {prof.n_dof}-DOF {prof.actuator} profile, and a "
            f"diagnosis is of a 3-DOF ship: {MODEL_JSON_FIX}"
        )
    half = positive(
        doc.get("half_sample_s", 0.0), f"{p}: field 'diagnosed_model.half_sample_s'", "s", RecordingError, allow_zero=True
    )
    cands, values = _candidates(doc.get("candidates"), prof, p)
    model = AugmentedModel(prof, prof.params(), cands)
    model.half_sample = half
    P = model.p0()
    for c, v in zip(cands, values):
        P[model.slot_of[c.key]] = v
    return model, P


CANDIDATE_KEYS = ("effect", "key", "dof", "description", "slots", "values")
SLOT_KEYS = tuple(f.name for f in fields(Slot))
# What a slot of each kind reads besides its name: its DOF, its term, an index below a bound
# (the current's or steady wind's north/east, the input offset, the biased signal u/v/r).
SLOT_NEEDS: dict[str, tuple[str, ...]] = {
    "term": ("dof", "term"),
    "scale": ("dof",),
    "current": ("index",),
    "steady_wind": ("index",),
    "offset": ("index",),
    "bias": ("index",),
    "delay": (),
    "thrust": (),
    "thrust_share": (),
}


def _candidates(raw: object, prof: ShipProfile, p: Path) -> tuple[list[Candidate], list[list[float]]]:
    """The ``diagnosed_model.candidates`` list, checked: the candidates and each one's slot values."""
    if not isinstance(raw, list) or not all(isinstance(c, dict) for c in raw):
        raise RecordingError(
            f"{p}: field 'diagnosed_model.candidates' must be a list of tables with {', '.join(CANDIDATE_KEYS)}: {MODEL_JSON_FIX}"
        )
    cands, values = [], []
    for i, c in enumerate(raw):
        at = f"{p}: field 'diagnosed_model.candidates.{i}"
        check_table_keys(c, CANDIDATE_KEYS, str(p), f"diagnosed_model.candidates number {i + 1}", RecordingError)
        for k in ("effect", "key"):
            if not isinstance(c.get(k), str) or not c[k]:
                raise RecordingError(f"{at}.{k}' must be a non-empty string, got {c.get(k)!r}: {MODEL_JSON_FIX}")
        if any(c["key"] == other.key for other in cands):
            raise RecordingError(f"{at}.key' {c['key']!r} is given twice: every candidate once ({MODEL_JSON_FIX})")
        if not isinstance(c.get("description", ""), str):
            raise RecordingError(f"{at}.description' must be a string, got {c['description']!r}: {MODEL_JSON_FIX}")
        slots = c.get("slots")
        if not isinstance(slots, list) or not slots or not all(isinstance(s, dict) for s in slots):
            raise RecordingError(f"{at}.slots' must be a non-empty list of tables with {', '.join(SLOT_KEYS)}: {MODEL_JSON_FIX}")
        vals = c.get("values")
        if not isinstance(vals, list) or len(vals) != len(slots):
            raise RecordingError(
                f"{at}.values' must be a list of {len(slots)} numbers, one per slot, got {vals!r}: {MODEL_JSON_FIX}"
            )
        values.append([finite(v, f"{at}.values.{j}'", "", RecordingError) for j, v in enumerate(vals)])
        cands.append(
            Candidate(
                c["effect"],
                c["key"],
                tuple(_slot(s, prof, p, f"diagnosed_model.candidates.{i}.slots.{j}") for j, s in enumerate(slots)),
                _index(c.get("dof"), 3, f"{at}.dof'"),
                c.get("description", ""),
            )
        )
    return cands, values


def _slot(s: dict, prof: ShipProfile, p: Path, field: str) -> Slot:
    """The slot at ``field`` of a candidate, checked against what its kind reads (:data:`SLOT_NEEDS`)."""
    check_table_keys(s, SLOT_KEYS, str(p), field, RecordingError)
    at = f"{p}: field '{field}"
    kind = s.get("kind")
    if kind not in SLOT_NEEDS:
        raise RecordingError(f"{at}.kind' must be one of {list(SLOT_NEEDS)}, got {kind!r}: {MODEL_JSON_FIX}")
    if not isinstance(s.get("name"), str):
        raise RecordingError(f"{at}.name' must be the slot's name (a string), got {s.get('name')!r}: {MODEL_JSON_FIX}")
    bound = {"current": 2, "steady_wind": 4, "offset": len(prof.inputs), "bias": 3}.get(kind, 0)
    slot = Slot(
        kind, s["name"], _index(s.get("dof"), 3, f"{at}.dof'"), s.get("term"), _index(s.get("index"), bound, f"{at}.index'")
    )
    for need in SLOT_NEEDS[kind]:
        if getattr(slot, need) is None:
            raise RecordingError(f"{at}.{need}' is needed by a {kind!r} slot: {MODEL_JSON_FIX}")
    if slot.term is not None:
        known = BASE_SIGNALS | set(prof.inputs) | set(WIND_EXCESS) | set(windload.SIGNALS) | {"phi"}
        try:
            if not isinstance(slot.term, str) or not set(compile_term(slot.term)[0]) <= known:
                raise TermError(f"it must be a term string of the signals {sorted(known)}")
        except TermError as exc:
            raise RecordingError(f"{at}.term' {slot.term!r}: {exc}: {MODEL_JSON_FIX}") from None
    return slot


def _index(value: object, bound: int, at: str) -> int | None:
    """A DOF or index field: null, or a whole number in 0..bound-1."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < bound:
        raise RecordingError(
            f"{at} must be null or a whole number 0..{bound - 1}, got {value!r}: {MODEL_JSON_FIX}"
            if bound
            else f"{at} must be null for this slot kind, got {value!r}: {MODEL_JSON_FIX}"
        )
    return value
