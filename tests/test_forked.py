"""maps.forked.map_halves: half of the items computed in a forked child, the results those of
computing every item here, in order, whatever happens to the child."""

from __future__ import annotations

import os

import numpy as np
import pytest

import maps.forked as forked
from tests.procs import children


def test_results_in_order_half_from_a_child():
    pids = forked.map_halves(lambda x: (x, os.getpid()), list(range(11)))
    assert [x for x, _ in pids] == list(range(11))
    here = {p for i, (_, p) in enumerate(pids) if i % 2 == 0}
    there = {p for i, (_, p) in enumerate(pids) if i % 2 == 1}
    assert here == {os.getpid()} and len(there) == 1 and there != here


def test_arrays_come_back_equal_and_large_results_do_not_block():
    items = list(range(10))
    out = forked.map_halves(lambda k: np.full((300, 300), k, float), items)  # 7 MB through the pipe
    assert all(np.array_equal(a, np.full((300, 300), k, float)) for k, a in zip(items, out))


def test_a_failing_child_is_recomputed_here():
    parent = os.getpid()

    def only_here(x):
        if os.getpid() != parent:
            raise RuntimeError("not in the child")
        return x * x

    assert forked.map_halves(only_here, list(range(9))) == [x * x for x in range(9)]


def test_an_error_here_is_raised_and_the_child_reaped():
    parent = os.getpid()

    def fails_here(x):
        if os.getpid() == parent and x == 4:
            raise ValueError("bad item 4")
        return x

    before = children()
    with pytest.raises(ValueError, match="bad item 4"):
        forked.map_halves(fails_here, list(range(10)))
    assert children() <= before


def test_few_items_are_not_forked():
    assert {p for p in forked.map_halves(lambda x: os.getpid(), [1, 2, 3])} == {os.getpid()}
