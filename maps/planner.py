"""Top level: plan a trial on a sea map (seed 001 chapter 8, section 9.4) -> :class:`maps.plan.Plan`.

1. load the map (draught + under-keel clearance make shallow water an obstacle);
2. build the motion set: informative primitives (counts d_q, optionally split at natural break
   points), basic moves with cost L-bar (8.8), every move settled onto the lattice;
3. rasterise footprints per heading and tabulate collision-free moves per lattice point;
4. A* over (i, j, heading, g_1..g_Q) (8.3) with the admissible relaxed cost-to-go table or the
   thesis heuristic (8.9);
5. re-simulate the plan continuously and check the swept hull against the map with the margin.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from maps import astar
from maps.collision import CollisionGrid, Window
from maps.geo import MapError, SeaMap, bundled_map_path, load_map
from maps.lattice import Move, classes, heading_table, lattice_basic_moves, nearest_heading, place, settle, transit_mismatch
from maps.plan import Plan, PlanStep
from maps.scenario import HELSINKI_GOAL, HELSINKI_START, thesis_planning_scenario
from maps.verify import resimulate
from primitives.library import Primitive
from primitives.ship import ShipProfile, load_profile
from primitives.simulate import simulate

LatLonHdg = tuple[float, float, float | None]


def default_resolution(profile: ShipProfile) -> float:
    """About four ship lengths, a whole number of samples of travel at cruise speed."""
    step = profile.cruise_speed_mps * profile.sample_time
    return float(max(1, round(4 * profile.length_m / step)) * step)


def resolve_primitives(profile: ShipProfile, counts: dict[str, int], given: list[Primitive] | None = None) -> list[Primitive]:
    """The informative primitives named in ``counts``: from ``given``, the section 9.4 scenario,
    the thesis dictionary or the standard trials of the library."""
    pool = {p.name: p for p in (given or [])}
    missing = [n for n in counts if n not in pool]
    if missing:
        pool.update({p.name: p for p in thesis_planning_scenario(profile)[0]})
        missing = [n for n in counts if n not in pool]
    if missing:
        from primitives.library import standard_trials, thesis_primitives

        pool.update({p.name: p for p in thesis_primitives(profile) + standard_trials(profile)})
        missing = [n for n in counts if n not in pool]
    if missing:
        raise MapError(f"unknown primitive(s) {missing} in the counts; known: {', '.join(sorted(pool))}")
    return [pool[n] for n in counts]


def _window(sea: SeaMap, res: float, start_xy, goal_xy, size: tuple[int, int]) -> Window:
    """Lattice through the start point, at least ``size`` points, covering start and goal."""
    ni, nj = size
    if sea.trial_area is not None:
        xmin, ymin, xmax, ymax = sea.trial_area.bounds
    else:
        cx, cy = (start_xy[0] + goal_xy[0]) / 2, (start_xy[1] + goal_xy[1]) / 2
        ni = max(ni, int(np.ceil(abs(start_xy[0] - goal_xy[0]) / res)) + 4)
        nj = max(nj, int(np.ceil(abs(start_xy[1] - goal_xy[1]) / res)) + 4)
        xmin, xmax = cx - (ni - 1) * res / 2, cx + (ni - 1) * res / 2
        ymin, ymax = cy - (nj - 1) * res / 2, cy + (nj - 1) * res / 2
        ex = sea.extent  # keep the window on the map: shift it inside
        dx = max(0.0, ex[0] - xmin) - max(0.0, xmax - ex[2])
        dy = max(0.0, ex[1] - ymin) - max(0.0, ymax - ex[3])
        xmin, xmax, ymin, ymax = xmin + dx, xmax + dx, ymin + dy, ymax + dy
    i0 = int(np.ceil((xmin - start_xy[0]) / res))
    j0 = int(np.ceil((ymin - start_xy[1]) / res))
    i1 = max(int(np.floor((xmax - start_xy[0]) / res)), i0 + ni - 1)
    j1 = max(int(np.floor((ymax - start_xy[1]) / res)), j0 + nj - 1)
    return Window(start_xy[0] + i0 * res, start_xy[1] + j0 * res, res, i1 - i0 + 1, j1 - j0 + 1)


def from_transit(prim: Primitive) -> Primitive:
    """The primitive's inputs applied from the transit state (cruise speed, no sway or yaw)."""
    nu0 = (prim.profile.cruise_speed_mps, 0.0, 0.0)
    sim = simulate(prim.profile, prim.inputs, nu0=nu0)
    return Primitive(prim.name, prim.description, prim.profile, prim.inputs, sim.nu[0], sim.eta[0], [], prim.kind, prim.commands)


def build_moves(profile: ShipProfile, prims: list[Primitive], counts: dict[str, int], res: float, n_head: int,
                split: bool, basic_cost: float, spot_turns: bool) -> tuple[list[Move], list[str], dict[str, int], list[str]]:
    """Motion set: informative moves (counter q each) then basic moves. Returns
    (moves, counter names, targets per counter, notes)."""
    moves: list[Move] = []
    names: list[str] = []
    targets: dict[str, int] = {}
    notes: list[str] = []
    for prim in prims:
        n = int(counts[prim.name])
        parts = prim.pieces() if split and prim.split_points else [prim]
        if split and len(parts) > 1:
            notes.append(f"{prim.name} split into {len(parts)} pieces at its natural break points, each used {n} times")
        for part in parts:
            if len(parts) > 1:  # a piece is sailed from the transit state, not from mid-manoeuvre
                part = from_transit(part)
            per = [settle(part, res, n_head, psi0) for psi0 in classes(n_head)]
            mm = max(transit_mismatch(s) for s in per)
            if mm > 0.05:
                notes.append(f"{part.name}: entry/exit velocity differs from transit by {mm:.2f}; the re-simulation will tell")
            q = len(names)
            names.append(part.name)
            targets[part.name] = n
            moves.append(place(per, res, n_head, q, 0.0, prim.name))
    for per in lattice_basic_moves(profile, res, n_head, spot_turns):
        moves.append(place(per, res, n_head, -1, basic_cost, per[0].name))
    return moves, names, targets, notes


def plan_trial(
    sea: SeaMap | str | Path | None = None,
    *,
    profile: ShipProfile | str = "full-scale",
    counts: dict[str, int] | None = None,
    primitives: list[Primitive] | None = None,
    start: LatLonHdg | None = None,
    goal: LatLonHdg | None = None,
    resolution: float | None = None,
    headings: int = 4,
    heuristic: str = "admissible",
    weights: tuple[float, float, float] = (1.0 / 120.0, 1.0, 10.0),
    margin: float = 20.0,
    split: bool = False,
    size: tuple[int, int] = (35, 44),
    sub: int = 8,
    basic_cost: float = 1.0,
    spot_turns: bool = True,
    ukc_m: float = 0.5,
    max_expansions: int = 30_000_000,
    replans: int = 2,
) -> Plan:
    """Plan a trial that uses every informative primitive ``counts[name]`` times (8.4) with as
    few basic moves as possible (8.8), from ``start`` to ``goal`` ((lat, lon, heading_deg|None)).

    When the continuous re-simulation breaks the margin, the footprints are grown by the deficit
    and the search repeated (``replans`` times at most). Without counts: the section 9.4 scenario (three primitives, three uses each). Returns a Plan;
    ``feasible`` is False (with ``stats['reason']`` and ``stats['help']``) when no plan exists
    or the re-simulated plan violates the margin.
    """
    t_all = time.perf_counter()
    if headings not in (4, 8, 16):
        raise MapError(f"--headings must be 4, 8 or 16, got {headings}")
    if margin < 0:
        raise MapError(f"--margin must be >= 0 m, got {margin:g}")
    prof = load_profile(profile) if isinstance(profile, str) else profile
    if not isinstance(sea, SeaMap):
        sea = load_map(sea, draught_m=prof.draught_m, ukc_m=ukc_m)
    res = float(resolution) if resolution else default_resolution(prof)
    if res <= 0:
        raise MapError(f"--resolution must be > 0 m, got {res:g}")
    if counts is None:
        prims, counts = thesis_planning_scenario(prof)
    else:
        bad = {k: v for k, v in counts.items() if not isinstance(v, (int, np.integer)) or v < 0}
        if bad:
            raise MapError(f"counts must be whole numbers >= 0, got {bad}")
        counts = {k: int(v) for k, v in counts.items() if v > 0}
        prims = resolve_primitives(prof, counts, primitives)
    is_helsinki = Path(sea.source).resolve() == bundled_map_path().resolve()

    def endpoint(given: LatLonHdg | None, feat, default: LatLonHdg, what: str) -> tuple[float, float, float | None, LatLonHdg]:
        if given is None and feat is not None:
            given = (feat.lat, feat.lon, None if feat.psi is None else float(np.degrees(feat.psi)))
        if given is None and is_helsinki:
            given = default
        if given is None:
            raise MapError(f"{sea.source}: no {what} point: give --{what} LAT,LON,HEADING_DEG or add a '{what}' Point feature")
        lat, lon, hdg = given
        x, y = sea.locate(lat, lon, what, margin)
        return x, y, (None if hdg is None else float(np.radians(hdg))), given

    sx, sy, spsi, start_ll = endpoint(start, sea.start, HELSINKI_START, "start")
    gx, gy, gpsi, goal_ll = endpoint(goal, sea.goal, HELSINKI_GOAL, "goal")
    table = heading_table(headings)
    h_start = nearest_heading(spsi or 0.0, table)
    warnings = list(sea.warnings)
    if spsi is not None and abs(((spsi - table[h_start]) + np.pi) % (2 * np.pi) - np.pi) > 1e-6:
        warnings.append(f"start heading {np.degrees(spsi):.1f} deg rounded to the lattice heading {np.degrees(table[h_start]):.1f} deg")

    t_setup = time.perf_counter()
    moves, cnames, targets, notes = build_moves(prof, prims, counts, res, headings, split, basic_cost, spot_turns)
    win = _window(sea, res, (sx, sy), (gx, gy), size)
    gi, gj = win.cell_of(gx, gy)
    si, sj = win.cell_of(sx, sy)
    if not win.contains(gi, gj):
        raise MapError(f"goal lies outside the planning window ({win.ni} x {win.nj} points of {res:g} m)")
    goal_snap = float(np.hypot(*(np.array(win.point(gi, gj)) - (gx, gy))))
    snap_max = max(float(m.snap_m.max()) for m in moves)
    ext = max(max(abs(v) for pr in m.prims for v in pr.footprint.bounds) for m in moves)
    max_extra = 100.0
    grid = CollisionGrid(sea, win, margin, sub, ext + margin + snap_max + res + max_extra)
    K, nj = headings, win.nj
    goal_h = [nearest_heading(gpsi, table)] if gpsi is not None else list(range(K))

    def problem(extra: float) -> tuple[astar.Problem, list]:
        """Collision-free moves per lattice point with footprints grown by margin + snap + extra."""
        valid = []
        for m in moves:
            per_h = []
            for h in range(K):
                rows = grid.footprint_rows(m.prim(h).footprint, float(table[h]), margin + m.snap_m[h] + extra)
                ok = grid.valid_everywhere(rows)
                di, dj = m.dcell[h]
                # the end point must be a lattice point of the window as well
                ii, jj = np.meshgrid(np.arange(win.ni) + di, np.arange(win.nj) + dj, indexing="ij")
                ok &= (ii >= 0) & (ii < win.ni) & (jj >= 0) & (jj < win.nj)
                per_h.append(ok)
            valid.append(per_h)
        succ: list[list[tuple[int, int, int, float]]] = [[] for _ in range(win.ni * nj * K)]
        for mi, m in enumerate(moves):
            for h in range(K):
                di, dj = (int(v) for v in m.dcell[h])
                h2 = (h + int(m.dh[h])) % K
                for i, j in zip(*np.nonzero(valid[mi][h])):
                    s = (int(i) * nj + int(j)) * K + h
                    succ[s].append((mi, ((int(i) + di) * nj + int(j) + dj) * K + h2, m.counter, m.cost))
        pb = astar.Problem(win.ni, nj, K, [targets[n] for n in cnames], succ,
                           (si * nj + sj) * K + h_start, [(gi * nj + gj) * K + h for h in goal_h], res)
        return pb, valid

    # plan; re-simulate; if the continuous track breaks the margin, grow the footprints by the
    # deficit and re-plan (at most ``replans`` times)
    extra = 0.0
    attempts: list[dict[str, float]] = []
    setup_s = time.perf_counter() - t_setup  # motion set, window, obstacle raster
    ver = None
    search_s, expansions, visited = 0.0, 0, 0
    for _ in range(replans + 1):
        t_tab = time.perf_counter()
        pb, valid = problem(extra)
        setup_s += time.perf_counter() - t_tab
        result = astar.search(pb, heuristic, weights, basic_cost, max_expansions)
        search_s += result.time_s
        expansions += result.expansions
        visited += result.states_visited
        if not result.found:
            break
        seq = [moves[m] for m in result.moves]
        prims_seq = [m.prim(s % K) for m, s in zip(seq, result.spatial)]
        end_cell = result.spatial[-1] // K
        ver = resimulate(sea, prims_seq, (sx, sy, float(table[h_start])), margin, win.point(end_cell // nj, end_cell % nj))
        attempts.append({"inflation_m": extra, "min_clearance_m": ver.min_clearance_m, "search_s": result.time_s})
        if ver.ok or extra >= max_extra:
            break
        extra = min(max_extra, extra + (margin - ver.min_clearance_m) + 2.0)
    n_states = win.ni * win.nj * K * int(np.prod([d + 1 for d in pb.targets]))  # (8.5)
    stats: dict[str, Any] = {
        "expansions": expansions, "states_visited": visited, "plan_time_s": search_s,
        "heuristic": heuristic, "expansions_per_s": expansions / max(search_s, 1e-9),
        "setup_time_s": setup_s, "lattice": {"ni": win.ni, "nj": win.nj, "headings": K, "resolution_m": res,
                                             "x0": win.x0, "y0": win.y0, "states": n_states},
        "cost": result.cost, "basic_cost": basic_cost, "h_start": result.h_start, "snap_max_m": snap_max,
        "goal_snap_m": goal_snap, "notes": notes, "warnings": warnings,
        "start": list(start_ll), "goal": list(goal_ll),
        "moves_valid": {m.name: int(sum(v.sum() for v in valid[i])) for i, m in enumerate(moves)},
        "attempts": attempts, "inflation_m": extra,
    }
    base = dict(ship=prof.name, input_names=list(prof.inputs), projection=sea.projection_info(), margin_m=margin,
                targets=dict(targets), map_name=sea.name, hull=(prof.length_m, prof.beam_m))
    if not result.found:
        from maps.diagnose import explain_failure

        reason, helps = explain_failure(pb, moves, cnames, result)
        if ver is not None:  # an earlier plan existed but broke the margin when re-simulated
            reason = f"{ver.reason}; with footprints grown by {extra:.0f} m: {reason}"
        stats.update(reason=reason, help=helps, total_time_s=time.perf_counter() - t_all)
        empty = np.zeros((0,))
        return Plan(steps=[], t=empty, track=np.zeros((0, 3)), lonlat=np.zeros((0, 2)), speed=empty,
                    step_of_sample=np.zeros((0,), int), inputs=np.zeros((0, len(prof.inputs))), feasible=False,
                    optimal=False, min_clearance_m=float("nan"), counts={n: 0 for n in cnames}, stats=stats, **base)

    lon, lat = sea.to_lonlat(ver.track[:, 0], ver.track[:, 1])
    steps = []
    t_acc = 0
    for k, (m, pr) in enumerate(zip(seq, prims_seq)):
        x, y, psi = ver.track[t_acc]
        b = pr.footprint.bounds
        steps.append(PlanStep(
            index=k, primitive=m.source or m.name, kind=m.kind, description=pr.description,
            start_time_s=float(ver.t[t_acc]), duration_s=pr.duration_s, entry_x=float(x), entry_y=float(y),
            entry_psi=float(psi), entry_lon=float(lon[t_acc]), entry_lat=float(lat[t_acc]),
            entry_speed_mps=float(np.hypot(*ver.nu[t_acc, :2])), commands=list(pr.commands),
            space_m=(float(b[2] - b[0]), float(b[3] - b[1])),
        ))
        t_acc += pr.n_samples
    used = {n: 0 for n in cnames}
    for m in seq:
        if m.counter >= 0:
            used[cnames[m.counter]] += 1
    stats.update(drift_m=ver.drift_m, total_time_s=time.perf_counter() - t_all, basic_moves=sum(1 for m in seq if m.counter < 0))
    if not ver.ok:
        stats.update(reason=ver.reason, help=["increase --margin (more room for drift)", "use a finer --resolution"])
    return Plan(steps=steps, t=ver.t, track=ver.track, lonlat=np.column_stack([lon, lat]), speed=np.hypot(ver.nu[:, 0], ver.nu[:, 1]),
                step_of_sample=ver.step_of_sample, inputs=ver.inputs, feasible=ver.ok, optimal=result.optimal and ver.ok,
                min_clearance_m=ver.min_clearance_m, counts=used, stats=stats, **base)
