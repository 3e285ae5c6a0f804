"""The motion set and the planning window of the lattice (Ljungberg 2022, section 8.2, (8.3)-(8.8)).

Informative primitives (counter q each) open with a run-in to their execute point and close
with a settling leg onto the lattice; basic moves (cost L-bar, (8.8)) reposition the ship.
"""

from __future__ import annotations

import numpy as np

from maps.collision import Window
from maps.geo import MapError, SeaMap
from maps.lattice import SETTLE_PHASES, Move, classes, lattice_basic_moves, place, run_in_inputs, transit_mismatch, with_run_in
from primitives.library import Primitive
from primitives.ship import ProfileError, ShipProfile
from primitives.simulate import simulate

MIN_POINTS_ACROSS = 8  # lattice points across the narrower side of a trial area


def default_resolution(profile: ShipProfile, sea: SeaMap | None = None) -> float:
    """About four ship lengths, a whole number of samples of travel at cruise speed; finer where
    the map's trial area is narrower than ``MIN_POINTS_ACROSS`` such spacings. A ship that
    cannot turn on the spot needs lattice points to reverse course on: a VLCC in a 6 km fjord at
    four lengths (1.3 km) has five points across, every turn ends on the far shore and the
    lattice has no cycle, so no plan can hold more than two manoeuvres."""
    step = profile.cruise_speed_mps * profile.sample_time
    want = 4 * profile.length_m
    if sea is not None and sea.trial_area is not None:
        x0, y0, x1, y1 = sea.trial_area.bounds
        want = min(want, min(x1 - x0, y1 - y0) / MIN_POINTS_ACROSS)
    return float(max(1, round(want / step)) * step)


def resolve_primitives(profile: ShipProfile, counts: dict[str, int], given: list[Primitive] | None = None) -> list[Primitive]:
    """The informative primitives named in ``counts``: from ``given``, the section 9.4 scenario,
    the thesis dictionary or the library of the profile."""
    from maps.scenario import scenario_supports, thesis_planning_scenario

    pool = {p.name: p for p in (given or [])}
    why: list[str] = []
    missing = [n for n in counts if n not in pool]
    if missing and scenario_supports(profile):  # its force-level zig-zags need generalized-force or azimuth inputs
        try:
            pool.update({p.name: p for p in thesis_planning_scenario(profile)[0]})
        except ProfileError as exc:  # a ship that does not swing under the scenario's yaw moment can still name its library's
            why.append(f"the planning scenario's manoeuvres are not offered: {exc}")
        missing = [n for n in counts if n not in pool]
    if missing:
        from primitives.library import build_library

        pool.update({p.name: p for p in build_library(profile, basic=False) if p.kind == "informative"})
        missing = [n for n in counts if n not in pool]
    if missing:
        from primitives.library import SWAY_STEPS, library_notes

        why += library_notes(profile) if set(missing) & set(SWAY_STEPS) else []
        raise MapError(
            f"--counts: unknown primitive(s) {', '.join(missing)} for {profile.name}; known: {', '.join(sorted(pool))}"
            + (f" ({'; '.join(why)})" if why else "")
        )
    return [pool[n] for n in counts]


def planning_window(
    sea: SeaMap, res: float, start_xy: tuple[float, float], goal_xy: tuple[float, float], size: tuple[int, int]
) -> Window:
    """Lattice through the start point, at least ``size`` points, covering start and goal (the
    trial area when the map has one)."""
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


def informative_moves(
    prims: list[Primitive],
    counts: dict[str, int],
    res: float,
    n_head: int,
    split: bool,
    run_in_s: float,
    q0: int = 0,
    settle: str = "lattice",
) -> tuple[list[Move], list[str], dict[str, int], list[str]]:
    """One move per informative primitive (or per piece with ``split``): run-in, primitive,
    settling leg (``settle``: a key of :data:`maps.lattice.SETTLE_PHASES`). Returns (moves,
    counter names, targets, notes); counters number from ``q0``."""
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
            ri = run_in_inputs(part, res, n_head, run_in_s)
            head = simulate(part.profile, np.vstack([ri, part.inputs]), nu0=(part.profile.cruise_speed_mps, 0.0, 0.0))
            built = [with_run_in(part, res, n_head, psi0, ri, head, SETTLE_PHASES[settle]) for psi0 in classes(n_head)]
            per = [b[0] for b in built]
            mm = max(transit_mismatch(s) for s in per)
            if mm > 0.05:
                notes.append(f"{part.name}: exit velocity differs from transit by {mm:.2f}; the re-simulation will tell")
            names.append(part.name)
            targets[part.name] = n
            moves.append(
                place(
                    per,
                    res,
                    n_head,
                    q0 + len(names) - 1,
                    0.0,
                    prim.name,
                    tuple(b[1] for b in built),
                    tuple(b[1] + part.n_samples for b in built),
                )
            )
    return moves, names, targets, notes


def basic_move_set(
    profile: ShipProfile, res: float, n_head: int, basic_cost: float, spot_turns: bool, settle: str = "lattice"
) -> list[Move]:
    """The repositioning moves (8.7), cost ``basic_cost`` each (8.8); ``settle`` as for :func:`informative_moves`."""
    per_class = lattice_basic_moves(profile, res, n_head, spot_turns, SETTLE_PHASES[settle])
    return [place(per, res, n_head, -1, basic_cost, per[0].name) for per in per_class]
