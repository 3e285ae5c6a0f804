"""A diagnosed model.json read back (diagnose.model_file.load_model, and as a profile by
load_profile): a malformed augmentations list or diagnosed_model section is refused in one line
naming the file, the field and the fix, never a traceback (before: KeyError, TypeError or
ValueError from deep inside, or silently read)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from diagnose.model_file import FORMAT, load_model
from primitives.errors import UserError
from primitives.ship import load_profile


def _doc() -> dict:
    """A model.json as `shiptrial diagnose --out` writes it: the model-ship with a delay, a
    current and an extra yaw damping term."""
    ms = load_profile("model-ship")
    base = ms.to_dict() | {
        "parameters": {"scored": ms.to_dict()["parameters"]["true"]},
        "simulation_set": "scored",
        "instrument_set": "scored",
    }
    cands = [
        {
            "effect": "actuator_delay",
            "key": "actuator_delay",
            "dof": None,
            "description": "time delay of all actuators",
            "slots": [{"kind": "delay", "name": "delay_s", "dof": None, "term": None, "index": None}],
            "values": [0.5],
        },
        {
            "effect": "current",
            "key": "current",
            "dof": None,
            "description": "constant current",
            "slots": [
                {"kind": "current", "name": "current_n", "dof": None, "term": None, "index": 0},
                {"kind": "current", "name": "current_e", "dof": None, "term": None, "index": 1},
            ],
            "values": [0.03, -0.04],
        },
        {
            "effect": "quadratic_damping",
            "key": "quadratic_damping:yaw:r*|r|",
            "dof": 2,
            "description": "r*|r| in yaw",
            "slots": [{"kind": "term", "name": "value", "dof": 2, "term": "r*|r|", "index": None}],
            "values": [-0.02],
        },
    ]
    aug = [
        {"effect": "actuator_delay", "dof": "yaw", "parameters": {"delay_s": 0.5}},
        {"effect": "current", "dof": "sway", "parameters": {"speed_mps": 0.05, "term": None}},
    ]
    profile_part = ms.to_dict()
    profile_part["disturbances"] = dict(profile_part.get("disturbances", {}), current_mean_ne=[0.03, -0.04])  # the found current
    return profile_part | {
        "name": "model-ship-diagnosed",
        "augmentations": aug,
        "diagnosed_model": {
            "format": FORMAT,
            "note": "exact scored model",
            "baseline_profile": base,
            "half_sample_s": 0.0625,
            "candidates": cands,
        },
    }


def test_a_well_formed_model_json_loads_as_the_scored_model(tmp_path):
    path = tmp_path / "model.json"
    path.write_text(json.dumps(_doc()))
    model, P = load_model(path)
    assert model.half_sample == 0.0625
    assert P[model.slot_of["current"]].tolist() == [0.03, -0.04] and P[model.slot_of["actuator_delay"]].tolist() == [0.5]
    np.testing.assert_array_equal(P[: model.n_base], load_profile("model-ship").params("true"))
    assert load_profile(path).name == "model-ship-diagnosed"  # and it is a profile


def _set(doc: dict, where: str, value) -> dict:
    """``doc`` with the field at the dotted path ``where`` set to ``value`` (``...`` deletes it)."""
    doc = copy.deepcopy(doc)
    *head, last = where.split(".")
    node = doc
    for k in head:
        node = node[int(k)] if isinstance(node, list) else node[k]
    if value is ...:
        del node[last]
    elif isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return doc


C = "diagnosed_model.candidates"
# (field set, value, what the one line must say); checked by load_model, the first four also by load_profile
BAD = [
    ("augmentations", "current", "field 'augmentations' must be a list of tables"),
    ("augmentations.0.dof", "heave", "field 'augmentations.0.dof' must be one of"),
    ("augmentations.1.effekt", "current", "unknown key 'effekt' in [[augmentations]] number 2"),
    ("diagnosed_model.formats", FORMAT, "unknown key 'formats' in [diagnosed_model]"),
    ("diagnosed_model.format", "shiptrial-diagnosed-model/0", "field 'diagnosed_model.format' must be"),
    ("diagnosed_model.baseline_profile", ..., "field 'diagnosed_model.baseline_profile' must be the scored ship profile"),
    ("diagnosed_model.baseline_profile.sample_time", -1.0, "[diagnosed_model.baseline_profile]: field 'sample_time'"),
    ("diagnosed_model.half_sample_s", "half", "field 'diagnosed_model.half_sample_s'"),
    (C, {"delay": 0.5}, f"field '{C}' must be a list of tables"),
    (f"{C}.0.values", [0.5, 0.1], f"field '{C}.0.values' must be a list of 1 numbers"),
    (f"{C}.1.values.0", "north", f"field '{C}.1.values.0'"),
    (f"{C}.1.values.1", float("nan"), f"field '{C}.1.values.1'"),
    (f"{C}.0.slots.0.kind", "warp", f"field '{C}.0.slots.0.kind' must be one of"),
    (f"{C}.1.slots.1.index", 2, f"field '{C}.1.slots.1.index' must be null or a whole number 0..1"),
    (f"{C}.2.slots.0.term", "w_r*u", f"field '{C}.2.slots.0.term' 'w_r*u'"),
    (f"{C}.2.slots.0.term", "v_r^-2", f"field '{C}.2.slots.0.term' 'v_r^-2'"),
    (f"{C}.2.slots.0.dof", None, f"field '{C}.2.slots.0.dof' is needed by a 'term' slot"),
    (f"{C}.2.slots.0.dof", 3, f"field '{C}.2.slots.0.dof' must be null or a whole number 0..2"),
    (f"{C}.2.key", "current", f"field '{C}.2.key' 'current' is given twice"),
    (f"{C}.2.slots", [], f"field '{C}.2.slots' must be a non-empty list"),
    (f"{C}.0.valuez", [0.5], f"unknown key 'valuez' in {C} number 1"),
    (f"{C}.0.slots.0.offset", 0.1, f"unknown key 'offset' in {C}.0.slots.0"),
]


@pytest.mark.parametrize("where,value,says", BAD, ids=[f"{w}={v!r}"[:60] for w, v, _ in BAD])
def test_malformed_model_json_is_refused_in_one_line(where, value, says, tmp_path):
    path = tmp_path / "model.json"
    path.write_text(json.dumps(_set(_doc(), where, value)))
    with pytest.raises(UserError) as err:
        load_model(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}") and says in msg and "\n" not in msg, msg
    assert any(fix in msg for fix in ("shiptrial diagnose --out", "accepted keys", "must be", "expected a number")), msg


@pytest.mark.parametrize("where,value,says", BAD[:4], ids=[w for w, _, _ in BAD[:4]])
def test_malformed_sections_refused_when_the_model_json_is_a_ship(where, value, says, tmp_path, capsys):
    """`--ship model.json` reads the profile part: a malformed section is refused, not ignored."""
    from cli.app import _run

    path = tmp_path / "model.json"
    path.write_text(json.dumps(_set(_doc(), where, value)))
    assert _run(["primitives", "--ship", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {path}: ") and says in err[0]


@pytest.mark.parametrize(
    "text,says",
    [("{", "not a readable model.json"), ("[]", "no field 'diagnosed_model'"), ('{"name": "x"}', "no field 'diagnosed_model'")],
)
def test_not_a_model_json(text, says, tmp_path):
    path = tmp_path / "model.json"
    path.write_text(text)
    with pytest.raises(UserError, match=says):
        load_model(path)
