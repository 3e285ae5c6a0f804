"""Which mixes of the designed manoeuvres the water holds together (maps.sailable, issue 28): in
confined water each manoeuvre may fit alone while the mix cannot be sailed start to goal."""

from __future__ import annotations

import numpy as np

from maps.astar import Problem, Successors, search
from maps.sailable import best_mix, sailable_mixes


def _problem(edges: list[tuple[int, int, int]], n: int, targets: list[int], goal: int) -> Problem:
    """A lattice of ``n`` spatial states in a row (one heading); ``edges``: (from, to, counter or -1)."""
    e = np.array(edges, np.int64)
    succ = Successors.from_edges(n, e[:, 0], np.arange(len(e)), e[:, 1], e[:, 2], np.where(e[:, 2] < 0, 1.0, 0.0))
    return Problem(1, n, 1, targets, succ, 0, [goal])


def test_two_manoeuvres_that_each_fit_but_not_one_after_the_other():
    """A turn (counter 0) and a stop (counter 1) each have a placement between start and goal, but
    the turn ends where no stop can follow and the stop where no turn can: the lattice search finds
    no plan for one of each, and the sailable mixes are one or the other (the turn, 613 s, sails
    more of the designed time than the stop, 350 s)."""
    pb = _problem([(0, 1, -1), (1, 2, 0), (2, 5, -1), (1, 3, 1), (3, 5, -1), (3, 4, -1)], 6, [1, 1], 5)
    assert not search(pb).found
    mixes = sailable_mixes(pb)
    assert mixes == {(1, 0), (0, 1)}
    assert best_mix(mixes, [613.0, 350.0]) == (1, 0)
    assert best_mix(mixes, [300.0, 350.0]) == (0, 1)


def test_every_count_up_to_the_target_is_a_mix_and_the_whole_mix_when_the_water_holds_it():
    """Two turns then a stop along one path (a loop lets the turn repeat): every vector the path
    allows, the designed (2, 1) among them; a state the goal cannot be reached from adds none."""
    pb = _problem([(0, 1, -1), (1, 1, 0), (1, 2, 1), (2, 3, -1), (1, 3, -1), (0, 4, 0)], 5, [2, 1], 3)
    assert search(pb).found
    assert sailable_mixes(pb) == {(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)}
    assert sailable_mixes(pb, max_states=3) is None  # undecided past the budget
    assert best_mix(sailable_mixes(pb), [600.0, 350.0]) == (2, 1)


def test_a_goal_out_of_reach_leaves_no_mix():
    pb = _problem([(0, 1, 0), (2, 3, -1)], 4, [1], 3)
    assert sailable_mixes(pb) == set()


def test_a_search_stopped_at_its_budget_is_said():
    """Past its state budget the search of the sailable mixes decides nothing: it leaves nothing out
    (None, not an empty verdict), and the fallback's note says the question was left undecided."""
    from types import SimpleNamespace

    from maps.planner import no_plan_note
    from maps.sailable import not_sailable_together

    pb = _problem([(0, 1, -1), (1, 2, 0), (2, 5, -1), (1, 3, 1), (3, 5, -1), (3, 4, -1)], 6, [1, 1], 5)
    lat = SimpleNamespace(last_problem=lambda: pb)
    assert not_sailable_together(lat, max_states=3) is None
    note = no_plan_note(SimpleNamespace(stats={"reason": "the goal cannot be reached"}), True)
    assert "not decided" in note and "2,000,000 lattice states" in note and "the goal cannot be reached" in note
    assert "not decided" not in no_plan_note(SimpleNamespace(stats={"reason": "x"}), False)


def test_a_manoeuvre_reached_only_through_another_fits_nowhere():
    """The map check asks for each manoeuvre a placement the ship reaches, and leaves for the goal, by
    repositioning moves alone: a stop (counter 1) placed only at the end of a turn (counter 0) is
    not counted as fitting, since the design may drop the turn (before, the turn counted as a way there)."""
    from types import SimpleNamespace

    from maps.chain import Lattice

    pb = _problem([(0, 1, -1), (1, 2, 0), (2, 3, 1), (3, 4, -1), (2, 4, -1), (1, 4, -1)], 5, [1, 1], 4)
    used = Lattice._usable_moves(SimpleNamespace(problem=lambda: pb))
    assert 1 in used and 2 not in used  # the turn fits, the stop (move 2) does not
