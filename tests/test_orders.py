"""Orders a crew can follow: every primitive of every bundled profile is described by orders in
the ship's own terms that stay within the profile's limits and rebuild the primitive's inputs."""

import dataclasses
from functools import cache

import numpy as np
import pytest

from primitives.library import build_library
from primitives.orders import (
    Order,
    engine_text,
    input_tolerance,
    inputs_from_orders,
    limit_violations,
    on_course,
    render,
    rudder_text,
)
from primitives.ship import Engine, builtin_profiles, load_profile, planar_profiles

_lib = cache(build_library)  # one build per profile for the whole module


@pytest.fixture(scope="module", params=planar_profiles())  # 4-DOF podded ships have no manoeuvre library
def library(request):
    return _lib(request.param)


def _prim(profile: str, name: str):
    return next(p for p in _lib(profile) if p.name == name)


def test_every_bundled_profile_is_covered():
    assert {"model-ship", "full-scale", "kvlcc2"} <= set(builtin_profiles())


def test_orders_stay_within_the_profile_limits(library):
    for p in library:
        assert p.orders, p.name
        assert not limit_violations(p.profile, p.orders), (p.name, limit_violations(p.profile, p.orders))
        # and so do the inputs they drive (the actuators never exceed their limits)
        for i, name in enumerate(p.profile.inputs):
            lo, hi = p.profile.input_limits.get(name, (-np.inf, np.inf))
            assert lo - 1e-9 <= p.inputs[:, i].min() and p.inputs[:, i].max() <= hi + 1e-9, (p.name, name)


def test_orders_rebuild_the_inputs(library):
    for p in library:
        times = [o.t_s for o in p.orders]
        assert times[0] == 0.0 and times == sorted(times) and times[-1] < p.duration_s, p.name
        rebuilt = inputs_from_orders(p.profile, p.orders, p.n_samples)
        tol = 1e-9 if p.profile.actuator == "rudder_propeller" else input_tolerance(p.profile, p.inputs)
        err = np.abs(rebuilt - p.inputs).max(axis=0)
        assert np.all(err <= tol), (p.name, err, tol)
        assert p.commands == render(p.orders)


def test_rudder_orders_respect_rate_and_angle(library):
    prof = library[0].profile
    if prof.actuator != "rudder_propeller":
        pytest.skip("rudder ships only")
    step = prof.helm.rudder_rate_deg_s * prof.sample_time
    for p in library:
        rudder = prof.helm.rudder_deg(p.inputs[:, 0])
        assert np.abs(rudder).max() <= prof.helm.max_rudder_deg + 1e-9, p.name
        assert np.abs(np.diff(np.concatenate([[0.0], rudder]))).max() <= step + 1e-9, p.name
        lo, hi = prof.engine.rps_limits
        assert lo - 1e-12 <= p.inputs[:, 1].min() and p.inputs[:, 1].max() <= hi + 1e-12


def test_checks_have_teeth():
    zz = _prim("kvlcc2", "zigzag_10_10_s")
    prof = zz.profile
    too_far = Order(5.0, "Starboard 40", {"rudder_deg": 40.0})
    too_fast = Order(5.0, "Engine 150 rpm", {"n_rps": 2.5, "n_rpm": 150.0})
    assert len(limit_violations(prof, zz.orders + [too_far, too_fast])) == 2
    # dropping the counter-rudder order changes the rebuilt inputs
    rebuilt = inputs_from_orders(prof, zz.orders[:2], zz.n_samples)
    assert np.abs(rebuilt - zz.inputs).max() > 0.1


def test_order_words_and_dict_round_trip():
    assert rudder_text(20) == "Starboard 20"
    assert rudder_text(-10) == "Port 10"
    assert rudder_text(0.0) == "Midships"
    assert rudder_text(35, 35) == "Hard a-starboard (35°)"
    prof = dataclasses.replace(load_profile("kvlcc2"), engine=Engine((0.0, 2.0), mcr_rpm=60 / 0.75 ** (1 / 3)))
    assert engine_text(prof, 1.0) == "Engine 60 rpm (75 % MCR)"
    assert engine_text(prof, 0.0) == "Stop engine"
    o = Order(
        12.0, "Port 20 at heading 20° to starboard of the initial course", {"rudder_deg": -20.0, "at_heading_change_deg": 20.0}
    )
    d = o.to_dict()
    assert d == {"t_s": 12.0, "text": o.text, "rudder_deg": -20.0, "at_heading_change_deg": 20.0}
    assert Order.from_dict(d) == o
    assert on_course(o, 350.0).text == "Port 20 at heading 010°"
    assert on_course(Order(0.0, "Midships"), 350.0).text == "Midships"


def test_azimuth_orders_name_angle_and_rpm_per_thruster():
    tau17 = _prim("full-scale", "tau17")
    first = tau17.orders[0]
    assert "Azimuth 1 (bow)" in first.text and "Azimuth 2 (stern)" in first.text and "rpm" in first.text
    assert {"n1_rpm", "alpha1_deg", "n2_rpm", "alpha2_deg"} <= set(first.values)
    # the zig-zag's reversals are given at the heading that triggers them
    switched = [o for o in tau17.orders if "at_heading_change_deg" in o.values]
    assert len(switched) >= 2 and all("initial course" in o.text for o in switched)


def test_expectations_and_abort_criteria():
    zz = _prim("kvlcc2", "zigzag_10_10_s")
    e = zz.expectations()
    assert e["heading_change_max_deg"] > 10 and e["heading_change_min_deg"] < -10  # overshoots past 10 deg
    # a zig-zag costs speed (MARIN zz_10: down to 7.09 m/s from 7.97), never gains any
    assert 0.75 * 7.97 < e["speed_min_mps"] < 0.95 * 7.97 and e["speed_max_mps"] < 8.1
    assert e["speed_min_kn"] == pytest.approx(e["speed_min_mps"] * 3600 / 1852)
    text = zz.abort_criteria()
    assert text.startswith("abort if speed below ") and "kn" in text and "initial course" in text
    d = zz.to_dict()
    assert d["orders"][0]["t_s"] == 0.0 and "expectations" in d and "inputs" not in d


def test_pieces_carry_the_orders_in_force():
    zz = _prim("kvlcc2", "zigzag_20_20_s")
    pieces = zz.pieces()
    assert len(pieces) == len(zz.split_points) + 1
    second = pieces[1]
    assert second.orders[0].t_s == 0.0
    assert any(o.text.startswith("(continuing) Engine") for o in second.orders)
    assert any(o.values.get("rudder_deg") == -20.0 for o in second.orders)
