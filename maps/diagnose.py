"""Why no plan was found, and what would help (used by the planner when A* fails)."""

from __future__ import annotations

from collections import deque

from maps.astar import Problem, SearchResult
from maps.lattice import Move


def _reachable(pb: Problem) -> set[int]:
    """Spatial states reachable from the start with any moves, ignoring the counters."""
    seen = {pb.start_spatial}
    todo = deque([pb.start_spatial])
    while todo:
        s = todo.popleft()
        for _, s2, _, _ in pb.succ[s]:
            if s2 not in seen:
                seen.add(s2)
                todo.append(s2)
    return seen


def explain_failure(pb: Problem, moves: list[Move], counters: list[str], result: SearchResult) -> tuple[str, list[str]]:
    """(one-line reason, list of suggestions) for a failed search."""
    placements = [0] * len(moves)
    for lst in pb.succ:
        for m, _, _, _ in lst:
            placements[m] += 1
    win = f"{pb.ni} x {pb.nj} points of {pb.res:g} m"
    for mi, m in enumerate(moves):
        if m.counter >= 0 and pb.targets[m.counter] > 0 and placements[mi] == 0:
            b = m.prims[0].footprint.bounds
            return (
                f"primitive {m.name} fits nowhere in the planning window ({win}): it needs "
                f"{b[2] - b[0]:.0f} x {b[3] - b[1]:.0f} m of water plus the margin",
                [
                    f"a smaller or shorter version of {m.name}",
                    "a larger area (trial_area or a coarser --resolution)",
                    "a smaller --margin",
                ],
            )
    reach = _reachable(pb)
    if not any(g in reach for g in pb.goal_spatial):
        few = (
            f": from the start the moves reach only {len(reach)} lattice states (the water round the start is too tight for them)"
            if len(reach) < 0.01 * len(pb.succ)
            else ""
        )
        more = "more headings (--headings 16: shorter turns)" if pb.n_head < 16 else "more headings"
        return (
            "the goal cannot be reached from the start with these moves, even ignoring the counters" + few,
            [
                "choose a goal in water connected to the start",
                more,
                "a smaller --margin",
                "a finer --resolution",
                "shorter run-ins (--run-in)",
            ],
        )
    for mi, m in enumerate(moves):
        if m.counter < 0 or pb.targets[m.counter] == 0:
            continue
        if not any(s in reach for s, lst in enumerate(pb.succ) for mm, _, _, _ in lst if mm == mi):
            return (
                f"counter of {counters[m.counter]} (target {pb.targets[m.counter]}) cannot be met: "
                f"{m.name} fits nowhere reachable from the start",
                [f"lower the count of {counters[m.counter]}", "a larger area", f"a smaller version of {m.name}"],
            )
    if result.expansions == 0 and result.reason:  # refused before the search: the relaxed problem has no solution
        return (
            result.reason,
            ["lower counts (a shorter --trial-length)", "a larger area", "shorter primitives (split them: --split)"],
        )
    if result.expansions >= 0 and "limit" in result.reason:
        other = (
            "--heuristic thesis (greedy: a plan found fast where long transits leave the admissible bound some moves "
            "short and every order of the manoeuvres along the way must be tried; not certified optimal)"
            if result.heuristic == "admissible"
            else "the admissible heuristic"
        )
        return (result.reason, ["lower counts", other, "a coarser --resolution"])
    tg = ", ".join(f"{n}={d}" for n, d in zip(counters, pb.targets))
    return (
        f"the counters ({tg}) cannot all be met on the way from start to goal: "
        f"every reachable combination was explored ({result.expansions} expansions)",
        ["lower counts", "a larger area", "shorter primitives (split them: --split)"],
    )
