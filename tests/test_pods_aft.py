"""A ship with both pods aft (`profile new --actuator azimuth`, issue 31) on the lattice: the helm turns it
with a drift angle, its moves end on lattice points, its library offers no steady sway, and it plans.

Before: the fully actuated helm asked the pods for a side force without yaw that pods aft cannot give;
their least-norm allocation turned them astern, the ship stopped, every turn ran to the helm's 1,200 s
limit and ended hundreds of metres off the lattice on the wrong heading, and the sway steps' run-in
never reached its entry sway: the search ran out of memory on the open sea.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from maps.chain import PlanOptions
from maps.lattice import lattice_basic_moves, place
from maps.planner import plan_trial
from maps.testmaps import open_sea
from primitives.library import force_dictionary, library_notes
from primitives.maneuvers import pod_arm
from primitives.ship import load_profile

POD = Path(__file__).parent / "data" / "ferry-pod.toml"
RES, K = 800.0, 16


@pytest.fixture(scope="module")
def pod():
    return load_profile(str(POD))


def test_pods_aft_share_one_lever_arm(pod):
    assert pod_arm(pod) == pytest.approx(-72.0)
    assert pod_arm(load_profile("full-scale")) is None  # bow and stern thrusters: sway and yaw apart


def test_pods_aft_turn_bow_in_with_a_drift_angle(pod):
    """A starboard turn (r > 0) is held with the bow inside the circle: sway to port at midships
    (v < 0), a drift angle of a few degrees at radius 3 L as a rudder ship's, mirrored to port; at
    that drift the steady yaw moment is the pods' side force times their lever arm."""
    from maps.autopilot import _Helm
    from primitives.steady_forces import steady_forces

    helm = _Helm(pod, RES, K)
    u, r = helm.uc, helm.r_lim
    assert r == pytest.approx(u / (3.0 * pod.length_m))
    v = helm.drift(u, r)
    beta = np.degrees(np.arctan2(-v, u))
    assert 2.0 < beta < 20.0, beta
    assert helm.drift(u, -r) == pytest.approx(-v, rel=1e-3)
    f = steady_forces(pod, round(u, 2), v, round(r, 4))
    assert f[2] == pytest.approx(helm.arm * f[1], abs=1e-3 * abs(f[2]))


def test_pod_turns_end_on_the_lattice(pod):
    per = lattice_basic_moves(pod, RES, K)
    moves = {m.name: m for m in (place(p, RES, K, -1, 1.0, p[0].name) for p in per)}
    assert "spot_turn_s" not in moves and "round_turn_s" in moves
    for name, dh in (("turn_s", 1), ("turn_p", K - 1), ("round_turn_s", K // 2), ("round_turn_p", K // 2)):
        m = moves[name]
        assert np.all(m.dh == dh), (name, m.dh)
        assert m.snap_m.max() < 10.0 and m.heading_err < np.radians(0.5), (name, m.snap_m.max(), m.heading_err)
        assert m.prims[0].n_samples * pod.sample_time < 900.0  # settled, not stopped by the helm's limit


def test_no_steady_sway_for_pods_aft(pod):
    names = [p.name for p in force_dictionary(pod)]
    assert not any(n.startswith("sway_steps") for n in names) and "zz_exc_100" in names
    assert any(p.name == "sway_steps" for p in force_dictionary(load_profile("full-scale")))
    # said to the user (primitives, design, the plan's notes, a --counts naming them), not dropped silently
    (note,) = library_notes(pod)
    assert "sway_steps" in note and "x = -72.0 m (pods aft)" in note
    assert library_notes(load_profile("full-scale")) == [] and library_notes(load_profile("kvlcc2")) == []


def test_pod_ship_plans_on_open_sea(pod, tmp_path):
    path = tmp_path / "sea.geojson"
    path.write_text(json.dumps(open_sea(size_m=12_000.0)))
    plan = plan_trial(
        str(path),
        profile=pod,
        counts={"pull_out_20_s": 1, "stopping": 1},
        options=PlanOptions(resolution=RES, max_memory_gib=0.5),
    )
    assert plan.feasible, plan.stats.get("reason")
    assert plan.counts == {"pull_out_20_s": 1, "stopping": 1}
    assert plan.stats["drift_m"] < 50.0


def test_a_search_out_of_memory_points_to_the_greedy_heuristic():
    """Long transits leave the admissible bound some moves short (the bundled full-scale ship on the open
    sea); a search stopped at its memory budget says so and names --heuristic thesis, not the heuristic
    it already used."""
    from maps.astar import Problem, Successors, search
    from maps.diagnose import explain_failure

    e = np.array([(s, s + 1, -1) for s in range(9)] + [(s, s, 0) for s in range(10)], np.int64)
    succ = Successors.from_edges(10, e[:, 0], np.arange(len(e)), e[:, 1], e[:, 2], np.where(e[:, 2] < 0, 1.0, 0.0))
    pb = Problem(1, 10, 1, [3], succ, 0, [9])
    res = search(pb, max_states=2)
    assert not res.found and "memory limit" in res.reason
    from types import SimpleNamespace

    moves = [SimpleNamespace(counter=int(q), name="turn" if q >= 0 else "straight") for q in e[:, 2]]
    reason, helps = explain_failure(pb, moves, ["turn"], res)
    assert "memory limit" in reason and any("--heuristic thesis" in h for h in helps)
