"""primitives.threads: the thread count follows OMP_NUM_THREADS (the setting the engines' workers
set to one), and map_in_threads gives the list comprehension's results, runs items at once on
several threads, leaves no thread running after it returns or raises, and raises the first
failed item's error only once every thread has stopped."""

from __future__ import annotations

import contextvars
import threading
import time

import numpy as np
import pytest

from primitives import threads


@pytest.mark.parametrize(
    "value,expected",
    [("3", 3), ("1", 1), ("2,1", 2), (" 2 ", 2), ("64", threads.MAX_THREADS)],
)
def test_the_count_follows_omp_num_threads(monkeypatch, value, expected):
    monkeypatch.setenv("OMP_NUM_THREADS", value)
    assert threads.count() == expected


@pytest.mark.parametrize("value", [None, "0", "-2", "abc", "", "²"])  # "²": str.isdigit, not int
def test_without_a_usable_setting_the_count_is_the_cpus_this_process_may_use(monkeypatch, value):
    monkeypatch.setattr(threads, "usable_cpus", lambda: 3)
    if value is None:
        monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    else:
        monkeypatch.setenv("OMP_NUM_THREADS", value)
    assert threads.count() == 3
    monkeypatch.setattr(threads, "usable_cpus", lambda: 40)
    assert threads.count() == threads.MAX_THREADS


@pytest.mark.parametrize("k", [1, 2, 3, 8])
def test_results_are_the_list_comprehensions_in_item_order(k):
    items = list(range(23))
    assert threads.map_in_threads(lambda x: x * x - 1, items, k) == [x * x - 1 for x in items]
    assert threads.map_in_threads(lambda x: x, [], k) == []


def test_items_run_at_once_on_several_threads_and_none_outlives_the_call():
    before = threading.active_count()
    barrier = threading.Barrier(3, timeout=30)  # passes only when three items run at the same time
    seen = []

    def fn(x):
        seen.append(threading.get_ident())
        if x < 3:
            barrier.wait()
        return x

    assert threads.map_in_threads(fn, list(range(9)), 3) == list(range(9))
    assert len(set(seen)) == 3
    assert threading.active_count() == before


def test_the_count_decides_the_threads_by_default(monkeypatch):
    seen = set()

    def fn(x):
        seen.add(threading.get_ident())
        time.sleep(0.01)
        return x

    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    threads.map_in_threads(fn, list(range(6)))
    assert seen == {threading.get_ident()}  # one thread: this one, no other started


def test_the_first_failed_items_error_once_every_thread_has_stopped():
    before = threading.active_count()
    finished = []

    def fn(x):
        if x in (1, 4):
            time.sleep(0.05 if x == 1 else 0.0)
            raise ValueError(f"item {x}")
        time.sleep(0.2 if x == 0 else 0.0)  # still running when the errors arrive
        finished.append(x)
        return x

    with pytest.raises(ValueError, match="item 1"):
        threads.map_in_threads(fn, list(range(40)), 3)
    assert 0 in finished  # the item running beside the failures finished before the error was raised
    assert len(finished) < 38  # no thread went on taking items after the errors
    assert threading.active_count() == before


def test_a_ctrl_c_in_the_callers_thread_stops_the_others_and_is_raised():
    main = threading.get_ident()
    taken = []

    def fn(x):
        taken.append(x)
        if threading.get_ident() == main:
            raise KeyboardInterrupt
        time.sleep(0.05)
        if x == 1:
            raise ValueError("after the interrupt")
        return x

    with pytest.raises(KeyboardInterrupt):
        threads.map_in_threads(fn, list(range(50)), 2)
    assert len(taken) <= 3


_HINT: contextvars.ContextVar[str] = contextvars.ContextVar("hint", default="unset")


def test_each_thread_runs_in_a_copy_of_the_callers_context():
    """numpy's error state and primitives.jitloop.job's hint are context variables: a thread that
    started without the caller's context would warn where the caller silenced numpy, or lose the hint."""
    barrier = threading.Barrier(2, timeout=30)

    def fn(x):
        if x < 2:
            barrier.wait()  # the first two items run at once: one of them in the other thread
        return _HINT.get(), np.geterr()["divide"], threading.get_ident()

    token = _HINT.set("caller's")
    try:
        with np.errstate(divide="raise"):
            out = threads.map_in_threads(fn, range(8), 2)
    finally:
        _HINT.reset(token)
    assert {(h, d) for h, d, _ in out} == {("caller's", "raise")}
    assert len({t for *_, t in out}) == 2
