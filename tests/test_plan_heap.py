"""plan-trial plans with the imported heap frozen (no full collection walks the imports again) and
gives the collector back as it was to an in-process caller, whether the plan succeeds or fails."""

from __future__ import annotations

import gc

import pytest

from cli.plan_cmd import _heap_frozen


def test_heap_frozen_while_planning_and_given_back_after():
    seen = []

    @_heap_frozen
    def work(x: int) -> int:
        seen.append(gc.get_freeze_count())
        return x + 1

    gc.unfreeze()  # a caller that froze nothing
    assert work(1) == 2
    assert seen[0] > 0  # what was alive at the start is out of the collector's sight
    assert gc.get_freeze_count() == 0


def test_a_callers_own_frozen_objects_stay_frozen(monkeypatch):
    """Neither frozen again nor given back. Asserted on the calls, not on the frozen count: a frozen object
    another thread lets go of leaves the permanent generation (CI saw the count fall by 2 within the test)."""

    @_heap_frozen
    def work() -> int:
        return gc.get_freeze_count()

    gc.unfreeze()
    gc.freeze()
    try:
        calls: list[str] = []
        monkeypatch.setattr(gc, "freeze", lambda: calls.append("freeze"))
        monkeypatch.setattr(gc, "unfreeze", lambda: calls.append("unfreeze"))
        assert work() > 0
        assert calls == [] and gc.get_freeze_count() > 0
    finally:
        monkeypatch.undo()
        gc.unfreeze()


def test_heap_given_back_when_planning_fails():
    @_heap_frozen
    def fail() -> None:
        raise ValueError("refused")

    gc.unfreeze()
    with pytest.raises(ValueError, match="refused"):
        fail()
    assert gc.get_freeze_count() == 0
