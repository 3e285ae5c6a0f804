"""The A* lattice planner: counters, optimality, collision checks, continuous verification."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import LineString, shape

from maps import astar
from maps.collision import CollisionGrid, Window, quarter_turns, rasterise, row_intervals
from maps.geo import bundled_map_path, load_map
from maps.plan import Plan
from maps.planner import plan_trial
from primitives.ship import load_profile

SCENARIO = {"steep_zigzag_surge": 3, "wide_zigzag_surge": 3, "wide_zigzag_sway": 3}


@pytest.fixture(scope="module")
def profile():
    return load_profile("full-scale")


@pytest.fixture(scope="module")
def helsinki_plan(profile):
    return plan_trial(profile=profile, scenario="thesis-9.4", headings=4, run_in_s=0)


def land_polygons(path):
    """Land straight from the GeoJSON file, independent of the planner's loader."""
    doc = json.loads(open(path, encoding="utf-8").read())
    return shapely.union_all([shape(f["geometry"]) for f in doc["features"] if f["properties"].get("kind", "land") == "land"])


def test_helsinki_thesis_scenario_solved_and_verified(helsinki_plan):
    p = helsinki_plan
    assert p.feasible and p.optimal
    assert p.counts == SCENARIO == p.targets  # every counter meets its target
    lat = p.stats["lattice"]
    assert lat["ni"] * lat["nj"] >= 35 * 44 and min(lat["ni"], lat["nj"]) >= 35 and lat["headings"] == 4
    assert p.min_clearance_m >= p.margin_m
    # the continuous track, checked independently against the land polygons of the file
    track = LineString(p.lonlat)
    assert not track.intersects(land_polygons(bundled_map_path()))
    # starts in the harbour (upper left), ends to the south
    assert p.lonlat[0, 1] > p.lonlat[-1, 1]
    assert len(p.segment_steps("informative")) == sum(p.counts.values())  # the thesis has no run-ins: run_in_s=0
    assert p.stats["basic_moves"] >= len(p.segment_steps("transit"))
    assert p.stats["expansions"] > 0 and p.stats["plan_time_s"] > 0


def test_plan_contents_for_exporters(helsinki_plan, tmp_path):
    p = helsinki_plan
    n = len(p.t)
    assert p.track.shape == (n, 3) and p.lonlat.shape == (n, 2) and p.inputs.shape == (n, 4)
    assert p.speed.shape == (n,) and p.step_of_sample.shape == (n,)
    assert np.all(np.diff(p.step_of_sample) >= 0) and p.step_of_sample[-1] == len(p.steps) - 1
    for s in p.steps:
        assert s.commands and s.duration_s > 0 and s.space_m[0] > 0
        k = int(round(s.start_time_s))
        assert abs(p.lonlat[k, 0] - s.entry_lon) < 1e-9 and abs(p.track[k, 0] - s.entry_x) < 1e-9
    sea = load_map()
    x, y = sea.to_local(p.lonlat[:, 0], p.lonlat[:, 1])
    assert np.max(np.hypot(x - p.track[:, 0], y - p.track[:, 1])) < 1e-3
    assert p.projection["proj4"].startswith("+proj=tmerc")
    path = tmp_path / "plan.json"
    path.write_text(p.to_json())
    q = Plan.load(path)
    assert q.counts == p.counts and np.allclose(q.track, p.track) and q.feasible


def test_admissible_never_worse_than_thesis_heuristic(profile, helsinki_plan):
    greedy = plan_trial(profile=profile, scenario="thesis-9.4", headings=4, run_in_s=0, heuristic="thesis")
    assert greedy.counts == SCENARIO
    assert not greedy.optimal  # (8.9) is not admissible: no certificate
    assert helsinki_plan.stats["cost"] <= greedy.stats["cost"]


def _brute_force_cost(pb: astar.Problem) -> float:
    """Dijkstra on the full counter-augmented state graph (tiny problems only)."""
    radix = [d + 1 for d in pb.targets]
    G = int(np.prod(radix))
    strides = [int(np.prod(radix[q + 1 :])) for q in range(len(radix))]
    ns = len(pb.succ)
    rows, cols, w = [], [], []
    for s, lst in enumerate(pb.succ):
        for c in range(G):
            g = [(c // strides[q]) % radix[q] for q in range(len(radix))]
            for _, s2, q, cost in lst:
                if q >= 0 and g[q] >= pb.targets[q]:
                    continue
                rows.append(s * G + c)
                cols.append(s2 * G + c + (strides[q] if q >= 0 else 0))
                w.append(cost if cost > 0 else 1e-9)
    mat = csr_matrix((w, (rows, cols)), shape=(ns * G, ns * G))
    d = dijkstra(mat, indices=pb.start_spatial * G)
    full = G - 1
    return float(np.floor(min(d[s * G + full] for s in pb.goal_spatial) + 1e-6))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_astar_optimal_on_random_small_lattices(seed):
    rng = np.random.default_rng(seed)
    ni, nj, K = 5, 6, 4
    moves = [(0, 1, 0, -1), (0, 0, 1, -1), (0, 0, 3, -1), (2, 1, 0, 0), (1, 2, 1, 1)]  # (di, dj, dh, q) in heading 0
    blocked = rng.random((ni, nj)) < 0.2
    blocked[0, 0] = blocked[ni - 1, nj - 1] = False
    rot = [np.array([[1, 0], [0, 1]]), np.array([[0, -1], [1, 0]]), np.array([[-1, 0], [0, -1]]), np.array([[0, 1], [-1, 0]])]
    succ = [[] for _ in range(ni * nj * K)]
    for i in range(ni):
        for j in range(nj):
            if blocked[i, j]:
                continue
            for h in range(K):
                for mi, (di, dj, dh, q) in enumerate(moves):
                    a, b = rot[h] @ np.array([di, dj])
                    i2, j2 = i + a, j + b
                    if 0 <= i2 < ni and 0 <= j2 < nj and not blocked[i2, j2]:
                        succ[(i * nj + j) * K + h].append(
                            (mi, (int(i2) * nj + int(j2)) * K + (h + dh) % K, q, 0.0 if q >= 0 else 1.0)
                        )
    pb = astar.Problem(ni, nj, K, [2, 1], succ, 0, [((ni - 1) * nj + nj - 1) * K + h for h in range(K)])
    res = astar.search(pb, "admissible")
    best = _brute_force_cost(pb)
    if np.isfinite(best):
        assert res.found and res.optimal and res.cost == best
        # replay: the path uses each counter exactly its target
        used = [0, 0]
        for m in res.moves:
            if moves[m][3] >= 0:
                used[moves[m][3]] += 1
        assert used == [2, 1]
    else:
        assert not res.found


def test_successor_rows_are_the_edges_of_each_state_in_their_given_order():
    """A state's successors, asked one state at a time (the search) or all at once (the failure
    diagnosis), are its edges in the order given, with Python ints and floats."""
    rng = np.random.default_rng(5)
    n, e = 7, 30
    src, mv, dst, q = (rng.integers(0, n, e) for _ in range(4))
    cost = rng.uniform(0, 2, e)
    want = [[(int(mv[k]), int(dst[k]), int(q[k]), float(cost[k])) for k in range(e) if src[k] == s] for s in range(n)]
    one = astar.Successors.from_edges(n, src, mv, dst, q, cost)
    assert [one[s] for s in (3, 0, 3, 6, 1, 2, 4, 5)] == [want[s] for s in (3, 0, 3, 6, 1, 2, 4, 5)]
    assert list(one) == want and [one[s] for s in range(n)] == want
    assert all(type(x) is int for row in list(one) for t in row for x in t[:3])


@pytest.mark.parametrize("seed", range(6))
def test_collision_test_is_conservative(seed):
    """Whenever the raster says a footprint is free, shapely must agree (never optimistic)."""
    rng = np.random.default_rng(seed)
    sea = load_map()
    win = Window(x0=1000.0 + rng.uniform(0, 50), y0=-2000.0 + rng.uniform(0, 50), res=120.0, ni=12, nj=12)
    grid = CollisionGrid(sea, win, margin=0.0, sub=8, pad_m=600.0)
    fp = shapely.Polygon(rng.uniform(-200, 200, (5, 2))).convex_hull
    for psi in (0.0, np.pi / 2):
        ok = grid.valid_everywhere(grid.footprint_rows(fp, psi, 0.0))
        rot = shapely.affinity.rotate(fp, psi, origin=(0, 0), use_radians=True)
        no_go = shapely.clip_by_rect(sea.no_go(), *win.bounds)
        for i in range(win.ni):
            for j in range(win.nj):
                placed = shapely.affinity.translate(rot, *win.point(i, j))
                inside = shapely.box(*win.bounds).contains(placed)
                if ok[i, j]:
                    assert inside and not placed.intersects(no_go)


@pytest.mark.parametrize("seed", range(4))
def test_valid_everywhere_is_the_brute_force_answer(seed):
    """A lattice point is valid exactly when none of the footprint's cells, placed there, is blocked."""
    rng = np.random.default_rng(seed)
    win = Window(x0=1000.0 + rng.uniform(0, 50), y0=-2000.0 + rng.uniform(0, 50), res=120.0, ni=10, nj=11)
    grid = CollisionGrid(load_map(), win, margin=0.0, sub=8, pad_m=600.0)
    rows = grid.footprint_rows(shapely.Polygon(rng.uniform(-250, 250, (6, 2))).convex_hull, rng.uniform(0, 6.3), 5.0)
    cells = [(a, b) for a, b0, b1 in rows.tolist() for b in range(b0, b1 + 1)]
    want = np.array(
        [
            [
                not any(grid.blocked[grid.pad + i * grid.sub + a, grid.pad + j * grid.sub + b] for a, b in cells)
                for j in range(win.nj)
            ]
            for i in range(win.ni)
        ]
    )
    assert 0 < want.sum() < want.size  # some points free, some blocked: both answers are checked
    assert (grid.valid_everywhere(rows) == want).all()


@pytest.mark.parametrize("seed", range(4))
def test_quarter_turned_cells_are_the_cells_of_the_turned_footprint(seed):
    """The planner rasterises a footprint once per heading class and turns the cells for the
    headings a quarter turn apart: the same cells as rasterising the turned footprint."""
    rng = np.random.default_rng(seed)
    win = Window(x0=0.0, y0=0.0, res=120.0, ni=3, nj=3)
    grid = CollisionGrid(load_map(), win, margin=0.0, sub=8, pad_m=600.0)
    fp = shapely.Polygon(rng.uniform(-300, 300, (7, 2))).convex_hull
    psi0 = float(rng.uniform(0, np.pi / 2))
    base = grid.footprint_rows(fp, psi0, 20.0)
    for k in range(4):
        assert quarter_turns(base, k).tolist() == grid.footprint_rows(fp, psi0 + k * np.pi / 2, 20.0).tolist()


def test_rasterise_touches_every_cell():
    a, b = rasterise(shapely.box(0.0, 0.0, 1.0, 1.0), 10.0)
    # a 1 m box at a cell centre touches only that cell; its corner cell neighbours are not touched
    assert set(zip(a.tolist(), b.tolist())) >= {(0, 0)}
    rows = row_intervals(np.array([0, 0, 0, 1]), np.array([0, 1, 3, 5]))
    assert rows.tolist() == [[0, 0, 1], [0, 3, 3], [1, 5, 5]]


def _tiny_sea(tmp_path, size_deg=(0.04, 0.08)):
    dlat, dlon = size_deg
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"kind": "trial_area"},
                "geometry": {
                    "type": "Polygon",
                    "coordinates": [
                        [[25.0, 60.0], [25.0 + dlon, 60.0], [25.0 + dlon, 60.0 + dlat], [25.0, 60.0 + dlat], [25.0, 60.0]]
                    ],
                },
            },
            {
                "type": "Feature",
                "properties": {"kind": "land"},
                "geometry": {
                    "type": "Polygon",
                    "coordinates": [
                        [
                            [25.0 + dlon * 0.45, 60.0 + dlat * 0.4],
                            [25.0 + dlon * 0.55, 60.0 + dlat * 0.4],
                            [25.0 + dlon * 0.55, 60.0 + dlat * 0.6],
                            [25.0 + dlon * 0.45, 60.0 + dlat * 0.6],
                            [25.0 + dlon * 0.45, 60.0 + dlat * 0.4],
                        ]
                    ],
                },
            },
        ],
    }
    p = tmp_path / "sea.geojson"
    p.write_text(json.dumps(doc))
    return p


def test_small_map_plan_meets_counters(tmp_path, profile):
    path = _tiny_sea(tmp_path)
    plan = plan_trial(
        path,
        profile=profile,
        counts={"steep_zigzag_surge": 2, "wide_zigzag_sway": 1},
        start=(60.005, 25.01, 0.0),
        goal=(60.035, 25.07, None),
    )
    assert plan.feasible and plan.counts == {"steep_zigzag_surge": 2, "wide_zigzag_sway": 1}
    assert not LineString(plan.lonlat).intersects(land_polygons(path))


def test_infeasible_counts_explained(tmp_path, profile):
    path = _tiny_sea(tmp_path, (0.006, 0.014))  # about 670 x 780 m: the 840 m sway zig-zag cannot fit
    plan = plan_trial(
        path, profile=profile, counts={"wide_zigzag_sway": 1}, start=(60.001, 25.002, 90.0), goal=(60.005, 25.012, None)
    )
    assert not plan.feasible
    assert "wide_zigzag_sway" in plan.stats["reason"] and "fits nowhere" in plan.stats["reason"]
    assert any("smaller" in h for h in plan.stats["help"])


def test_counter_cannot_be_met(tmp_path, profile):
    """Start and goal in a small enclosed basin: the sway zig-zag fits only in the outer channel."""
    ring = [[24.99, 59.995], [25.07, 59.995], [25.07, 60.035], [24.99, 60.035], [24.99, 59.995]]
    basin = [[25.02, 60.01], [25.032, 60.01], [25.032, 60.016], [25.02, 60.016], [25.02, 60.01]]
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"kind": "trial_area"},
                "geometry": {
                    "type": "Polygon",
                    "coordinates": [[[24.98, 59.99], [25.08, 59.99], [25.08, 60.04], [24.98, 60.04], [24.98, 59.99]]],
                },
            },
            {
                "type": "Feature",
                "properties": {"kind": "land"},
                "geometry": {"type": "Polygon", "coordinates": [ring, basin[::-1]]},
            },
        ],
    }
    path = tmp_path / "basin.geojson"
    path.write_text(json.dumps(doc))
    plan = plan_trial(
        path, profile=profile, counts={"wide_zigzag_sway": 1}, start=(60.0118, 25.0235, 90.0), goal=(60.0142, 25.0285, None)
    )
    assert not plan.feasible
    assert "counter of wide_zigzag_sway" in plan.stats["reason"] and "reachable" in plan.stats["reason"]
    assert any("lower the count" in h for h in plan.stats["help"])


@pytest.mark.parametrize("headings", [8, pytest.param(16, marks=pytest.mark.slow)])
def test_more_headings_snap_to_lattice_and_verify(profile, headings):
    plan = plan_trial(profile=profile, headings=headings, counts={"steep_zigzag_surge": 1, "wide_zigzag_sway": 1})
    assert plan.feasible and plan.counts == plan.targets
    assert plan.stats["snap_max_m"] < 3.0  # every move ends within a few metres of a lattice point
    assert plan.stats["drift_m"] < 30.0


def test_split_primitives_count_pieces(profile, tmp_path):
    plan = plan_trial(
        _tiny_sea(tmp_path),
        profile=profile,
        split=True,
        counts={"steep_zigzag_surge": 1},
        start=(60.005, 25.01, 0.0),
        goal=(60.035, 25.07, None),
    )
    assert plan.feasible
    assert len(plan.counts) > 1 and all(k.startswith("steep_zigzag_surge.") for k in plan.counts)
    assert all(v == 1 for v in plan.counts.values())


def test_relaxed_infeasibility_is_explained_not_reported_as_zero_expansions():
    """A manoeuvre that ends where the goal cannot be reached: the search is refused up front and
    the reason says why, instead of 'every reachable combination was explored (0 expansions)'."""
    from maps.astar import Problem, search
    from maps.diagnose import explain_failure

    # states 0 (start) -> 1 (goal) by a basic move; the informative move 1 -> 2 ends in a dead end
    succ = [[(0, 1, -1, 1.0)], [(1, 2, 0, 0.0)], []]
    pb = Problem(3, 1, 1, [1], succ, 0, [1], 100.0)
    res = search(pb)
    assert not res.found and res.expansions == 0
    from types import SimpleNamespace

    moves = [SimpleNamespace(counter=-1, name="straight"), SimpleNamespace(counter=0, name="zigzag")]
    reason, helps = explain_failure(pb, moves, ["zigzag"], res)
    assert "uses all 1 informative manoeuvres" in reason and "0 expansions" not in reason
    assert any("lower counts" in h for h in helps)


def test_rudder_ship_can_reverse_course_on_the_lattice():
    """A ship that cannot turn on the spot still gets a cycle on the lattice: turns settle on the
    neighbouring heading (a VLCC's overshoot must not carry it onto the next one: with 16
    headings the odd headings were a trap) and round turns reverse course to either side."""
    from maps.lattice import heading_table
    from maps.motionset import basic_move_set

    prof = load_profile("kvlcc2")
    K = 16
    moves = {m.name: m for m in basic_move_set(prof, 749.0, K, 1.0, True)}
    assert not any(n.startswith("spot_turn") for n in moves)
    assert (moves["turn_s"].dh == 1).all() and (moves["turn_p"].dh == K - 1).all()
    for side in ("s", "p"):
        m = moves[f"round_turn_{side}"]
        assert (m.dh == K // 2).all()
        # the ship moves to the side it turned to (starboard: east of a northbound start)
        assert np.sign(m.dcell[0][1]) == (1 if side == "s" else -1)
    assert len(heading_table(K)) == K


def test_default_resolution_gives_eight_points_across_a_narrow_trial_area():
    from maps.motionset import default_resolution

    prof = load_profile("kvlcc2")
    data = Path(__file__).parent / "data"
    fjord = load_map(data / "fjord.geojson", draught_m=prof.draught_m)
    x0, y0, x1, y1 = fjord.trial_area.bounds
    res = default_resolution(prof, fjord)
    assert res < 4 * prof.length_m and min(x1 - x0, y1 - y0) / res >= 8 - 0.05
    open_sea = load_map(data / "open-sea.geojson", draught_m=prof.draught_m)
    assert default_resolution(prof, open_sea) == default_resolution(prof)  # wide water: about four ship lengths


def test_thesis_scenario_with_run_ins_at_four_headings_says_why_it_fails():
    """Four headings with run-ins: the start in the South Harbour is boxed in; the reason says so
    (how few lattice states the moves reach) and the help offers 16 headings."""
    plan = plan_trial(scenario="thesis-9.4", headings=4)
    assert not plan.feasible
    assert "reach only" in plan.stats["reason"] and "lattice states" in plan.stats["reason"]
    assert any("--headings 16" in h for h in plan.stats["help"])


def test_cheap_fit_test_gives_the_footprints_answer():
    """Whether a primitive fits a box in a heading, decided from its hull placements without
    the footprint where they tell, is the answer of the footprint's own bounds, in boxes just
    smaller and just larger than the footprint."""
    from maps.sizing import _fits_box
    from primitives.footprint import swept_hulls
    from primitives.library import build_library

    prof = load_profile("full-scale")
    lib = [p for p in build_library(prof) if p.kind == "informative"][:4]
    for p in lib:
        parts = swept_hulls(p.track, prof.length_m, prof.beam_m)
        for psi in (0.0, 0.4, 1.9):
            b = shapely.affinity.rotate(p.footprint, psi, origin=(0, 0), use_radians=True).bounds
            w, h = b[2] - b[0] + 40.0, b[3] - b[1] + 40.0
            for dw, dh in ((0.0, 0.0), (-1e-3, 0.0), (0.0, -1e-3), (-5.0, 5.0), (5.0, 5.0), (-2 * parts[1], 0.0), (1e-7, 1e-7)):
                room = (w + dw, h + dh)
                want = b[2] - b[0] + 40.0 <= room[0] and b[3] - b[1] + 40.0 <= room[1]
                assert _fits_box(p, parts, psi, room, 20.0) == want
