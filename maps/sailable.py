"""Which mixes of the designed manoeuvres can be sailed together, start to goal.

The design checks that each manoeuvre has a placement reachable from the start with the goal
reachable after it (:meth:`maps.chain.Lattice.fits_nowhere`); in confined water that does not make
the mix sailable: a VLCC's turn may end where no stop can follow. On the counter-augmented lattice
(Ljungberg 2022, (8.3)-(8.5)) a breadth-first search from the start, over states from which the
goal stays reachable (counters ignored), gives every counter vector (g_1..g_Q), g_q <= d_q, with
which a path reaches the goal: the mixes the water holds. The planner keeps the one that sails the
most of the designed time and re-designs without the manoeuvres it leaves out.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from maps.astar import Problem
from maps.graphsearch import Rows, reached
from maps.sizing import Needs, needs

if TYPE_CHECKING:
    from maps.chain import Lattice

MAX_STATES = 2_000_000  # counter-augmented states the search may visit (the lattice search has its own budget)


def goal_reachable(pb: Problem) -> np.ndarray:
    """Per spatial state: whether some sequence of moves (counters ignored) reaches a goal state."""
    sc = pb.succ
    return reached(Rows(len(sc), np.asarray(sc.dst, np.int64), sc.sources()), pb.goal_spatial)


def sailable_mixes(pb: Problem, max_states: int = MAX_STATES) -> set[tuple[int, ...]] | None:
    """Every counter vector (g_1..g_Q) with which some path from the start reaches a goal state
    (each g_q <= d_q, the problem's targets); None when the search would visit more than
    ``max_states`` states (undecided)."""
    Q = len(pb.targets)
    radix, stride, G = pb.counter_index()
    back = goal_reachable(pb)
    if not back[pb.start_spatial]:
        return set()
    goals = set(pb.goal_spatial)
    seen = {pb.start_spatial * G}
    todo = deque(seen)
    out: set[int] = set()
    while todo:
        key = todo.popleft()
        s, c = divmod(key, G)
        if s in goals:
            out.add(c)
        for _, s2, q, _ in pb.succ[s]:
            if not back[s2]:
                continue
            c2 = c
            if q >= 0:
                if (c // stride[q]) % radix[q] >= pb.targets[q]:
                    continue
                c2 = c + stride[q]
            k2 = s2 * G + c2
            if k2 not in seen:
                if len(seen) >= max_states:
                    return None
                seen.add(k2)
                todo.append(k2)
    return {tuple((c // stride[q]) % radix[q] for q in range(Q)) for c in out}


def best_mix(mixes: set[tuple[int, ...]], seconds: list[float]) -> tuple[int, ...]:
    """The mix that sails the most manoeuvre time (``seconds``: each counter's manoeuvre duration),
    then the most manoeuvres; ties by the counters' order (deterministic)."""
    return max(mixes, key=lambda g: (sum(n * s for n, s in zip(g, seconds)), sum(g), g))


# said in the plan's notes (or its refusal) when the search above stops at its budget: nothing was left out for it
UNDECIDED = (
    "which of the designed manoeuvres can be sailed together was not decided: the search of the mixes the water "
    "holds stopped at its budget of {n:,} lattice states, so none was left out to re-design without it"
)


def not_sailable_together(lat: Lattice, max_states: int = MAX_STATES) -> dict[str, Needs] | None:
    """The designed manoeuvres that the best sailable mix (:func:`best_mix`) sails fewer times than
    designed, as :class:`maps.sizing.Needs` (``apart``); empty when the whole mix is sailable (a
    failure elsewhere) or when nothing is; None when the search stopped at ``max_states`` undecided
    (:data:`UNDECIDED` says so). Asked of the problem searched last: with the placements whose
    re-simulation broke the margin blocked."""
    pb = lat.last_problem()
    mixes = sailable_mixes(pb, max_states)
    if mixes is None:
        return None
    full = tuple(pb.targets)
    if not mixes or full in mixes:
        return {}
    prims = [lat.primitives[n] for n in lat.cnames]
    best = best_mix(mixes, [p.duration_s for p in prims])
    margin = lat.options.margin
    return {p.name: needs(p, margin, apart=True) for p, g, d in zip(prims, best, full) if g < d}
