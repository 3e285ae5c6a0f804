"""The planning chain as steps a notebook can call one at a time (Ljungberg 2022, chapters 7-8, section 9.4).

    td   = design_counts(profile)                          # maps.trialdesign: design -> whole manoeuvres
    lat  = build_lattice(sea, profile, td.support(), td.counts, options=PlanOptions())
    lat.fits_nowhere()                                     # {name: (along, cross) m of water it needs}
    out  = search_plan(lat)                                # A* over (i, j, heading, g_1..g_Q) (8.3)
    real = verify_plan(lat, out)                           # legs sailed from the actual state, re-simulated
    plan = assemble_plan(lat, out, real, design=td.record)

:func:`maps.trialdesign.design_for_map` redoes the design without what fits nowhere;
:func:`maps.planner.plan_trial` composes it all (with the re-plans on a verification failure).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from maps import astar, mapcache, movecache
from maps.collision import CollisionGrid, Window, quarter_turns
from maps.forked import map_halves
from maps.geo import MapError, SeaMap, bundled_map_path
from maps.graphsearch import Rows, reached
from maps.headings import heading_rounding_warning
from maps.lattice import Move, heading_table, nearest_heading, run_in_seconds
from maps.motionset import basic_move_set, default_resolution, informative_moves, planning_window
from maps.planoptions import PlanOptions
from maps.sailplan import assemble_plan, verify_plan  # noqa: F401 - the chain's steps, importable in one place
from maps.sizing import BYTES_PER_STATE, estimate_memory, needs, refuse_too_large, too_big_for_water
from primitives.footprint import swept_footprints
from primitives.library import Primitive
from primitives.ship import ShipProfile

LatLonHdg = tuple[float, float, float | None]


@dataclass
class Lattice:
    """Everything the search needs: window, collision grid, motion set, counters, start, goal."""

    sea: SeaMap
    profile: ShipProfile
    options: PlanOptions
    window: Window
    grid: CollisionGrid
    table: np.ndarray
    moves: list[Move]
    cnames: list[str]
    targets: dict[str, int]
    primitives: dict[str, Primitive]
    start: tuple[float, float, float]  # x, y, lattice heading
    h_start: int
    start_cell: tuple[int, int]
    goal_cell: tuple[int, int]
    goal_h: list[int]
    start_ll: LatLonHdg
    goal_ll: LatLonHdg
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    setup_s: float = 0.0
    too_big: dict[str, tuple[float, float]] = field(default_factory=dict)  # left out: larger than the water in every heading
    _placements: dict[float, list] = field(default_factory=dict, repr=False)
    _problem: tuple | None = field(default=None, repr=False)

    @property
    def res(self) -> float:
        return self.window.res

    @property
    def snap_max(self) -> float:
        return max(float(m.snap_m.max()) for m in self.moves)

    def n_states(self) -> int:
        """Size of the counter-augmented lattice (8.5)."""
        return self.window.ni * self.window.nj * len(self.table) * int(np.prod([d + 1 for d in self.targets.values()]))

    def placements(self, extra: float = 0.0) -> list[list[tuple[np.ndarray, np.ndarray]]]:
        """Per move and heading: (collision-free, inside the soft clearance zone) per lattice point;
        footprints grown by margin + snapping + ``extra``."""
        if extra in self._placements:
            return self._placements[extra]
        K = len(self.table)
        for m in self.moves:  # footprints first (cached on the primitives): the forked half would lose its copies
            for h in range(K):
                m.prim(h).footprint  # noqa: B018
        shape = (len(self.moves), K, self.window.ni, self.window.nj)
        # kept beside the map (maps.mapcache): they depend on the map, the grid and the moves' footprints only
        out = mapcache.kept_placements(
            self.sea, lambda: self.placement_inputs(extra), shape, lambda: self._make_placements(extra)
        )
        self._placements[extra] = out
        return out

    def _make_placements(self, extra: float) -> list[list[tuple[np.ndarray, np.ndarray]]]:
        """:meth:`placements` made: every (move, heading class) on its own, half of them in a forked child
        (:mod:`maps.forked`), the same results; read-only, as when read back from the cache."""
        K = len(self.table)
        q_n = K // 4
        flat = map_halves(lambda mq: self._class_placements(*mq, extra), [(m, q) for m in self.moves for q in range(q_n)])
        out = [[flat[mi * q_n + h % q_n][h // q_n] for h in range(K)] for mi in range(len(self.moves))]
        for per in out:
            for arrays in per:
                for a in arrays:
                    a.flags.writeable = False
        return out

    def placement_inputs(self, extra: float) -> str:
        """SHA-256 of everything :meth:`placements` reads beyond the map's key (the code, the map file, the draught):
        the collision grid (its window, cells and blocked cells), the margin, the soft clearance zone (the ship's
        length) and its cost, ``extra``, the heading table, and per move its footprints (WKB), which heading uses
        which primitive, its snapping errors and cell steps. Another ship, option or design gives other moves, so
        another digest."""
        o, g, w = self.options, self.grid, self.window
        h = hashlib.sha256(
            repr(
                (
                    (float(w.x0), float(w.y0), float(w.res), int(w.ni), int(w.nj)),
                    (int(g.sub), int(g.pad), float(g.c), g.blocked.shape),
                    (float(o.margin), float(o.clearance_lengths * self.profile.length_m), float(o.clearance_cost)),
                    float(extra),
                    len(self.moves),
                )
            ).encode()
        )
        h.update(np.packbits(g.blocked).tobytes())
        h.update(np.ascontiguousarray(self.table, dtype=np.float64).tobytes())
        for m in self.moves:
            firsts = [next(i for i, p in enumerate(m.prims) if p is q) for q in m.prims]  # which headings share one
            h.update(repr((len(m.prims), firsts)).encode())
            h.update(np.ascontiguousarray(m.snap_m, dtype=np.float64).tobytes())
            h.update(np.ascontiguousarray(m.dcell, dtype=np.int64).tobytes())
            for p in m.prims:
                wkb = shapely.to_wkb(p.footprint)
                h.update(len(wkb).to_bytes(8, "little") + wkb)
        return h.hexdigest()

    def _class_placements(self, m: Move, q: int, extra: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """(collision-free, inside the soft clearance zone) per lattice point of move ``m`` at the
        headings q, q + K/4, q + K/2, q + 3K/4 (a heading class and its quarter turns)."""
        o, grid, K = self.options, self.grid, len(self.table)
        base: dict[float, np.ndarray] = {}

        def rows(h: int, add: float) -> np.ndarray:
            """The cells of the footprint at heading h grown by margin + snapping + extra + add:
            rasterised once per class and turned (:func:`maps.collision.quarter_turns`) when the
            heading's growth is the class's (the snapping errors of turned headings are equal but
            for float rounding, about 1e-12 m)."""
            grow = o.margin + m.snap_m[h] + extra + add
            if m.prim(h) is m.prim(q) and abs(grow - (o.margin + m.snap_m[q] + extra + add)) <= 1e-9:
                if add not in base:
                    base[add] = grid.footprint_rows(
                        m.prim(q).footprint, float(self.table[q]), o.margin + m.snap_m[q] + extra + add
                    )
                return quarter_turns(base[add], (h - q) // (K // 4))
            return grid.footprint_rows(m.prim(h).footprint, float(self.table[h]), grow)

        return [self._placement(m, h, rows) for h in range(q, K, K // 4)]

    def _placement(self, m: Move, h: int, rows: Callable[[int, float], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """(collision-free, inside the soft clearance zone) per lattice point of move ``m`` at
        heading ``h``; ``rows(h, add)``: the cells of its footprint grown by ``add`` more."""
        o, win, grid = self.options, self.window, self.grid
        soft = o.clearance_lengths * self.profile.length_m
        ok = grid.valid_everywhere(rows(h, 0.0))
        di, dj = m.dcell[h]
        ii, jj = np.meshgrid(np.arange(win.ni) + di, np.arange(win.nj) + dj, indexing="ij")
        ok &= (ii >= 0) & (ii < win.ni) & (jj >= 0) & (jj < win.nj)  # ends on a lattice point too
        near = np.zeros_like(ok)
        if soft > 0 and o.clearance_cost > 0 and ok.any():
            near = ok & ~grid.valid_everywhere(rows(h, soft))
        return ok, near

    def fits_nowhere(self) -> dict[str, tuple[float, float]]:
        """Informative primitives with no collision-free placement in the water the ship can use
        (reachable from the start, the goal reachable after it): {name: (along, cross) metres of
        water the move takes, margin included on both sides, as :class:`maps.sizing.Needs` that
        says which of the two it is: too large for the water, or no placement reachable}."""
        out: dict[str, tuple[float, float]] = dict(self.too_big)
        used = self._usable_moves()
        for mi, m in enumerate(self.moves):
            if m.counter >= 0 and mi not in used:
                out[m.source or m.name] = needs(m.prims[0], self.options.margin, reach=True)
        return out

    def _usable_moves(self) -> set[int]:
        """Moves with a placement reachable from the start from which the goal stays reachable by
        repositioning moves alone (breadth-first search on the basic moves' graph both ways): another
        designed manoeuvre is no way there, since the mix may not hold it (:mod:`maps.sailable`) and
        a manoeuvre left out by the design would leave the ship with no way back."""
        pb = self.problem()
        sc = pb.succ
        e = np.column_stack([sc.sources(), sc.dst, sc.move]).astype(np.int64)
        n = len(sc)
        basic = np.asarray(sc.counter) < 0
        fwd = reached(Rows(n, e[basic, 0], e[basic, 1]), [pb.start_spatial])
        back = reached(Rows(n, e[basic, 1], e[basic, 0]), pb.goal_spatial)
        ok = fwd[e[:, 0]] & back[e[:, 1]]
        return set(np.unique(e[ok, 2]).tolist())

    def problem(self, extra: float = 0.0, blocked: frozenset = frozenset()) -> astar.Problem:
        """The A* problem: collision-free successors per spatial state, soft clearance in the cost,
        ``blocked`` (move index, spatial state) pairs left out (built once per (extra, blocked))."""
        key = (extra, blocked)
        if self._problem is not None and self._problem[0] == key:
            return self._problem[1]
        pb = self._build_problem(extra, blocked)
        self._problem = (key, pb)
        return pb

    def last_problem(self) -> astar.Problem:
        """The problem searched last (footprints grown, placements that broke the margin blocked by
        the re-plans of :func:`maps.planner.solve`), else the plain one."""
        return self._problem[1] if self._problem is not None else self.problem()

    def _build_problem(self, extra: float, blocked: frozenset) -> astar.Problem:
        K, nj, win = len(self.table), self.window.nj, self.window
        pen = self.options.clearance_cost * self.options.basic_cost
        parts = []
        for mi, (m, per_h) in enumerate(zip(self.moves, self.placements(extra))):
            for h, (ok, near) in enumerate(per_h):
                di, dj = (int(v) for v in m.dcell[h])
                h2 = (h + int(m.dh[h])) % K
                ii, jj = np.nonzero(ok)
                s = (ii * nj + jj) * K + h
                # the soft clearance cost steers repositioning away from shores; informative moves keep
                # only the hard margin (penalising them too made A* expand 20x more states for no safer plan)
                cost = np.where(near[ii, jj], m.cost + pen, m.cost) if m.counter < 0 else np.full(len(s), m.cost)
                parts.append((s, np.full(len(s), mi), ((ii + di) * nj + jj + dj) * K + h2, np.full(len(s), m.counter), cost))
        src, mv, dst, q, cost = (np.concatenate([p[k] for p in parts]) if parts else np.zeros(0) for k in range(5))
        if blocked:
            n_sp = win.ni * nj * K
            keep = ~np.isin(mv.astype(np.int64) * n_sp + src.astype(np.int64), [a * n_sp + b for a, b in blocked])
            src, mv, dst, q, cost = src[keep], mv[keep], dst[keep], q[keep], cost[keep]
        succ = astar.Successors.from_edges(
            win.ni * nj * K,
            src.astype(np.int64),
            mv.astype(np.int64),
            dst.astype(np.int64),
            q.astype(np.int64),
            cost.astype(float),
        )
        si, sj = self.start_cell
        gi, gj = self.goal_cell
        return astar.Problem(
            win.ni,
            nj,
            K,
            [self.targets[n] for n in self.cnames],
            succ,
            (si * nj + sj) * K + self.h_start,
            [(gi * nj + gj) * K + h for h in self.goal_h],
            self.res,
        )

    def pose(self, spatial: int) -> tuple[float, float, float]:
        K, nj = len(self.table), self.window.nj
        cell, h = divmod(spatial, K)
        x, y = self.window.point(cell // nj, cell % nj)
        return x, y, float(self.table[h])


def _endpoint(sea: SeaMap, given: LatLonHdg | None, feat, default: LatLonHdg, what: str, margin: float):
    if given is None and feat is not None:
        given = (feat.lat, feat.lon, None if feat.psi is None else float(np.degrees(feat.psi)))
    if given is None and Path(sea.source).resolve() == bundled_map_path().resolve():
        given = default
    if given is None:
        raise MapError(f"{sea.source}: no {what} point: give --{what} LAT,LON,HEADING_DEG or add a '{what}' Point feature")
    lat, lon, hdg = given
    x, y = sea.locate(lat, lon, what, margin)
    return x, y, (None if hdg is None else float(np.radians(hdg))), given


def build_lattice(
    sea: SeaMap,
    profile: ShipProfile,
    primitives: list[Primitive],
    counts: dict[str, int],
    *,
    start: LatLonHdg | None = None,
    goal: LatLonHdg | None = None,
    options: PlanOptions | None = None,
    cache: dict[str, Any] | None = None,
    prefilter: bool = False,
) -> Lattice:
    """Window, collision grid and motion set for planning ``counts`` uses of ``primitives``.

    ``cache`` (a dict kept between calls) reuses moves already built for the same options.
    Raises MapError before any heavy work when the lattice would not fit in ``max_memory_gib``.
    ``prefilter``: leave out (in ``too_big``) primitives larger than the navigable water in every
    lattice heading, without building their moves.
    """
    t0 = time.perf_counter()
    o = replace(options) if options is not None else PlanOptions()  # the lattice's own: solve may switch off smoothing
    o.check()
    res = float(o.resolution) if o.resolution else default_resolution(profile, sea)
    K = o.headings
    (sx, sy, spsi, start_ll), (gx, gy, gpsi, goal_ll) = _endpoints(sea, start, goal, o.margin, cache)
    win = planning_window(sea, res, (sx, sy), (gx, gy), o.size)
    prims = [p for p in primitives if counts.get(p.name, 0) > 0]
    refuse_too_large(win, K, prims, counts, profile, o)
    table = heading_table(K)
    h_start = nearest_heading(spsi or 0.0, table)
    warnings = [*profile.load_warnings, *sea.warnings]  # a model.json's findings its profile cannot hold first
    if spsi is not None and (w := heading_rounding_warning(spsi, float(table[h_start]))):
        warnings.append(w)
    too_big = too_big_for_water(sea, win, prims, table, o.margin) if prefilter else {}
    moves, names, targets, notes = _motion_set(
        profile, [p for p in prims if p.name not in too_big], counts, res, o, {} if cache is None else cache
    )
    gi, gj = win.cell_of(gx, gy)
    if not win.contains(gi, gj):
        raise MapError(f"goal lies outside the planning window ({win.ni} x {win.nj} points of {res:g} m)")
    return Lattice(
        sea,
        profile,
        o,
        win,
        _collision_grid(sea, win, moves, profile, o),
        table,
        moves,
        names,
        targets,
        {p.name: p for p in prims},
        (sx, sy, float(table[h_start])),
        h_start,
        win.cell_of(sx, sy),
        (gi, gj),
        [nearest_heading(gpsi, table)] if gpsi is not None else list(range(K)),
        start_ll,
        goal_ll,
        notes,
        warnings,
        time.perf_counter() - t0,
        too_big,
    )


def _endpoints(
    sea: SeaMap, start: LatLonHdg | None, goal: LatLonHdg | None, margin: float, cache: dict[str, Any] | None = None
) -> tuple[tuple, tuple]:
    """(x, y, psi or None, (lat, lon, heading)) of the start and of the goal: given, else the map's
    features, else (bundled map) the thesis's start and goal. Taken from ``cache`` when
    :func:`prepare_basic_moves` found them already (checking a point against the obstacles grown
    by the margin is 0.05 s on the bundled map)."""
    from maps.scenario import HELSINKI_GOAL, HELSINKI_START

    hit = (cache or {}).get("endpoints")
    if hit is not None and hit[0] is sea and hit[1] == (start, goal, margin):
        return hit[2]
    mapcache.kept_no_go(sea, margin)  # the obstacles grown by the margin: made from the map alone, kept beside it
    return (
        _endpoint(sea, start, sea.start, HELSINKI_START, "start", margin),
        _endpoint(sea, goal, sea.goal, HELSINKI_GOAL, "goal", margin),
    )


def _motion_set(
    profile: ShipProfile, prims: list[Primitive], counts: dict[str, int], res: float, o: PlanOptions, cache: dict[str, Any]
) -> tuple[list[Move], list[str], dict[str, int], list[str]]:
    """(moves, counter names, targets, notes): the informative moves of ``prims`` (one counter
    each, or one per piece with ``split``) and the basic moves, built into ``cache`` or taken from it."""
    K = o.headings
    _basic_footprints(profile, res, o, cache)  # read by _collision_grid: kept with the moves, not formed every plan
    run_in = run_in_seconds(profile, o.run_in_s)
    # each primitive's moves on their own: kept on disk between commands (maps.movecache), else built,
    # some of them in a forked child (maps.forked), same moves
    built_with = (res, K, o.split, run_in, o.settle)
    todo = []
    for p in prims:
        if p.name not in cache:
            k = movecache.key(profile, "informative", built_with, p)
            kept = movecache.load(k, profile)
            if kept is not None:
                cache[p.name] = kept
            else:
                todo.append((p, k))
    for (p, k), built in zip(todo, map_halves(lambda pk: _informative(pk[0], *built_with), todo, min_items=2)):
        cache[p.name] = built
        movecache.store(k, built, profile)
    moves, names, targets, notes = [], [], {}, []
    for p in prims:
        mv_, nm_, _, nt_ = cache[p.name]
        for m, n in zip(mv_, nm_):
            moves.append(Move(**{**m.__dict__, "counter": len(names)}))
            names.append(n)
            targets[n] = int(counts[p.name])
        notes += nt_
    return moves + cache["basic"], names, targets, notes


def _collision_grid(sea: SeaMap, win: Window, moves: list[Move], profile: ShipProfile, o: PlanOptions) -> CollisionGrid:
    """The window's blocked cells, padded by the reach of the largest footprint grown by every
    growth the placements use (margin, snapping, a cell, the soft zone and 100 m for re-plans).
    The reach is the farthest footprint point from the move's start at any heading (its distance
    from the origin: the bounds alone miss up to a factor sqrt(2) once the footprint is turned)."""
    ext = max(
        (float(np.hypot(*shapely.get_coordinates(pr.footprint).T).max(initial=0.0)) for m in moves for pr in m.prims), default=0.0
    )
    snap = max(float(m.snap_m.max()) for m in moves)
    pad = ext + o.margin + snap + win.res + 100.0 + o.clearance_lengths * profile.length_m
    return mapcache.kept_grid(sea, win, o.margin, o.sub, pad)  # made from the map alone: kept beside it


def _informative(p: Primitive, res: float, K: int, split: bool, run_in: float, settle: str) -> tuple:
    """:func:`maps.motionset.informative_moves` of ``p`` alone, with the swept footprints of its
    moves computed (cached on their primitives)."""
    out = informative_moves([p], {p.name: 1}, res, K, split, run_in, settle=settle)
    for m in out[0]:  # a move's primitives share their run-in and manoeuvre: the union of those hulls formed once
        todo = [pr for pr in m.prims if "footprint" not in pr.__dict__]
        for pr, fp in zip(todo, swept_footprints([pr.track for pr in todo], p.profile.length_m, p.profile.beam_m)):
            pr.__dict__["footprint"] = fp  # the cached property's value
    return out


def _footprint(pr: Primitive) -> Any:
    """The primitive's swept footprint (its cached property)."""
    return pr.footprint


def _basic_moves(profile: ShipProfile, res: float, o: PlanOptions, cache: dict[str, Any]) -> list[Move]:
    """The basic (repositioning) moves for lattice spacing ``res``, from ``cache`` or built into it
    (the cache is cleared when the options it was built for changed)."""
    key = (res, o.headings, o.split, o.run_in_s, o.basic_cost, o.spot_turns, o.settle)
    if cache.get("key") != key:
        cache.clear()
        cache["key"] = key
    if "basic" not in cache:
        cache["basic_key"] = movecache.key(profile, "basic", key)
        cache["basic"] = movecache.load(cache["basic_key"], profile)
        if cache["basic"] is None:
            cache["basic"] = basic_move_set(profile, res, o.headings, o.basic_cost, o.spot_turns, o.settle)
            movecache.store(cache["basic_key"], cache["basic"], profile)
    return cache["basic"]


def _basic_footprints(profile: ShipProfile, res: float, o: PlanOptions, cache: dict[str, Any]) -> None:
    """The basic moves (:func:`_basic_moves`) with their swept footprints, read by :func:`build_lattice`: half of
    them formed in a forked child (maps.forked), the same polygons, and the moves kept again with them, so that a
    later plan reads them (whichever path, plan-trial's early step or the planner, built the moves first)."""
    todo = [pr for m in _basic_moves(profile, res, o, cache) for pr in m.prims if "footprint" not in pr.__dict__]
    for pr, fp in zip(todo, map_halves(_footprint, todo)):
        pr.__dict__["footprint"] = fp  # the cached property's value
    if todo:
        movecache.store(cache["basic_key"], cache["basic"], profile)


def prepare_basic_moves(
    sea: SeaMap,
    profile: ShipProfile,
    options: PlanOptions,
    cache: dict[str, Any],
    *,
    start: LatLonHdg | None = None,
    goal: LatLonHdg | None = None,
) -> None:
    """Build the basic moves, and their swept footprints, and find the start and goal into
    ``cache`` for :func:`build_lattice`: work that needs no design, done while a design is
    computed elsewhere."""
    res = float(options.resolution) if options.resolution else default_resolution(profile, sea)
    _basic_footprints(profile, res, options, cache)
    try:
        cache["endpoints"] = (sea, (start, goal, options.margin), _endpoints(sea, start, goal, options.margin))
    except MapError:  # said by build_lattice, where it would be said without this step (after the design)
        pass


@dataclass
class SearchOutcome:
    result: astar.SearchResult
    problem: astar.Problem
    extra: float = 0.0
    blocked: frozenset = frozenset()

    @property
    def found(self) -> bool:
        return self.result.found


def search_plan(lat: Lattice, extra: float = 0.0, blocked: frozenset = frozenset()) -> SearchOutcome:
    """A* over the counter-augmented lattice with footprints grown by ``extra`` metres and the
    ``blocked`` placements left out (re-plans after a failed verification)."""
    t0 = time.perf_counter()
    pb = lat.problem(extra, blocked)
    lat.setup_s += time.perf_counter() - t0
    o = lat.options
    fixed, _ = estimate_memory(lat.window.ni, lat.window.nj, len(lat.table), len(lat.moves), list(lat.targets.values()))
    max_states = max(10_000, int((o.max_memory_gib * 2**30 - fixed) / BYTES_PER_STATE))
    return SearchOutcome(
        astar.search(pb, o.heuristic, o.weights, o.basic_cost, o.max_expansions, max_states=max_states), pb, extra, blocked
    )
