"""Manoeuvres sized to the sea room (issue 28): shorter forms of a rudder ship's manoeuvres, offered
only when the long ones fit nowhere; what fits designed with the parameters it cannot identify held
at the profile's values; a profile's engine declaring astern power."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from cli.app import _run
from maps.export.card import design_rows
from maps.plan import Plan
from maps.planner import plan_with_design
from maps.testmaps import bay
from maps.trialdesign import design_for_map, first_design
from primitives import helm as hm
from primitives.library import by_name, thesis_primitives
from primitives.orders import inputs_from_orders
from primitives.profile_document import profile_from_dict
from primitives.ship import PROFILE_DIR, ProfileError
from primitives.simulate import simulate
from primitives.sized import short_form_table, short_forms


@pytest.fixture(scope="module")
def kvlcc2_lib(kvlcc2):
    return thesis_primitives(kvlcc2)


def _kvlcc2_doc() -> dict:
    return tomllib.loads((PROFILE_DIR / "kvlcc2.toml").read_text())


def _astern_doc(astern_rpm=60.0, thrust="n*|n|", n_lo=-1.5) -> dict:
    """kvlcc2 with its thrust written n|n| (the same ahead, reversing astern) and astern power
    declared: a test profile, not a claim about the KVLCC2's engine."""
    doc = _kvlcc2_doc()
    doc["name"] = "kvlcc2-astern"
    doc["model"]["surge"] = ["u_r*|u_r|", thrust, "v_r*r"]
    doc["input_limits"]["n"] = [n_lo, 2.0]
    doc["engine"]["astern_rpm"] = astern_rpm
    return doc


def _executes(prim) -> int:
    """Rudder orders to a side before the ship is told to regain speed."""
    out = 0
    for o in prim.orders:
        if "regain" in o.text or "Midships" in o.text:
            break
        out += o.text.startswith(("Starboard", "Port"))
    return out


def test_short_zigzags_have_their_executes_are_shorter_and_their_orders_rebuild_their_inputs(kvlcc2, kvlcc2_lib):
    long = by_name(kvlcc2_lib, ["zigzag_10_10_s"])[0]
    short = {p.name: p for p in short_forms(kvlcc2, ["zigzag_10_10_s"])}
    assert set(short) == {"zigzag_10_10_s_e4", "zigzag_10_10_s_e3", "zigzag_10_10_s_e2"}
    assert _executes(long) == 5
    for e in (4, 3, 2):
        p = short[f"zigzag_10_10_s_e{e}"]
        assert _executes(p) == e
        b, bl = p.footprint.bounds, long.footprint.bounds
        assert b[2] - b[0] < bl[2] - bl[0]  # shorter along
        rebuilt = inputs_from_orders(kvlcc2, p.orders, p.n_samples)
        assert np.allclose(rebuilt, p.inputs, atol=1e-9)
        # speed regained full ahead: the manoeuvre ends within 1 % of the approach speed
        assert p.nu[-1, 0] >= 0.985 * kvlcc2.cruise_speed_mps


def test_large_water_keeps_the_first_design_and_offers_no_short_form(kvlcc2, kvlcc2_lib):
    lib = by_name(kvlcc2_lib, ["zigzag_10_10_s", "zigzag_10_10_p", "stopping", "turning_circle_35_s"])
    first = first_design(kvlcc2, lib)
    seen = []

    def fits_everywhere(ps, cs):
        seen.append([p.name for p in ps])
        return {}

    td = design_for_map(kvlcc2, fits_everywhere, lib, first=first)
    assert td is first.design and len(seen) == 1 and "held_parameters" not in td.record


def _bay(tmp_path: Path) -> Path:
    """8 km (north) x 6 km (east) of navigable water as a GeoJSON fixture (maps.testmaps.bay)."""
    path = tmp_path / "bay-8x6.geojson"
    path.write_text(json.dumps(bay()))
    return path


@pytest.fixture(scope="module")
def bay_plan(tmp_path_factory, kvlcc2, kvlcc2_lib):
    """kvlcc2's plan in the bay from a library of a turning circle and a stop, and 8 lattice
    headings (the default 16 give the same plan, counts, drops and held parameters at 10.9 s wall
    against 6.3 s under load), to keep the tests fast; the whole library at the defaults is
    measured in the README (benchmarks/bench_sea_room.py). Returns the map's path, the plan and its design."""
    path = _bay(tmp_path_factory.mktemp("bay"))
    lib = by_name(kvlcc2_lib, ["turning_circle_35_s", "stopping"])
    plan, td = plan_with_design(path, profile=kvlcc2, primitives=lib, trial_length_s=360.0, headings=8)
    return path, plan, td


def test_kvlcc2_in_an_8_by_6_km_bay_gets_a_verified_plan_with_the_held_parameters_named(tmp_path, kvlcc2, kvlcc2_lib, bay_plan):
    """Before: 'N manoeuvre(s) fit nowhere ... cannot identify the model', no plan."""
    lib = by_name(kvlcc2_lib, ["turning_circle_35_s", "stopping"])
    _, plan, td = bay_plan
    assert plan.feasible and plan.steps
    rec = td.record
    sailed = [k for k, v in rec["counts"].items() if v]
    assert sailed and all(n not in ("turning_circle_35_s", "stopping") for n in sailed)  # shortened forms only
    assert {d["primitive"] for d in rec["dropped"]} >= {"turning_circle_35_s", "stopping"}
    held = {h["parameter"]: h for h in rec["held_parameters"]}
    assert held and set(held) < set(kvlcc2.predictor_param_names)
    values = dict(zip(kvlcc2.param_names, kvlcc2.params()))
    for name, h in held.items():
        assert h["value"] == pytest.approx(values[name])
        assert h["identified_by"]["primitive"] in {d["primitive"] for d in rec["dropped"]}
    assert any("held at the profile's values" in n for n in plan.stats["notes"])
    # the confined-water lattice was tried first: a 360 s trial cannot hold the turns it makes reachable
    assert plan.stats["options"]["settle"] == "lattice"
    assert any(n.startswith("confined-water settling") and "tried and not kept" in n for n in plan.stats["notes"])
    # ... and the notes say what in this water would identify the held ones: the confined-water design's
    # manoeuvres in a longer trial; before, only the coarse lattice's verdict was given
    longer = [n for n in plan.stats["notes"] if n.startswith("a longer trial would identify every held parameter")]
    assert len(longer) == 1, plan.stats["notes"]
    need = float(re.search(r"--trial-length >= (\d+) s", longer[0]).group(1))
    assert need > 360.0
    longer_plan, longer_td = plan_with_design(_bay(tmp_path), profile=kvlcc2, primitives=lib, trial_length_s=need, headings=8)
    assert longer_plan.feasible and "held_parameters" not in longer_td.record  # measured: the 180 deg turn and the stop
    head, _ = design_rows(plan)  # the trial card's design section names them too
    line = next(x for x in head if x.startswith("Held at the profile's values"))
    assert all(n in line for n in held)
    # the water each dropped one is said to need is true: a move whose extent would fit the bay in some
    # heading fits nowhere because no placement of it is reachable, and the card says that, not 'needs'
    for d in rec["dropped"]:
        a, c = d["needs_m"]
        if max(a, c) <= 8000.0 and min(a, c) <= 6000.0:
            assert d.get("unreachable") is True, d
    by = next(iter(held.values()))["identified_by"]
    a, c = by["needs_m"]
    assert max(a, c) <= 8000.0 and min(a, c) <= 6000.0  # what would identify them is not larger than the bay
    assert by["unreachable"] is True and f"{by['primitive']} (" in line and "has no reachable placement" in line
    assert f"{by['primitive']} needs" not in line


def test_a_bay_plan_resumes_over_its_short_forms_holding_what_it_held(tmp_path, kvlcc2, bay_plan):
    """Before: the example recordings of its first step raised KeyError 'stopping_coast_75', and
    the resume re-designed over the ship's library without the plan's short forms and held
    parameters (refused: 'the primitive library [...] cannot identify'). The rest is designed over
    the plan's own library (its short forms) with the same parameters held, listed again. The ship
    is put back at the plan's start (heading north): from the end of its stop the bay has no
    placement of another one, and the resumed plan would be infeasible for the water, not the resume."""
    from maps.resume_example import example_recordings

    bay_map, plan, td = bay_plan
    assert any(s.segment == "informative" and s.primitive == "stopping_coast_75" for s in plan.steps)
    path = tmp_path / "plan.json"
    path.write_text(plan.to_json())
    example_recordings(path, tmp_path / "rec", 1)
    (rec,) = sorted((tmp_path / "rec").glob("*.csv"))
    lat, lon = plan.stats["start"][:2]
    args = ["plan", "--resume", str(path), "--map", str(bay_map), "--from", f"{lat},{lon},0", "--time-left", "600"]
    assert _run([*args, "--recordings", str(rec), "--no-export", "--json", "--out", str(tmp_path / "rest")]) == 0
    doc = json.loads((tmp_path / "rest" / "plan.json").read_text())
    assert doc["feasible"] and doc["design"]["counts"] == {"stopping_coast_75": 1}
    held = [h["parameter"] for h in td.record["held_parameters"]]
    assert [h["parameter"] for h in doc["design"]["held_parameters"]] == held
    values = dict(zip(kvlcc2.param_names, kvlcc2.params()))
    assert all(doc["design"]["reidentified"]["parameters"][n] == pytest.approx(values[n]) for n in held)
    assert any(n.startswith(f"the rest holds {len(held)} parameter(s) at the profile's values") for n in doc["stats"]["notes"])
    # a manoeuvre the first design had but did not choose was never checked against the map: when the
    # re-design chooses it (here the long stop, 10 km) and it fits nowhere, the rest is re-designed without it
    # (before: the plan was refused for it, 'deceleration fits nowhere', on the whole library's bay plan)
    import maps.resume as mr
    from diagnose.recording import load_recording
    from maps.geo import load_map

    first = Plan.load(path)
    first.design["dropped"] = [d for d in first.design["dropped"] if d["primitive"] != "stopping"]
    first.design["not_used"] = ["stopping"]
    runs = mr.match_recordings(first, [load_recording(rec)[0]], kvlcc2)
    sea = load_map(str(bay_map), draught_m=kvlcc2.draught_m)
    rest, rd = mr.resume_plan(first, runs, mr.Position(lat, lon, 0.0), 600.0, sea, kvlcc2)
    assert rest.feasible and rd.counts == {"stopping_coast_75": 1}
    assert "stopping" in {d["primitive"] for d in rd.record["dropped"]}  # a next resume leaves it out too
    assert any(n.startswith("the rest also leaves out stopping") for n in rest.stats["notes"])


def test_kvlcc2_in_the_bay_turns_round_on_a_confined_water_lattice_and_the_plan_is_verified(tmp_path, kvlcc2, kvlcc2_lib):
    """With the lattice autopilot's settling no course reversal of a VLCC has a reachable placement
    in the bay and the planner's only plan is a stop with 11 of 13 parameters held (or none, for a
    trial that asks for two manoeuvres). Settled as a master would on a 1.25 L lattice, a 1300 s
    trial is two 180 deg turns (the shortened form of the turning circle), verified against the
    margin, with every parameter identified and the lattice's choice said in the notes."""
    lib = by_name(kvlcc2_lib, ["turning_circle_35_s", "stopping"])
    plan, td = plan_with_design(_bay(tmp_path), profile=kvlcc2, primitives=lib, trial_length_s=1300.0, headings=8)
    assert plan.feasible and plan.min_clearance_m >= plan.margin_m
    counts = {k: v for k, v in td.record["counts"].items() if v}
    assert counts == {"turning_circle_35_s_180": 2}
    assert "held_parameters" not in td.record
    assert plan.stats["options"]["settle"] == "ship"
    assert plan.stats["lattice"]["resolution_m"] == pytest.approx(1.25 * kvlcc2.length_m, abs=kvlcc2.cruise_speed_mps)
    assert any(n.startswith("confined water: ") for n in plan.stats["notes"])
    sailed = [s.primitive for s in plan.steps if s.kind == "informative"]
    assert sorted(sailed) == ["turning_circle_35_s_180"] * 2
    # a run-in counted from the master's tolerance: the plan names each manoeuvre executed off the steady approach
    # its design assumed (the large-water run-in's tolerance), checked on the plan's inputs sailed again from the start
    nu = simulate(kvlcc2, plan.inputs[:-1], nu0=(kvlcc2.cruise_speed_mps, 0.0, 0.0), eta0=plan.track[0]).nu[0]
    prims = {p.name: p for p in td.primitives}
    expect = {}
    for s in plan.steps:
        if s.execute:
            d = nu[round(s.start_time_s / kvlcc2.sample_time)] - prims[s.primitive].nu0
            off = (d[0], d[1], d[2] * kvlcc2.length_m)
            assert abs(off[0]) < 0.1 and abs(off[1]) < 0.05 and abs(off[2]) < 0.05, (s.index, off)  # steady_enough's
            if any(abs(x) > t for x, t in zip(off, (0.02, 0.01, 0.005))):
                expect[s.index + 1] = off
    notes = [n for n in plan.stats["notes"] if "executed off the steady approach" in n]
    assert len(notes) == len(expect)  # measured: one, the second turn (speed -0.031 m/s, sway -0.003, r L -0.0044)
    for n in notes:
        got = [float(v) for v in re.findall(r"([+-]\d+\.\d+) m/s", n)]
        assert got == pytest.approx(expect[int(n.split()[1])], abs=1e-3), n


def test_a_mix_the_bay_cannot_hold_together_is_redesigned_without_what_cannot_follow(tmp_path, kvlcc2, kvlcc2_lib):
    """Before: each manoeuvre of the confined-water design had a placement of its own, but the mix (a
    stop after the turns) could not be sailed start to goal, and the fallback (six stops on the coarse
    lattice) was refused: no plan. Now the design is redone without the stop, the manoeuvre the best
    sailable part of the mix leaves out (maps.sailable), and the plan of shortened turns is verified;
    the stop is listed as dropped because it cannot follow the rest, not as too large for the water."""
    lib = by_name(kvlcc2_lib, ["turning_circle_35_p", "pull_out_20_s", "stopping"])
    plan, td = plan_with_design(_bay(tmp_path), profile=kvlcc2, primitives=lib, trial_length_s=2124.0, headings=8)
    assert plan.feasible and plan.min_clearance_m >= plan.margin_m
    assert plan.stats["options"]["settle"] == "ship"
    counts = {k: v for k, v in td.record["counts"].items() if v}
    assert counts and all(k.startswith("turning_circle_35_p_") for k in counts)  # measured: the 180 deg turn x3
    assert sorted(s.primitive for s in plan.steps if s.kind == "informative") == sorted(
        k for k, v in counts.items() for _ in range(v)
    )
    apart = [d for d in td.record["dropped"] if d.get("apart")]
    assert [d["primitive"] for d in apart] == ["stopping_coast_75"]
    a, c = apart[0]["needs_m"]
    assert max(a, c) <= 8000.0 and min(a, c) <= 6000.0  # it fits the bay alone
    assert apart[0]["unreachable"] is True
    head, _ = design_rows(plan)
    assert any("stopping_coast_75 (" in x and "cannot be sailed after the rest of the mix" in x for x in head)


def test_astern_power_declared_stops_the_ship_through_the_kernel(kvlcc2):
    prof = profile_from_dict(_astern_doc(), "kvlcc2-astern.toml")
    assert prof.engine.astern_rpm == 60.0 and prof.engine.rps_limits[0] == pytest.approx(-1.0)
    assert hm.has_astern(prof) and not hm.has_astern(kvlcc2)
    names = [f.name for f in short_form_table(prof)["stopping"]]
    assert "stopping_astern_50" in names and "stopping_astern_50" not in [f.name for f in short_form_table(kvlcc2)["stopping"]]
    stop = {p.name: p for p in short_forms(prof, ["stopping"])}
    astern = stop["stopping_astern_50"]
    coast, what = hm.stopping(kvlcc2)  # the same hull without astern: engine stop, coasting to half speed
    assert "coasting" in what
    k_astern = int(np.argmax(astern.nu[:, 0] < 0.5 * prof.cruise_speed_mps))
    k_coast = len(coast.inputs)
    assert 0 < k_astern < 0.7 * k_coast  # full astern halves the speed in well under the coasting time
    assert np.any(astern.inputs[:, 1] < -0.99)  # the shaft turned astern in the inputs the kernel simulated
    # the library's own stopping is now a crash stop
    gen, what = hm.stopping(prof)
    assert "astern" in what


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda d: d["engine"].update(astern_rpm=-5), "astern_rpm' must be a number > 0"),
        (lambda d: d["engine"].update(astern_rpm=200.0), "exceeds the ahead maximum"),
        (lambda d: d["engine"].update(astern_rpm=1e-9), "too little to stop the ship"),
        (lambda d: d["engine"].update(astern_rpm=1.0), "too little to stop the ship"),  # rev/s typed for rpm
        (lambda d: d["input_limits"].update(n=[-0.5, 2.0]), "needs input_limits.n down to"),
        (lambda d: d["model"].update(surge=["u_r*|u_r|", "n^2", "v_r*r"]), "do not reverse the thrust"),
        (lambda d: d["engine"].update(rps_limits=[-0.5, 2.0]), "rps_limits' starts at"),
    ],
)
def test_bad_astern_declarations_exit_2_in_one_line(tmp_path, capsys, edit, words):
    doc = _astern_doc()
    edit(doc)
    with pytest.raises(ProfileError, match="astern|rps_limits"):
        profile_from_dict(doc, "x.toml")
    p = tmp_path / "bad-astern.json"
    p.write_text(json.dumps(doc))
    rc = _run(["primitives", "--ship", str(p)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("error:") and words in err, err


def test_held_design_information_is_gammas_principal_submatrix_in_every_mean_subtraction(kvlcc2, kvlcc2_lib):
    """With the held parameters known, their regressors move to the left-hand side and the design's
    information for the rest is Gamma's principal submatrix (no Schur complement), whatever the
    instrument-mean subtraction: restricting each primitive's moments must give exactly that."""
    from expdesign.dopt import InfoSet
    from primitives.information import MEAN_SUBTRACTION, library_information, restrict

    infos = library_information(kvlcc2, by_name(kvlcc2_lib, ["zigzag_10_10_s", "stopping"]))
    names = kvlcc2.predictor_param_names
    keep = np.array([n not in ("Xvr", "Nrr", "Ydnn") for n in names])
    w = np.array([0.3, 0.7])
    for ms in MEAN_SUBTRACTION:
        whole = InfoSet.from_infos(infos).gamma(w, ms)
        part = InfoSet.from_infos(restrict(infos, keep)).gamma(w, ms)
        assert np.allclose(part, whole[np.ix_(keep, keep)], rtol=1e-12, atol=0.0), ms


def _settled_end(prim, psi0: float, res: float, heading: float) -> tuple[float, float, np.ndarray, float]:
    """(heading error rad, distance m to the nearest lattice point, end velocities, cross-track m to
    the lattice line through that point) of a basic move started on a lattice point at ``psi0``."""
    x, y, p = prim.track[-1]
    c, s = np.cos(psi0), np.sin(psi0)
    end = np.array([c * x - s * y, s * x + c * y])
    point = np.round(end / res) * res
    err = float(np.angle(np.exp(1j * (heading - psi0 - p))))
    cross = float((end - point) @ np.array([-np.sin(heading), np.cos(heading)]))
    return err, float(np.hypot(*(end - point))), prim.nu[-1], cross


def test_confined_settling_shortens_a_vlccs_course_reversal_and_ends_every_turn_steady_on_a_lattice_point(kvlcc2):
    """The lattice autopilot's settling (0.2 deg, 1 % of a length off the line, yaw rate under
    0.005 m/s at the hull's ends) makes a VLCC's course reversal 21-22 minutes on a 1.25 L lattice;
    settled as a master would (maps.autopilot.steady_enough: full ahead to regain speed, steady to
    0.5 deg) it is at least 10 % shorter (measured 13 % and 29 %), a 45 deg course change at least
    15 % (measured 21 % and 30 %), and every turn still ends steady on a lattice point of its new heading."""
    from maps.autopilot import steady_enough
    from maps.lattice import classes, lattice_basic_moves

    step = kvlcc2.cruise_speed_mps * kvlcc2.sample_time
    res = round(1.25 * kvlcc2.length_m / step) * step
    tight = lattice_basic_moves(kvlcc2, res, 8, spot_turns=False, settle="settle")
    steady = lattice_basic_moves(kvlcc2, res, 8, spot_turns=False, settle="steady")
    turns = {"turn_s": np.pi / 4, "turn_p": -np.pi / 4, "round_turn_s": np.pi, "round_turn_p": np.pi}
    for t_per, s_per in zip(tight[1:], steady[1:]):
        for psi0, t, s in zip(classes(8), t_per, s_per):
            if t.name.startswith("round_turn"):
                assert s.duration_s < 0.9 * t.duration_s, (t.name, s.duration_s, t.duration_s)
            else:
                assert s.duration_s < 0.85 * t.duration_s, (t.name, s.duration_s, t.duration_s)
            err, dist, nu, cross = _settled_end(s, float(psi0), res, float(psi0) + turns[t.name])
            assert steady_enough(kvlcc2, err, nu, cross), (t.name, err, nu, cross)
            assert dist <= step  # on a lattice point, to half a sample of travel either side


def test_a_refusal_after_the_confined_attempt_says_why_that_failed_too():
    """When the confined-water lattice gave no plan and today's planning refuses as well, the
    one-line refusal carries both reasons (the user would otherwise see only today's); when today's
    planning answers, the confined attempt's reason is a note of its lattice."""
    from maps.planner import CONFINED_TRIED, _fallback
    from maps.trialdesign import TrialTooShort

    def refuses(confined: bool):
        assert not confined
        raise TrialTooShort("--trial-length 1800 s cannot hold ...: give --trial-length >= 5988")

    why = f"{CONFINED_TRIED}: no verified plan (no sequence of moves reaches the goal)"
    with pytest.raises(TrialTooShort) as err:
        _fallback(refuses, why)
    assert str(err.value) == f"--trial-length 1800 s cannot hold ...: give --trial-length >= 5988; {why}"

    class Lat:
        notes: list[str] = []

    lat, td = _fallback(lambda confined: (Lat(), "design", False), why)
    assert (lat.notes, td) == ([why], "design")
