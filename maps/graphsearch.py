"""Shortest distances and reachability on the lattice's graphs in plain numpy (no scipy.sparse).

The planner's only graph searches were ``scipy.sparse.csgraph``'s ``dijkstra`` (the relaxed
cost-to-go table of :func:`maps.astar.relaxed_table`) and ``breadth_first_order`` (which states
reach a goal, which moves are usable): importing scipy's sparse base for them cost 0.39-0.45 s of
CPU in every ``plan-trial`` (stop 46's profile), more than the searches themselves.

:func:`distances` is a label-correcting search (Bellman-Ford relaxation, Bertsekas 1998 section
2.3) over whole frontiers at once: every state whose distance fell in one sweep relaxes its edges
in the next, until none falls. With non-negative weights and IEEE rounding, ``fl(a + w)`` is
monotone in ``a``, so the distance reached is the minimum over paths of the path's floating-point
sum taken from the source outwards, as in Dijkstra's algorithm: the values are scipy's bit for
bit, whatever order the states are settled in (tests/test_graphsearch.py checks this against
scipy on the bundled map and on random graphs with tied weights).

A label-correcting search is O(V E) at worst (Bellman-Ford's bound: a state can fall once per
sweep, and there can be a sweep per hop), against Dijkstra's O(E log V): a chain of 20,000 states
with a costly shortcut to each took 41 s here against scipy's 0.007 s (stop 47's review). On the
planner's lattices it relaxes 1.1-2.7 times the edges in 7-47 sweeps, so :func:`distances` counts
its work and, past ``WORK_LIMIT`` times the graph's size, finishes with a heap-ordered Dijkstra
(:func:`_dijkstra_from`) from the labels it has: the same values, since every label is a path's
floating-point sum and the same monotonicity holds.
"""

from __future__ import annotations

import heapq

import numpy as np

WORK_LIMIT = 10  # edges relaxed (and SWEEP_COST per sweep) per edge and state before the heap takes over
SWEEP_COST = 1000  # one sweep's numpy calls (about 40 us) in edges relaxed (about 40 ns each)


class Rows:
    """A graph's edges grouped by source state (compressed rows): the edges of ``s`` are
    ``to[ptr[s]:ptr[s + 1]]`` with weights ``w[...]`` (in their given order)."""

    def __init__(self, n: int, frm: np.ndarray, to: np.ndarray, w: np.ndarray | None = None):
        frm = np.asarray(frm, np.int64)
        self.n = n
        self.ptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(frm, minlength=n), out=self.ptr[1:])
        self.to = np.asarray(to, np.int64)
        self.w = None if w is None else np.asarray(w, float)
        if not (frm[1:] >= frm[:-1]).all():  # not grouped yet (a lattice's own edges are)
            # stable either way; numpy sorts 16-bit integers by radix: 2 ms, not 12-30, for the bundled map's 143k edges
            order = np.argsort(frm.astype(np.uint16) if n <= 1 << 16 else frm, kind="stable")
            self.to = self.to[order]
            self.w = None if w is None else self.w[order]

    def out_of(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(edge indices, count per state) of the edges leaving ``states``, state by state."""
        a = self.ptr[states]
        cnt = self.ptr[states + 1] - a
        start = a - (np.cumsum(cnt) - cnt)
        return np.repeat(start, cnt) + np.arange(int(cnt.sum())), cnt


def reached(g: Rows, sources: np.ndarray | list[int]) -> np.ndarray:
    """Per state: whether a path along ``g``'s edges leads to it from one of ``sources`` (a
    source reaches itself): breadth-first, a whole frontier at a time."""
    seen = np.zeros(g.n, bool)
    front = np.unique(np.asarray(sources, np.int64))
    seen[front] = True
    while front.size:
        idx, _ = g.out_of(front)
        nxt = g.to[idx]
        nxt = np.unique(nxt[~seen[nxt]])
        seen[nxt] = True
        front = nxt
    return seen


def distances(g: Rows, dist: np.ndarray) -> np.ndarray:
    """Shortest distances along ``g``'s edges (non-negative weights) from the states with a finite
    ``dist`` (their starting values: 0 at a source, or the cost of arriving there), updated in
    place and returned; inf where no path leads. See the module doc for why the values are
    Dijkstra's bit for bit."""
    assert g.w is not None
    front = np.flatnonzero(np.isfinite(dist))
    budget = WORK_LIMIT * (g.to.size + g.n)
    while front.size:
        idx, cnt = g.out_of(front)
        budget -= idx.size + SWEEP_COST
        if budget < 0:  # many states falling many times (see the module doc): finish in Dijkstra's order
            return _dijkstra_from(g, dist)
        cand = np.repeat(dist[front], cnt) + g.w[idx]
        tgt = g.to[idx]
        fell = cand < dist[tgt]
        tgt, cand = tgt[fell], cand[fell]
        np.minimum.at(dist, tgt, cand)
        front = np.unique(tgt)
    return dist


def _dijkstra_from(g: Rows, dist: np.ndarray) -> np.ndarray:
    """Dijkstra's search (a binary heap, O(E log V)) from every state with a finite ``dist`` at
    that starting value, as :func:`distances` (in place). Python floats are IEEE doubles: the sums
    are numpy's bit for bit."""
    ptr, to, w, d = g.ptr.tolist(), g.to.tolist(), g.w.tolist(), dist.tolist()
    heap = [(d[s], s) for s in np.flatnonzero(np.isfinite(dist)).tolist()]
    heapq.heapify(heap)
    while heap:
        du, u = heapq.heappop(heap)
        if du > d[u]:  # a stale entry: u fell again after this was pushed
            continue
        for k in range(ptr[u], ptr[u + 1]):
            c = du + w[k]
            if c < d[to[k]]:
                d[to[k]] = c
                heapq.heappush(heap, (c, to[k]))
    dist[:] = d
    return dist
