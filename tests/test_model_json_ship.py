"""A diagnosed model.json given as a ship (``--ship model.json``): its current turns with the
ship wherever the profile's current is simulated (the design's disturbed information, the Monte
Carlo truth), as the diagnosis scored it; and what would make it another model than the one
scored is refused in one line naming the file, the field and the fix."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from diagnose.model_file import FORMAT
from primitives.library import build_library
from primitives.profile_document import DIAGNOSED_FORMAT
from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate
from tests.test_model_file import _doc, _set

CURRENT = [0.03, -0.04]


def _model_json(tmp_path, doc: dict | None = None):
    doc = _doc() if doc is None else doc
    doc["disturbances"] = dict(doc.get("disturbances", {}), current_mean_ne=CURRENT)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(doc))
    return path


def test_the_format_is_the_diagnosis_format():
    assert DIAGNOSED_FORMAT == FORMAT


def test_a_diagnosed_current_turns_with_the_ship(tmp_path):
    """The model.json's current is fixed in the earth frame: simulated from the profile's own
    disturbances, the velocity over ground follows it as the ship turns (current_turning), which a
    turning run shows; the thesis profiles keep the thesis's form."""
    prof = load_profile(_model_json(tmp_path))
    dist = Disturbances.from_profile(prof)
    assert dist.current_turning and dist.current_ne == tuple(CURRENT)
    assert not Disturbances.from_profile(load_profile("full-scale")).current_turning
    assert not Disturbances.from_profile(load_profile("model-ship")).current_turning
    prim = next(p for p in build_library(prof) if np.ptp(p.track[:, 2]) > np.pi)  # a primitive that turns round
    off = dataclasses.replace(dist, current_turning=False)
    turned = simulate(prof, prim.inputs, nu0=prim.nu0, disturbances=dist, seed=1)
    explicit = simulate(prof, prim.inputs, nu0=prim.nu0, disturbances=off, current_turning=True, seed=1)
    flat = simulate(prof, prim.inputs, nu0=prim.nu0, disturbances=off, seed=1)
    np.testing.assert_array_equal(turned.nu, explicit.nu)
    assert np.max(np.abs(turned.nu - flat.nu)) > 0.01  # the turn of the current matters on this run


def test_the_design_information_turns_the_current(tmp_path):
    """The design's disturbed information matrices (run_design(disturbed_realisations=...)) come
    from simulations in which the model.json's current turns with the ship."""
    from primitives.information import primitive_information
    from primitives.regressors import predictor_regressors

    prof = load_profile(_model_json(tmp_path))
    prim = next(p for p in build_library(prof) if np.ptp(p.track[:, 2]) > np.pi)
    dist = Disturbances.from_profile(prof)
    info = primitive_information(prof, prim, disturbances=dist, realisations=3, seed=5)

    def mean_regressors(d: Disturbances) -> np.ndarray:
        res = simulate(prof, prim.inputs, nu0=prim.nu0, disturbances=d, batch=3, seed=5)
        phi, _ = predictor_regressors(prof, res.y, np.broadcast_to(prim.inputs, (3,) + prim.inputs.shape), res.psi_meas)
        return phi.mean(axis=(0, 1))

    np.testing.assert_array_equal(info.Y, mean_regressors(dist))
    assert not np.allclose(info.Y, mean_regressors(dataclasses.replace(dist, current_turning=False)), rtol=1e-6, atol=0)


def test_current_turning_may_be_switched_off_and_must_be_a_bool(tmp_path):
    doc = _doc()
    doc["disturbances"] = {"current_turning": False}
    assert not Disturbances.from_profile(load_profile(_model_json(tmp_path, doc))).current_turning
    doc["disturbances"] = {"current_turning": "yes"}
    with pytest.raises(Exception, match=r"field 'disturbances.current_turning' must be true or false"):
        load_profile(_model_json(tmp_path, doc))


D = "diagnosed_model"
BAD = [
    (f"{D}.format", "shiptrial-diagnosed-model/9", f"field '{D}.format' must be 'shiptrial-diagnosed-model/1'"),
    (f"{D}.baseline_profile", "x", f"field '{D}.baseline_profile' must be the scored ship profile"),
    (f"{D}.baseline_profile.actuator", "azimuth", f"field '{D}.baseline_profile.actuator' is 'azimuth'"),
    (f"{D}.baseline_profile.sample_time", 1.0, f"field '{D}.baseline_profile.sample_time' is 1.0"),
    (f"{D}.half_sample_s", -1, f"field '{D}.half_sample_s' must be a number of seconds"),
    (f"{D}.candidates", "x", f"field '{D}.candidates' must be a list of tables"),
    ("disturbances.current_mean_ne", ..., "field 'disturbances.current_mean_ne' is missing, and the findings"),
    ("disturbances.current_mean_ne", [5.0, 0.0], "field 'disturbances.current_mean_ne' is a current of 5 m/s"),
]


@pytest.mark.parametrize("where,value,says", BAD, ids=[f"{w}={v!r}"[:50] for w, v, _ in BAD])
def test_a_model_json_that_is_not_the_scored_model_is_refused_as_a_ship(where, value, says, tmp_path, capsys):
    from cli.app import _run

    doc = _doc()
    doc["disturbances"] = dict(doc.get("disturbances", {}), current_mean_ne=CURRENT)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(_set(doc, where, value)))
    assert _run(["primitives", "--ship", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {path}: ") and says in err[0], err
    assert "shiptrial diagnose --out" in err[0] or "slower than the ship" in err[0]


def test_the_monte_carlo_truth_turns_the_current(tmp_path):
    """The Monte Carlo's true system sails in the profile's current as the profile says: a
    model.json's current turns with the ship (the same numbers as the kernel with
    current_turning), and switching it off gives the thesis's flat current."""
    from expdesign.montecarlo import MCConfig, prepare, run_segments, simulate_data

    prof = load_profile(_model_json(tmp_path))
    cur = tuple(CURRENT)
    for turning in (True, False):
        dist = Disturbances(current_ne=cur, current_turning=turning)
        sh = prepare(prof, {"one": {"tau9": 1.0}}, MCConfig(runs=1, n_samples=300, protocol="piecewise"), disturbances=dist)
        segs, _ = run_segments(sh, [("tau9", 300)])
        (seg,) = simulate_data(sh, [segs], [np.random.default_rng(1)])
        want = simulate(
            prof,
            seg.inputs[0],
            prof.params(prof.simulation_set),
            nu0=seg.nu0[0],
            disturbances=Disturbances(current_ne=cur),
            current_turning=True,
        )
        same = np.allclose(seg.y[0], want.nu[0], rtol=0, atol=1e-12)
        assert same is turning


def test_findings_the_profile_cannot_hold_are_named_in_one_warning(tmp_path):
    """A model.json's profile part holds the current and a finding's term once it is among the
    model terms; an actuator delay, a sensor bias and a term the profile part lacks are named, with
    their values, in one warning line naming the file (before: silently dropped)."""
    doc = _doc()
    doc["diagnosed_model"]["candidates"].append(
        {
            "effect": "sensor_bias",
            "key": "sensor_bias:r",
            "dof": 2,
            "description": "bias of r",
            "slots": [{"kind": "bias", "name": "bias_r", "dof": 2, "term": None, "index": 2}],
            "values": [0.0012],
        }
    )
    path = _model_json(tmp_path, doc)
    prof = load_profile(path)
    (w,) = prof.load_warnings
    assert "\n" not in w and w.startswith(f"{path}: ")
    assert "actuator_delay (delay_s 0.5)" in w and "quadratic_damping:yaw:r*|r| (value -0.02)" in w
    assert "sensor_bias:r (bias_r 0.0012) [a measurement error]" in w and "current" not in w.split("cannot hold")[1]
    # the term added to the profile part's yaw terms (as diagnose.model_file.model_dict does): held, not named
    doc["model"]["yaw"] = [*doc["model"]["yaw"], "r*|r|"]
    doc["parameter_names"]["yaw"] = [*doc["parameter_names"]["yaw"], "quadratic_damping:r*|r|"]
    for vals in doc["parameters"].values():
        vals["yaw"] = [*vals["yaw"], -0.02]
    (w,) = load_profile(_model_json(tmp_path, doc)).load_warnings
    assert "actuator_delay" in w and "quadratic_damping" not in w
    # nothing left out: no warning; a plain profile has none
    doc["diagnosed_model"]["candidates"] = [
        c for c in doc["diagnosed_model"]["candidates"] if c["effect"] in ("current", "quadratic_damping")
    ]
    assert load_profile(_model_json(tmp_path, doc)).load_warnings == ()
    assert load_profile("model-ship").load_warnings == ()


def test_commands_given_such_a_ship_warn(tmp_path, capsys):
    """`shiptrial primitives` says it on stderr; the design carries it in its warnings (stderr
    and the JSON)."""
    from cli.app import _run

    path = _model_json(tmp_path)
    assert _run(["primitives", "--ship", str(path), "--json"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"warning: {path}: ") and "actuator_delay (delay_s 0.5)" in err[0]
    from expdesign.api import default_library, run_design

    prof = load_profile(path)
    d = run_design(prof, default_library(prof), trial_length_s=600.0)
    assert d.warnings[0] == prof.load_warnings[0]


def test_a_plan_with_such_a_ship_carries_the_warning(tmp_path):
    """The plan's warnings (plan.json, printed by plan-trial) start with it."""
    from maps.planner import plan_trial

    fs = load_profile("full-scale")
    doc = fs.to_dict() | {
        "name": "full-scale-diagnosed",
        "diagnosed_model": {
            "format": FORMAT,
            "note": "exact scored model",
            "half_sample_s": 0.0,
            "baseline_profile": fs.to_dict()
            | {
                "parameters": {"scored": fs.to_dict()["parameters"]["true"]},
                "simulation_set": "scored",
                "instrument_set": "scored",
            },
            "candidates": [
                {
                    "effect": "inertia_change",
                    "key": "inertia_change:yaw",
                    "dof": 2,
                    "description": "yaw inertia",
                    "slots": [{"kind": "scale", "name": "scale", "dof": 2, "term": None, "index": None}],
                    "values": [1.3],
                }
            ],
        },
    }
    path = tmp_path / "model.json"
    path.write_text(json.dumps(doc))
    plan = plan_trial(profile=load_profile(path), scenario="thesis-9.4", headings=4, run_in_s=0)
    assert plan.stats["warnings"][0].startswith(f"{path}: ") and "inertia_change:yaw (scale 1.3)" in plan.stats["warnings"][0]


def test_what_model_dict_writes_is_judged_as_it_writes_it():
    """On the model.json `shiptrial diagnose` writes (diagnose.model_file.model_dict): a thrust
    loss, a quadratic damping and a coupling term go into the profile part and are not named; a delay, an
    input offset, a sensor bias and an inertia change are, each once."""
    from types import SimpleNamespace

    from diagnose.candidates import build_library
    from diagnose.model import AugmentedModel
    from diagnose.model_file import model_dict
    from primitives.profile_document import profile_from_dict
    from tests.test_diagnose_candidate_physics import _kvlcc2_run

    ship = load_profile("kvlcc2")
    lib, _ = build_library(ship, [_kvlcc2_run(1), _kvlcc2_run(2)])
    held = ["thrust_loss:fraction", "quadratic_damping:sway:v_r*|v_r|", "missing_coupling:surge:r^2"]
    dropped = [
        next(c.key for c in lib if c.effect == e) for e in ("actuator_delay", "input_offset", "sensor_bias", "inertia_change")
    ]
    cands = [c for c in lib if c.key in held + dropped]
    model = AugmentedModel(ship, ship.params(), cands)
    P = model.p0()
    for c in cands:
        P[model.slot_of[c.key]] = 0.01
    findings = [{"effect": c.effect, "dof": None, "key": c.key, "parameters": {}} for c in cands]
    doc = model_dict(SimpleNamespace(profile=ship, model=model, P=P, findings=findings, structure=[]))
    (w,) = profile_from_dict(doc, "model.json").load_warnings
    assert len(cands) == 7 and all(k not in w for k in held)
    assert all(w.count(f"{k} (") == 1 for k in dropped), w
