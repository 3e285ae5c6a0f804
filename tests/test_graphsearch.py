"""maps.graphsearch against scipy.sparse.csgraph, which the planner used before: the same distances
bit for bit (so the same A* heuristic table and the same plans) and the same reachable states, on
the bundled map's lattice and on random graphs whose weights tie; and the planner no longer
imports scipy to get them."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, dijkstra

from maps import astar, graphsearch
from maps.graphsearch import Rows, distances, reached
from maps.sailable import goal_reachable

# weights that tie (1.0, 1.5, EPS) and ones whose sums round (0.1, 0.2, 0.3, 0.7)
WEIGHTS = np.array([astar.EPS, 1.0, 1.5, 0.1, 0.2, 0.3, 0.7])


def _scipy_relaxed_table(pb: astar.Problem) -> np.ndarray:
    """maps.astar.relaxed_table as it was: one Dijkstra over the whole (state, r) graph, reversed."""
    ns = pb.ni * pb.nj * pb.n_head
    D = int(sum(pb.targets))
    src, dst, qq, cost = astar.edges(pb)
    w0 = np.where(cost > 0, cost, astar.EPS)
    r = np.arange(D + 1)
    basic, info = qq < 0, qq >= 0
    rows = np.concatenate([(src[basic, None] * (D + 1) + r).ravel(), (src[info, None] * (D + 1) + r[1:]).ravel()])
    cols = np.concatenate([(dst[basic, None] * (D + 1) + r).ravel(), (dst[info, None] * (D + 1) + r[1:] - 1).ravel()])
    w = np.concatenate([np.repeat(w0[basic], D + 1), np.repeat(w0[info], D)])
    n = ns * (D + 1)
    order = np.lexsort((w, rows, cols))  # duplicate edges would be summed by csr_matrix: keep the cheapest
    keep = np.ones(len(w), bool)
    keep[1:] = (np.diff(cols[order]) != 0) | (np.diff(rows[order]) != 0)
    sel = order[keep]
    g = csr_matrix((w[sel], (cols[sel], rows[sel])), shape=(n, n))
    dist = dijkstra(g, directed=True, indices=[s * (D + 1) for s in pb.goal_spatial], min_only=True)
    return dist.reshape(ns, D + 1)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool((a.view(np.int64) == b.view(np.int64)).all())


def _random_graph(rng: np.random.Generator, n: int, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """m edges among n states, no self-loops, no repeated (from, to) pair (csr_matrix would sum them)."""
    frm, to = rng.integers(0, n, m), rng.integers(0, n, m)
    pairs = np.unique(np.stack([frm, to], 1)[frm != to], axis=0)
    pairs = pairs[rng.permutation(len(pairs))]
    return pairs[:, 0], pairs[:, 1], rng.choice(WEIGHTS, len(pairs))


@pytest.mark.parametrize("seed", range(8))
def test_distances_are_dijkstras_bit_for_bit_on_random_graphs_with_ties(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 400))
    frm, to, w = _random_graph(rng, n, int(rng.integers(n, 6 * n)))
    sources = rng.choice(n, int(rng.integers(1, 5)), replace=False)
    n += 10  # ten states no edge touches: out of reach (inf)
    d = np.full(n, np.inf)
    d[sources] = 0.0
    ours = distances(Rows(n, frm, to, w), d)
    ref = dijkstra(csr_matrix((w, (frm, to)), shape=(n, n)), directed=True, indices=sources, min_only=True)
    assert np.isinf(ours[-10:]).all() and np.isfinite(ours).sum() > 10
    assert _same_bits(ours, ref)


@pytest.mark.parametrize("seed", range(4))
def test_dijkstras_order_gives_the_same_bits_as_the_sweeps(seed, monkeypatch):
    """The heap-ordered finish (taken when labels keep falling) alone, from the first sweep on."""
    monkeypatch.setattr(graphsearch, "WORK_LIMIT", 0)
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 400))
    frm, to, w = _random_graph(rng, n, int(rng.integers(n, 6 * n)))
    sources = rng.choice(n, int(rng.integers(1, 5)), replace=False)
    d = np.full(n, np.inf)
    d[sources] = 0.0
    ref = dijkstra(csr_matrix((w, (frm, to)), shape=(n, n)), directed=True, indices=sources, min_only=True)
    assert _same_bits(distances(Rows(n, frm, to, w), d), ref)


def test_labels_that_keep_falling_are_finished_in_dijkstras_order(monkeypatch):
    """A chain with a costly shortcut from the source to each state: every state falls once per
    sweep, n sweeps of n edges (41 s for 20,000 states without the switch); the search hands over
    to the heap and still gives scipy's values."""
    used = []
    heap = graphsearch._dijkstra_from
    monkeypatch.setattr(graphsearch, "_dijkstra_from", lambda g, d: used.append(1) or heap(g, d))
    n = 5000
    i = np.arange(1, n)
    frm, to, w = np.r_[i - 1, np.zeros(n - 2, int)], np.r_[i, i[1:]], np.r_[np.ones(n - 1), 3.0 * i[1:]]
    d = np.full(n, np.inf)
    d[0] = 0.0
    ours = distances(Rows(n, frm, to, w), d)
    assert used and _same_bits(ours, np.arange(n, dtype=float))


@pytest.mark.parametrize("limit", [10, 0])
def test_zero_weights_and_repeated_edges_keep_the_cheapest(limit, monkeypatch):
    """Zero-weight edges (cycles of them too) are edges of no cost, and of repeated (from, to)
    edges the cheapest counts: scipy's values on the graph holding only the cheapest of each."""
    monkeypatch.setattr(graphsearch, "WORK_LIMIT", limit)
    rng = np.random.default_rng(7)
    n = 300
    frm, to = rng.integers(0, n, 2000), rng.integers(0, n, 2000)
    w = rng.choice(np.r_[0.0, WEIGHTS], 2000)
    order = np.lexsort((w, to, frm))
    first = np.r_[True, (np.diff(frm[order]) != 0) | (np.diff(to[order]) != 0)]
    sel = order[first]
    g = csr_matrix((w[sel], (frm[sel], to[sel])), shape=(n, n))
    assert g.nnz == len(sel) and (w[sel] == 0).sum() > 100 and len(sel) < len(w)
    d = np.full(n, np.inf)
    d[:2] = 0.0
    assert _same_bits(distances(Rows(n, frm, to, w), d), dijkstra(g, directed=True, indices=[0, 1], min_only=True))


def test_graphs_of_more_states_than_16_bits_hold():
    """Rows sorts the states' numbers as 16-bit integers (radix) only while they fit: the open sea at
    800 m has 90,000 states. Edges given ungrouped, reaching states past 65,535."""
    rng = np.random.default_rng(11)
    n = 70_000
    frm, to, w = _random_graph(rng, n, 4 * n)
    d = np.full(n, np.inf)
    d[[0, n - 1]] = 0.0
    ref = dijkstra(csr_matrix((w, (frm, to)), shape=(n, n)), directed=True, indices=[0, n - 1], min_only=True)
    assert np.isfinite(ref[1 << 16 :]).sum() > 1000
    assert _same_bits(distances(Rows(n, frm, to, w), d), ref)
    assert np.array_equal(reached(Rows(n, frm, to), [0, n - 1]), np.isfinite(ref))


@pytest.mark.parametrize("seed", range(4))
def test_distances_from_starting_costs_are_those_through_a_source_before_them(seed):
    """Started from a cost per state (as each layer of the relaxed table is): the values of Dijkstra
    from one extra source with an edge of that cost to each of them."""
    rng = np.random.default_rng(100 + seed)
    n = 300
    frm, to, w = _random_graph(rng, n, 900)
    starts = rng.choice(n, 20, replace=False)
    cost0 = rng.choice(WEIGHTS, 20) * rng.integers(1, 9, 20)
    d = np.full(n, np.inf)
    d[starts] = cost0
    ours = distances(Rows(n, frm, to, w), d)
    g = csr_matrix((np.r_[w, cost0], (np.r_[frm, np.full(20, n)], np.r_[to, starts])), shape=(n + 1, n + 1))
    ref = dijkstra(g, directed=True, indices=n)[:n]
    assert _same_bits(ours, ref)


@pytest.mark.parametrize("seed", range(4))
def test_reached_is_the_union_of_breadth_first_searches(seed):
    rng = np.random.default_rng(200 + seed)
    n = 500
    frm, to, _ = _random_graph(rng, n, 700)
    sources = rng.choice(n, 3, replace=False)
    g = csr_matrix((np.ones(len(frm)), (frm, to)), shape=(n, n))
    ref = np.zeros(n, bool)
    for s in sources:
        ref[breadth_first_order(g, s, directed=True, return_predecessors=False)] = True
    got = reached(Rows(n, frm, to), sources)
    assert 0 < got.sum() < n and np.array_equal(got, ref)


def _random_problem(rng: np.random.Generator) -> astar.Problem:
    """A small counter-augmented lattice problem with tied costs (1, 1.5, 0 for the informative moves)."""
    ni, nj, K = 6, 7, 4
    ns = ni * nj * K
    succ: list[list[tuple[int, int, int, float]]] = [[] for _ in range(ns)]
    for s in range(ns):
        for mi in range(int(rng.integers(0, 5))):
            q = int(rng.integers(-1, 3))
            succ[s].append((mi, int(rng.integers(0, ns)), q, 0.0 if q >= 0 else float(rng.choice([1.0, 1.5]))))
    goals = [int(g) for g in rng.choice(ns, 3, replace=False)]
    return astar.Problem(ni, nj, K, [2, 1, 1], succ, int(rng.integers(0, ns)), goals)


@pytest.mark.parametrize("seed", range(6))
def test_relaxed_table_and_plan_as_with_scipy_on_random_lattices(seed):
    pb = _random_problem(np.random.default_rng(300 + seed))
    ours, ref = astar.relaxed_table(pb), _scipy_relaxed_table(pb)
    assert np.isfinite(ours).any() and np.isinf(ours).any()
    assert _same_bits(ours, ref)
    a, b = astar.search(pb, table=ours), astar.search(pb, table=ref)
    assert (a.found, a.moves, a.spatial, a.cost) == (b.found, b.moves, b.spatial, b.cost)


@pytest.fixture(scope="module")
def bundled_problem() -> astar.Problem:
    from maps.chain import PlanOptions, build_lattice
    from maps.geo import load_map
    from maps.motionset import resolve_primitives
    from primitives.ship import load_profile

    prof = load_profile("full-scale")
    counts = {"steep_zigzag_surge": 2, "wide_zigzag_surge": 2, "wide_zigzag_sway": 1}
    sea = load_map(None, draught_m=prof.draught_m)
    lat = build_lattice(sea, prof, resolve_primitives(prof, counts, None), counts, options=PlanOptions())
    return lat.problem()


def test_relaxed_table_reachability_and_plan_as_with_scipy_on_the_bundled_map(bundled_problem):
    pb = bundled_problem
    ours, ref = astar.relaxed_table(pb), _scipy_relaxed_table(pb)
    assert len(pb.succ) > 10_000 and np.isfinite(ours).sum() > 10_000
    assert _same_bits(ours, ref)
    a, b = astar.search(pb, table=ours), astar.search(pb, table=ref)
    assert a.found and (a.moves, a.spatial, a.cost) == (b.moves, b.spatial, b.cost)

    sc = pb.succ
    n = len(sc)
    gt = csr_matrix((np.ones(len(sc.dst)), (np.asarray(sc.dst), sc.sources())), shape=(n, n))
    back = np.zeros(n, bool)
    for goal in pb.goal_spatial:
        back[breadth_first_order(gt, goal, directed=True, return_predecessors=False)] = True
    assert np.array_equal(goal_reachable(pb), back)


@pytest.mark.parametrize("seed", range(6))
def test_usable_moves_as_with_scipy_on_random_lattices(seed):
    """Lattice._usable_moves (the map check's moves with a placement reached from the start and
    leaving for a goal by basic moves) against main's two scipy breadth-first searches, on lattices
    where some moves are usable and some not (on the bundled map every move is)."""
    from types import SimpleNamespace

    from maps.chain import Lattice

    rng = np.random.default_rng(400 + seed)
    n, m = 150, 600  # moves mostly forward along a row of states: those before the start or past the goals unusable
    src = rng.integers(0, n, m)
    dst = np.clip(src + rng.integers(-2, 8, m), 0, n - 1)
    q = np.where(rng.random(m) < 0.3, rng.integers(0, 2, m), -1)
    sc = astar.Successors.from_edges(n, src, np.arange(m), dst, q, np.where(q < 0, 1.0, 0.0))
    pb = astar.Problem(1, n, 1, [1, 1], sc, int(rng.integers(20, 40)), [int(g) for g in rng.integers(100, 130, 2)])
    e = np.column_stack([sc.sources(), sc.dst, sc.move]).astype(np.int64)
    basic = np.asarray(sc.counter) < 0
    g = csr_matrix((np.ones(int(basic.sum())), (e[basic, 0], e[basic, 1])), shape=(n, n))
    fwd = np.zeros(n, bool)
    fwd[breadth_first_order(g, pb.start_spatial, directed=True, return_predecessors=False)] = True
    back = np.zeros(n, bool)
    for goal in pb.goal_spatial:
        back[breadth_first_order(g.T.tocsr(), goal, directed=True, return_predecessors=False)] = True
    ok = fwd[e[:, 0]] & back[e[:, 1]]
    assert ok.any() and not ok.all()
    assert Lattice._usable_moves(SimpleNamespace(problem=lambda: pb)) == set(np.unique(e[ok, 2]).tolist())


def test_the_planner_imports_no_scipy():
    """scipy's sparse base cost 0.39-0.45 s of CPU in every plan-trial for these searches alone."""
    code = "import sys, maps.planner, maps.sailable, maps.chain; print(sorted(m for m in sys.modules if m.startswith('scipy')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
