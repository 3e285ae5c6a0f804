"""`shiptrial profile new --actuator twin_screw | azimuth` (issue 31): the two-unit MMG models behind
them (primitives/particulars/units.py), the profiles they convert to, and what the other commands
make of them.

No published twin-screw or podded ship with main particulars and measured manoeuvres was found to
check against (see README, "A ship from its main particulars"); the one published comparison used
is qualitative: Reichel (2019), "Equivalent standard manoeuvres for pod-driven ships", Ocean Eng.
187, 106165 (abstract): free-running sister ships, twin pods and twin screws with twin rudders —
the pods at the IMO's 35 deg turn the ship differently from 35 deg of rudder (only other pod angles
give similar figures). Our reading, stated in the test: a podded sister turns tighter at 35 deg.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from cli.app import _run
from primitives.particulars.build import Particulars, approach_rps, build_profile, mmg_ship, sample_time
from primitives.particulars.fit import excitation_runs
from primitives.particulars.mmg import fixed_helm, run
from primitives.particulars.trials import standard_trials, turn_figures
from primitives.particulars.units import unit_forces

FERRY = Particulars("ferry", 150.0, 25.0, 6.0, 0.6, 18.0)  # a twin-screw ferry's proportions


def _ship(actuator: str, **changes):
    p = replace(FERRY, actuator=actuator, **changes)
    ship = mmg_ship(p, 0.75)
    return p, ship, approach_rps(ship, p.speed)


def _tactical_l(ship, p, n0, delta=math.radians(35)) -> float:
    r = run(ship, "tc", fixed_helm(delta, n0), p.speed, int(25 * p.length / p.speed), 1.0, math.radians(2.32), math.radians(35))
    return turn_figures(np.c_[r.xy, r.psi])[1] / p.length


@pytest.mark.parametrize("actuator", ["twin_screw", "azimuth"])
def test_two_units_hold_the_approach_speed_straight_and_without_yaw(actuator):
    """The approach rpm balances the resistance with both screws' thrust (each carries half), and
    equal shafts with rudders or pods amidships make no sway or yaw."""
    p, ship, n0 = _ship(actuator)
    acc = ship.derivatives(np.array([p.speed, 0.0, 0.0]), 0.0, n0)
    assert acc[0] == pytest.approx(0.0, abs=1e-9) and acc[1] == 0.0 and acc[2] == pytest.approx(0.0, abs=1e-12)
    single = mmg_ship(FERRY, 0.75)
    assert n0 < approach_rps(replace(single, inter=ship.inter), p.speed)  # two screws turn slower than one


@pytest.mark.parametrize("actuator", ["twin_screw", "azimuth"])
def test_a_faster_port_shaft_turns_the_ship_to_starboard(actuator):
    """The thrust of off-centre screws has an arm: -y X (Khanfir et al. 2011's twin-screw moment)."""
    p, ship, n0 = _ship(actuator)
    r_dot = ship.derivatives(np.array([p.speed, 0.0, 0.0]), 0.0, (n0, 0.6 * n0))[2]
    assert r_dot > 0
    assert ship.derivatives(np.array([p.speed, 0.0, 0.0]), 0.0, (0.6 * n0, n0))[2] == pytest.approx(-r_dot)


def test_the_outer_screw_of_a_turn_runs_lighter():
    """Each screw sees the speed of its own position, u - y r: in a starboard turn (r > 0) the port
    screw (y < 0) meets faster water and gives less thrust, so the thrust's yaw moment -y X of the
    two units opposes the turn (rudders made negligible so that only the screws act)."""
    p, ship, n0 = _ship("twin_screw")
    bare = replace(ship, rudder_area=1e-9)
    r = 0.01
    rp = r * p.length / p.speed
    y = ship.y_unit * p.length
    port = ship.propeller_force(p.speed + y * r, n0, 0.0, rp)[0]
    stbd = ship.propeller_force(p.speed - y * r, n0, 0.0, rp)[0]
    assert port < stbd
    _, _, n_turn = unit_forces(bare, np.array([p.speed, 0.0, r]), 0.0, n0, p.speed, 0.0, rp)
    assert n_turn == pytest.approx(y * (port - stbd), rel=1e-6) and n_turn < 0


def test_a_pod_turns_its_thrust_and_its_housing_adds_steering_force():
    """Pods steered to +35 deg (alpha = -35 deg: thrust toward port at the stern) turn the ship to
    starboard; without its housing's lift the same pods turn it wider."""
    p, ship, n0 = _ship("azimuth")
    assert ship.input_row(math.radians(35), n0) == (n0, -math.radians(35), n0, -math.radians(35))
    with_housing = _tactical_l(ship, p, n0)
    bare = replace(ship, inter=ship.inter | {"housing": 0.0})
    assert 0 < with_housing < _tactical_l(bare, p, n0)


def test_a_podded_sister_turns_tighter_at_35_deg_than_twin_rudders():
    """Reichel (2019), abstract (module docstring): at the IMO's 35 deg the pod version's turning
    figures differ from the twin-rudder sister's; ours: the pods' tactical diameter is the smaller.
    A qualitative check of two models built from the same particulars, not a measured figure."""
    pods = _tactical_l(*(lambda p, s, n: (s, p, n))(*_ship("azimuth")))
    twin = _tactical_l(*(lambda p, s, n: (s, p, n))(*_ship("twin_screw")))
    assert pods < 0.8 * twin


@cache
def built(actuator: str):
    return build_profile(replace(FERRY, actuator=actuator), oe_nfev=15, draws=3, seed=0)


@pytest.mark.parametrize("actuator", ["twin_screw", "azimuth"])
def test_a_built_profile_names_its_sources_and_carries_a_prior(actuator):
    b = built(actuator)
    doc = tomllib.loads(b.text)
    for source in ("Taylor's twin-screw", "Schoenherr", "Kijima", "single-screw regressions applied", "assumed"):
        assert source in b.text, source
    assert ("Khanfir" in b.text) == (actuator == "twin_screw") and ("Gierusz" in b.text) == (actuator == "azimuth")
    p = b.profile
    assert p.prior_std is not None and p.prior_std.shape == p.params().shape and np.all(np.isfinite(p.prior_std))
    if actuator == "twin_screw":
        assert p.actuator == "rudder_propeller" and doc["particulars"]["rudder_area_m2"] == pytest.approx(2 * b.mmg.rudder_area)
    else:
        assert (
            p.actuator == "azimuth" and [t.y for t in p.thrusters] == [-6.25, 6.25] and "rudder_area_m2" not in doc["particulars"]
        )


@pytest.mark.parametrize("actuator", ["twin_screw", "azimuth"])
def test_the_profile_turns_and_zigzags_like_the_mmg_model_it_was_fitted_to(actuator):
    """The conversion, not the physics: the profile's own standard manoeuvres (the kernel, as the
    planner sails them) against the two-unit MMG model's, tactical diameter within 10 %."""
    b = built(actuator)
    p = replace(FERRY, actuator=actuator)
    mmg = turn_figures(np.c_[(r := excitation_runs(b.mmg, p.speed, b.approach_rps, sample_time(p))[0]).xy, r.psi])[1] / p.length
    fig = standard_trials(b.profile)
    assert fig.tactical_l["starboard"] == pytest.approx(mmg, rel=0.1)
    assert fig.tactical_l["port"] == pytest.approx(fig.tactical_l["starboard"], rel=0.02)
    assert fig.overshoot_10["starboard"] is not None and 0 < fig.overshoot_10["starboard"] < 20


COASTER = ["--name", "c", "--length", "100", "--beam", "16", "--draught", "6", "--block-coefficient", "0.7", "--speed", "13"]


@pytest.mark.parametrize("actuator", ["twin_screw", "azimuth"])
def test_profile_new_writes_each_actuator_and_the_other_commands_accept_it(tmp_path, capsys, actuator):
    out = tmp_path / "c.toml"
    assert _run(["profile", "new", *COASTER, "--actuator", actuator, "--prior-draws", "2", "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "tactical diameter" in said.out and "20/20" in said.out and "Traceback" not in said.err
    assert ("note: two pods" in said.err) == (actuator == "azimuth")
    assert _run(["primitives", "--ship", str(out)]) == 0
    assert _run(["design", "--ship", str(out), "--monte-carlo", "0", "--out", str(tmp_path / "rep")]) == 0
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--actuator", "azimuth", "--rudder-area", "10"], ["--rudder-area 10", "no rudder", "leave --rudder-area out"]),
        (
            ["--actuator", "twin_screw", "--beam", "12", "--draught", "8", "--propeller-diameter", "6.2"],
            ["--propeller-diameter 6.2", "6 m apart", "at most 6 m"],
        ),
        (["--actuator", "waterjet"], ["--actuator 'waterjet'", "twin_screw", "azimuth"]),
    ],
)
def test_particulars_that_make_no_sense_for_the_actuator_are_refused_in_one_line(tmp_path, capsys, args, says):
    base = list(COASTER)
    for flag, val in zip(args[::2], args[1::2]):
        if flag in base:
            base[base.index(flag) + 1] = val
        else:
            base += [flag, val]
    out = tmp_path / "s.toml"
    assert _run(["profile", "new", *base, "--out", str(out)]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    for s in says:
        assert s in lines[0], (s, lines[0])
    assert not out.exists()
