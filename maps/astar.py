"""A* over the counter-augmented state lattice (Ljungberg 2022, (8.1)-(8.12)).

State (8.3): (i, j, heading, g_1..g_Q), packed into one int:
``key = spatial * G + counters`` with ``spatial = (i nj + j) K + h`` and ``counters`` the
mixed-radix number of (g_1..g_Q) with radices d_q + 1. Costs (8.8): informative moves 0,
basic moves L-bar.

Heuristics:
* ``"admissible"``: cost-to-go table of a relaxed problem, computed once by a shortest-path search
  (:func:`maps.graphsearch.distances`, Dijkstra's values bit for bit) on the reversed graph over (i, j, heading, r) where r is the
  number of informative uses still to make, any primitive allowed for any remaining use.
  Every lattice path maps to a relaxed path of the same cost, so the table is admissible and
  consistent (Knepper & Kelly 2006; Ljungberg (2022) section 8.2.2) and the returned plan is optimal
  in repositioning cost on the lattice.
* ``"thesis"``: (8.9) h = a1 ||p - p_f|| + a2 |psi - psi_f| + a3 sum_q (d_q - g_q): greedy,
  neither admissible nor consistent; plans are not certified optimal.
"""

from __future__ import annotations

import heapq
import time
from dataclasses import dataclass, field

import numpy as np

from maps.graphsearch import Rows, distances

EPS = 1e-9  # weight standing in for a zero-cost edge (as scipy's csgraph had it: it drops explicit zeros)


class Successors:
    """Successors of every spatial state in compressed rows: the edges (move, successor, counter q
    or -1, cost) of state s are ``ptr[s]:ptr[s + 1]``. Built from arrays in one go; ``succ[s]``
    gives the list of tuples the search iterates, made when the search first reaches s (a search
    often expands a few dozen states of a lattice with 10^5 edges)."""

    def __init__(self, ptr: np.ndarray, move: np.ndarray, dst: np.ndarray, counter: np.ndarray, cost: np.ndarray):
        self.ptr, self.move, self.dst, self.counter, self.cost = ptr, move, dst, counter, cost
        self._p = ptr.tolist()
        self._rows: list[tuple[int, int, int, float]] | None = None  # every edge, once all are wanted (iteration)
        self._of: dict[int, list[tuple[int, int, int, float]]] = {}

    @classmethod
    def from_edges(
        cls, n: int, src: np.ndarray, move: np.ndarray, dst: np.ndarray, counter: np.ndarray, cost: np.ndarray
    ) -> Successors:
        """From edges in any order; a state's edges keep their given order (stable sort)."""
        order = np.argsort(src, kind="stable")
        ptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(src, minlength=n), out=ptr[1:])
        return cls(ptr, move[order], dst[order], counter[order], cost[order])

    def __len__(self) -> int:
        return len(self._p) - 1

    def __getitem__(self, s: int) -> list[tuple[int, int, int, float]]:
        a, b = self._p[s], self._p[s + 1]
        if self._rows is not None:
            return self._rows[a:b]
        row = self._of.get(s)
        if row is None:
            row = self._of[s] = list(
                zip(self.move[a:b].tolist(), self.dst[a:b].tolist(), self.counter[a:b].tolist(), self.cost[a:b].tolist())
            )
        return row

    def __iter__(self):
        if self._rows is None:
            self._rows = list(zip(self.move.tolist(), self.dst.tolist(), self.counter.tolist(), self.cost.tolist()))
        rows, p = self._rows, self._p
        return (rows[p[s] : p[s + 1]] for s in range(len(self)))

    def sources(self) -> np.ndarray:
        return np.repeat(np.arange(len(self)), np.diff(self.ptr))


@dataclass
class Problem:
    """The lattice search problem.

    ``succ[s]``: list of (move index, spatial successor, counter q or -1, cost) for spatial
    state s (collision-free moves only). ``goal_spatial``: accepted spatial goal states.
    """

    ni: int
    nj: int
    n_head: int
    targets: list[int]  # d_q
    succ: Successors | list[list[tuple[int, int, int, float]]]
    start_spatial: int
    goal_spatial: list[int]
    res: float = 1.0

    def counter_index(self) -> tuple[list[int], list[int], int]:
        """The packing of the counter vector (g_1..g_Q), 0 <= g_q <= d_q, into one index c = sum g_q stride_q
        ((8.3)-(8.5); a search state's key is spatial state x G + c): each counter's radix d_q + 1, its stride and
        G, the number of counter vectors."""
        radix = [d + 1 for d in self.targets]
        stride = [int(np.prod(radix[q + 1 :])) for q in range(len(self.targets))]
        return radix, stride, int(np.prod(radix))


@dataclass
class SearchResult:
    found: bool
    moves: list[int]  # move indices in order
    spatial: list[int]  # spatial states along the path (len moves + 1)
    cost: float
    expansions: int
    states_visited: int
    time_s: float
    heuristic: str
    optimal: bool
    h_start: float
    reason: str = ""
    extra: dict = field(default_factory=dict)


def edges(pb: Problem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(source, successor, counter, cost) of every edge, state by state."""
    if isinstance(pb.succ, Successors):
        sc = pb.succ
        return sc.sources(), sc.dst.astype(np.int64), sc.counter.astype(float), sc.cost.astype(float)
    e = np.array([(s, s2, q, cost) for s, lst in enumerate(pb.succ) for _, s2, q, cost in lst], float).reshape(-1, 4)
    return e[:, 0].astype(np.int64), e[:, 1].astype(np.int64), e[:, 2], e[:, 3]


def relaxed_table(pb: Problem) -> np.ndarray:
    """Cost-to-go h[spatial, r] of the relaxed problem (see module doc); inf if unreachable.

    Layer by layer: a state's cost with r informative uses left is reached by basic moves within
    layer r, or by an informative move into layer r - 1; so layer 0 is the search from the goals
    over the basic moves, and layer r the same search started from the cost of each informative
    move's arrival in layer r - 1 (the values of one search over the whole (state, r) graph)."""
    ns = pb.ni * pb.nj * pb.n_head
    D = int(sum(pb.targets))
    src, dst, qq, cost = edges(pb)
    w0 = np.where(cost > 0, cost, EPS)
    basic = qq < 0
    back = Rows(ns, dst[basic], src[basic], w0[basic])  # reversed graph: edge v -> u for every basic move u -> v
    isrc, idst, iw = src[~basic], dst[~basic], w0[~basic]
    out = np.empty((ns, D + 1))
    for r in range(D + 1):
        d = np.full(ns, np.inf)
        if r == 0:
            d[pb.goal_spatial] = 0.0
        else:
            arrive = out[idst, r - 1] + iw
            ok = np.isfinite(arrive)
            np.minimum.at(d, isrc[ok], arrive[ok])
        out[:, r] = distances(back, d)
    return out


class _Rows(dict):
    """Rows of a heuristic table as Python lists, converted when the search first reaches a state
    (a whole-table ``tolist`` cost more than a short search)."""

    def __init__(self, table: np.ndarray, f=None):
        super().__init__()
        self.table, self.f = table, f

    def __missing__(self, s: int) -> list[float]:
        row = self.table[s] if self.f is None else self.f(self.table[s])
        out = self[s] = row.tolist()
        return out


def _heuristic_rows(
    pb: Problem, heuristic: str, weights: tuple[float, float, float], basic_cost: float, table: np.ndarray | None, D: int
) -> _Rows:
    """The heuristic by spatial state (row) and informative manoeuvres still to sail (column, 0..``D``): "admissible",
    the relaxed problem's cost to go (:func:`relaxed_table`, or ``table``) floored to whole ``basic_cost``; "thesis",
    (8.9)-(8.12): ``weights`` (a1, a2, a3) times the distance to the nearest goal, its heading change and the
    manoeuvres left."""
    K, nj, ns = pb.n_head, pb.nj, len(pb.succ)
    if heuristic == "admissible":
        tab = relaxed_table(pb) if table is None else table
        return _Rows(tab, lambda row: np.floor(row / basic_cost + 1e-6) * basic_cost)  # drop the EPS residue
    if heuristic != "thesis":
        raise ValueError(f"heuristic must be 'admissible' or 'thesis', got {heuristic!r}")
    a1, a2, a3 = weights
    sp = np.arange(ns)
    cell = sp // K
    p = np.column_stack([cell // nj, cell % nj]).astype(float) * pb.res
    gs = np.asarray(pb.goal_spatial)
    goal_p = np.column_stack([(gs // K) // nj, (gs // K) % nj]).astype(float) * pb.res
    d = np.min(np.hypot(p[:, None, 0] - goal_p[None, :, 0], p[:, None, 1] - goal_p[None, :, 1]), axis=1)
    if len(set((gs % K).tolist())) == K:
        dpsi = np.zeros(ns)
    else:
        dh = np.abs(((sp[:, None] % K) - (gs[None, :] % K) + K // 2) % K - K // 2)
        dpsi = dh.min(axis=1) * 2 * np.pi / K
    return _Rows((a1 * d + a2 * dpsi)[:, None] + a3 * np.arange(D + 1)[None, :])  # (8.9)-(8.12)


def _path(parent: dict[int, tuple[int, int]], found_key: int, G: int) -> tuple[list[int], list[int]]:
    """The moves and spatial states from the start to ``found_key``, followed back through ``parent``
    (key = spatial state x ``G`` + counter index)."""
    moves, spatial = [], [found_key // G]
    k = found_key
    while k in parent:
        k, m = parent[k]
        moves.append(m)
        spatial.append(k // G)
    moves.reverse()
    spatial.reverse()
    return moves, spatial


def _counter_tables(pb: Problem) -> tuple[list[int], int, int, list[int], list[list[bool]]]:
    """The counters of (8.3)-(8.5) packed into one index (:meth:`Problem.counter_index`): the strides,
    the number of indices ``G``, the index with every counter at its target, and per index the
    informative manoeuvres still to sail and which counters may still advance."""
    Q = len(pb.targets)
    radix, stride, G = pb.counter_index()
    full = sum(d * st for d, st in zip(pb.targets, stride))
    ci = np.arange(G)
    g_of = np.stack([(ci // stride[q]) % radix[q] for q in range(Q)], axis=1) if Q else np.zeros((G, 0), int)
    remaining = (np.asarray(pb.targets) - g_of).sum(axis=1).tolist() if Q else [0] * G
    can = [[bool(g_of[c, q] < pb.targets[q]) for q in range(Q)] for c in range(G)]
    return stride, G, full, remaining, can


def _unreachable(heuristic: str, h0: float, D: int, t0: float) -> SearchResult:
    """The result when the start's heuristic is infinite: the relaxed problem has no path, so none exists."""
    return SearchResult(
        False,
        [],
        [],
        float("inf"),
        0,
        1,
        time.perf_counter() - t0,
        heuristic,
        False,
        h0,
        f"no sequence of moves that uses all {D} informative manoeuvres reaches the goal, even with the "
        "counters pooled and in any order (the relaxed problem): some manoeuvre ends where the goal "
        "cannot be reached, or the water between them is too tight",
    )


def _not_found(
    expansions: int, max_expansions: int, held: int, max_states: int | None, dt: float, heuristic: str, h0: float, D: int
) -> SearchResult:
    """The result of a search that stopped without reaching the goal, with why: a limit (``held``
    states against ``max_states``) or every reachable state explored."""
    if expansions > max_expansions:
        why = "expansion limit reached"
    elif max_states is not None and held > max_states:
        why = f"memory limit reached ({held:,} states held; raise --max-memory or plan fewer manoeuvres)"
    else:
        why = "every reachable state was explored"
    return SearchResult(
        False,
        [],
        [],
        float("inf"),
        expansions,
        held,
        dt,
        heuristic,
        False,
        h0,
        f"no sequence of moves meets all counters and reaches the goal ({why})",
        {"D": D},
    )


def search(
    pb: Problem,
    heuristic: str = "admissible",
    weights: tuple[float, float, float] = (1.0, 1.0, 1.0),
    basic_cost: float = 1.0,
    max_expansions: int = 50_000_000,
    table: np.ndarray | None = None,
    max_states: int | None = None,
) -> SearchResult:
    """A* with a binary heap (heapq), packed integer keys and a closed set; stops when it holds
    more than ``max_states`` states (the memory budget)."""
    t0 = time.perf_counter()
    stride, G, full, remaining, can = _counter_tables(pb)
    D = int(sum(pb.targets))
    goal_set = set(pb.goal_spatial)

    htab = _heuristic_rows(pb, heuristic, weights, basic_cost, table, D)

    s0 = pb.start_spatial
    k0 = s0 * G
    h0 = htab[s0][remaining[0]]
    if not np.isfinite(h0):
        return _unreachable(heuristic, h0, D, t0)
    gcost = {k0: 0.0}
    parent: dict[int, tuple[int, int]] = {}
    closed: set[int] = set()
    tie = 0
    heap = [(h0, remaining[0], 0, k0)]
    expansions = 0
    found_key = -1
    succ = pb.succ
    inf = float("inf")
    while heap:
        f, _, _, key = heapq.heappop(heap)
        if key in closed:
            continue
        closed.add(key)
        s, c = divmod(key, G)
        if c == full and s in goal_set:
            found_key = key
            break
        expansions += 1
        if expansions > max_expansions or (max_states is not None and len(gcost) > max_states):
            break
        gk = gcost[key]
        cr = can[c]
        for m, s2, q, cost in succ[s]:
            if q >= 0:
                if not cr[q]:
                    continue
                c2 = c + stride[q]
            else:
                c2 = c
            k2 = s2 * G + c2
            if k2 in closed:
                continue
            g2 = gk + cost
            old = gcost.get(k2)
            if old is not None and old <= g2:
                continue
            h2 = htab[s2][remaining[c2]]
            if h2 == inf:
                continue
            gcost[k2] = g2
            parent[k2] = (key, m)
            tie -= 1  # LIFO among equals: dive along zero-cost plateaus
            heapq.heappush(heap, (g2 + h2, remaining[c2], tie, k2))
    dt = time.perf_counter() - t0
    if found_key < 0:
        return _not_found(expansions, max_expansions, len(gcost), max_states, dt, heuristic, h0, D)
    moves, spatial = _path(parent, found_key, G)
    return SearchResult(
        True, moves, spatial, gcost[found_key], expansions, len(gcost), dt, heuristic, heuristic == "admissible", h0
    )
