"""primitives.heap: glibc's thresholds set once (detect's no-change records reuse freed memory)."""

from __future__ import annotations

import platform

import pytest

from primitives import heap


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt thresholds are glibc's")
def test_glibc_thresholds_are_set_once() -> None:
    assert heap.keep_freed_memory() is True
    assert heap.keep_freed_memory() is True  # a second call is a no-op that says the same
