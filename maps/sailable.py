"""Which mixes of the designed manoeuvres can be sailed together, start to goal.

The design checks that each manoeuvre has a placement reachable from the start with the goal
reachable after it (:meth:`maps.chain.Lattice.fits_nowhere`); in confined water that does not make
the mix sailable: a VLCC's turn may end where no stop can follow. On the counter-augmented lattice
(Ljungberg 2022, (8.3)-(8.5)) a breadth-first search from the start, over states from which the
goal stays reachable (counters ignored), gives every counter vector (g_1..g_Q), g_q <= d_q, with
which a path reaches the goal: the mixes the water holds. The planner keeps the one that identifies
the most parameters, then sails the most of the designed time, and re-designs without the
manoeuvres it leaves out.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order

from expdesign.dopt import InfoSet
from maps.astar import Problem
from maps.sizing import Needs, needs
from primitives.information import library_information, unidentified_parameters
from primitives.library import Primitive
from primitives.ship import ShipProfile

if TYPE_CHECKING:
    from maps.chain import Lattice

MAX_STATES = 2_000_000  # counter-augmented states the search may visit (the lattice search has its own budget)


def goal_reachable(pb: Problem) -> np.ndarray:
    """Per spatial state: whether some sequence of moves (counters ignored) reaches a goal state."""
    sc = pb.succ
    n = len(sc)
    src, dst = sc.sources(), np.asarray(sc.dst, np.int64)
    gt = csr_matrix((np.ones(len(src)), (dst, src)), shape=(n, n))
    back = np.zeros(n, bool)
    for goal in pb.goal_spatial:
        if not back[goal]:
            back[breadth_first_order(gt, goal, directed=True, return_predecessors=False)] = True
    return back


def sailable_mixes(pb: Problem, max_states: int = MAX_STATES) -> set[tuple[int, ...]] | None:
    """Every counter vector (g_1..g_Q) with which some path from the start reaches a goal state
    (each g_q <= d_q, the problem's targets); None when the search would visit more than
    ``max_states`` states (undecided)."""
    Q = len(pb.targets)
    radix = [d + 1 for d in pb.targets]
    stride = [int(np.prod(radix[q + 1 :])) for q in range(Q)]
    G = int(np.prod(radix))
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


def best_mix(
    mixes: set[tuple[int, ...]], seconds: list[float], identified: Callable[[tuple[int, ...]], int] | None = None
) -> tuple[int, ...]:
    """The mix that identifies the most parameters (``identified(mix)``, when given; asked of the
    mixes no other sailable mix contains), then sails the most manoeuvre time (``seconds``: each
    counter's manoeuvre duration), then the most manoeuvres; ties by the counters' order."""
    top = [g for g in mixes if not any(h != g and all(a <= b for a, b in zip(g, h)) for h in mixes)]
    score = identified or (lambda g: 0)
    return max(top, key=lambda g: (score(g), sum(n * s for n, s in zip(g, seconds)), sum(g), g))


def identified_by(profile: ShipProfile, prims: list[Primitive], mean_subtraction: str) -> Callable[[tuple[int, ...]], int]:
    """``mix -> number of the profile's parameters`` the mix (counts of ``prims``) identifies, from
    each primitive's information matrix (:func:`primitives.information.unidentified_parameters`)."""
    infos = library_information(profile, prims)

    def count(g: tuple[int, ...]) -> int:
        w = np.array([n * p.n_samples for n, p in zip(g, prims)], float)
        if w.sum() <= 0:
            return 0
        gamma = InfoSet.from_infos(infos).gamma(w / w.sum(), mean_subtraction)
        return len(profile.predictor_param_names) - len(unidentified_parameters(profile, gamma))

    return count


def not_sailable_together(lat: Lattice, mean_subtraction: str = "complete") -> dict[str, Needs]:
    """The designed manoeuvres that the best sailable mix (:func:`best_mix`, the parameters
    identified under ``mean_subtraction`` first) sails fewer times than designed, as
    :class:`maps.sizing.Needs` (``apart``); empty when the whole mix is sailable (a failure
    elsewhere), when nothing is or when the search is undecided. Asked of the problem searched last:
    with the placements whose re-simulation broke the margin blocked."""
    pb = lat.last_problem()
    mixes = sailable_mixes(pb)
    full = tuple(pb.targets)
    if not mixes or full in mixes:
        return {}
    prims = [lat.primitives[n] for n in lat.cnames]
    best = best_mix(mixes, [p.duration_s for p in prims], identified_by(lat.profile, prims, mean_subtraction))
    margin = lat.options.margin
    return {p.name: needs(p, margin, apart=True) for p, g, d in zip(prims, best, full) if g < d}
