"""primitives.heap: glibc keeps freed memory in the processes the project owns (the engines' workers,
``shiptrial detect``), never in a library caller's unless asked; Dask's trim threshold is undone."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent  # this checkout's package, not an installed one


def _fresh(code: str, trim: str | None) -> list[str]:
    """``code``'s printed words in a fresh process (mallopt is process-wide) with MALLOC_TRIM_THRESHOLD_ ``trim``."""
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_TRIM_THRESHOLD_"}
    if trim is not None:
        env["MALLOC_TRIM_THRESHOLD_"] = trim
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout.split()


@pytest.mark.parametrize(
    "value,always,kept",
    [("65536", False, True), ("1000000", False, False), (None, False, False), (None, True, True), ("1000000", True, False)],
)
def test_only_dasks_default_or_an_owned_process_keeps_freed_memory(value, always, kept) -> None:
    """Dask's MALLOC_TRIM_THRESHOLD_=65536 is undone; a value the user chose is left alone, and so is
    none unless ``always`` (a process the project owns); a second call says the same (glibc only)."""
    got = _fresh(f"from primitives.heap import keep_freed_memory as k; print(k({always}), k({always}))", value)
    assert got == [str(kept and platform.libc_ver()[0] == "glibc")] * 2


def test_release_hands_free_heap_back() -> None:
    """release_freed_memory calls malloc_trim on glibc (True) and does nothing elsewhere (False)."""
    code = "import numpy as np; from primitives.heap import release_freed_memory as r; x = np.ones(1 << 24); del x; print(r())"
    assert _fresh(code, None) == [str(platform.libc_ver()[0] == "glibc")]
