"""The design's bits do not depend on the BLAS thread count, so ``plan-trial`` gives the same plan.json whatever
the state of the user's caches.

scipy's SLSQP (the design's non-convex step) rounds differently on one and two OpenBLAS threads: before stop 59,
a first design kept in the move cache by a run under ``OPENBLAS_NUM_THREADS=1`` (the benchmarks' setting) had
weights 1e-13 from those a two-thread run made, and every later run of that cache planned with them. Each
process here runs with the thread count its environment gives (as two users, or a benchmark and a user, do).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
START = "2026-06-01T08:00:00Z"
TIMINGS = {"plan_time_s", "expansions_per_s", "setup_time_s", "design_time_s", "total_time_s", "search_s"}

# the default ship's first design (the drawer's early design: maps.librarycache.kept_first_design, no cache),
# its weights and criterion value printed bit for bit
_FIRST_DESIGN = """
from maps.librarycache import kept_first_design
from primitives.ship import load_profile
first = kept_first_design(load_profile("full-scale"), criterion="D", mean_subtraction="complete", trial_length_s=None, seed=0)
print(first.baseline.hex(), *(w.hex() for w in first.design.design.weights.values()))
"""

# one_blas_thread's controller made before scipy's BLAS is loaded, then asked again after: every library at one thread
_LATER_LIBRARY = """
from threadpoolctl import threadpool_info
from primitives.threads import one_blas_thread
with one_blas_thread():
    pass
import scipy.optimize  # noqa: F401  loads scipy's own OpenBLAS
with one_blas_thread():
    print(*sorted(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
"""


def _python(code: str, threads: int, **env: str) -> str:
    """``code``'s output in a fresh interpreter whose BLAS and OpenMP start with ``threads`` threads."""
    n = str(threads)
    run_env = dict(os.environ, PYTHONPATH=str(ROOT), SHIPTRIAL_CACHE_DIR="", OPENBLAS_NUM_THREADS=n, OMP_NUM_THREADS=n)
    run = subprocess.run([sys.executable, "-c", code], env=run_env | env, capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def test_first_design_has_the_same_bits_on_one_and_two_blas_threads():
    """Fails when the design's SLSQP runs on the thread count it finds (mutant: ``minimize_slsqp`` without
    ``one_blas_thread``): the weights then differ from their 12th digit on."""
    one, two = (_python(_FIRST_DESIGN, n).split() for n in (1, 2))
    assert len(one) > 3 and one == two  # the criterion value and every weight


# a rudder ship's LQR autopilot (maps.autopilot._Rudder: scipy.linalg.solve_discrete_are, not under one_blas_thread)
_AUTOPILOT_GAIN = """
from maps.autopilot import _Rudder
from primitives.ship import load_profile
rudder = _Rudder(load_profile("kvlcc2"))
print(*(float(k).hex() for k in rudder.K), float(rudder.r_lim).hex())  # the gain and the yaw-rate limit it steers to
"""


def test_rudder_autopilot_gain_has_the_same_bits_on_one_and_two_blas_threads():
    """The autopilot's Riccati solution is left on the thread count it finds (3 states: too small for OpenBLAS to
    split): its gain, which every rudder ship's moves are simulated with, must still not depend on it. Fails if
    the autopilot's problem grows into sizes OpenBLAS threads; then put it under ``one_blas_thread``."""
    one, two = (_python(_AUTOPILOT_GAIN, n).split() for n in (1, 2))
    assert len(one) == 4 and one == two


def test_one_blas_thread_limits_a_blas_loaded_after_its_first_use():
    """Fails when the limiter keeps the controller it made first (mutant: no ``len(sys.modules)`` check): scipy's
    OpenBLAS, loaded after, then runs on its two threads."""
    assert _python(_LATER_LIBRARY, 2).split() == ["1", "1"]


def _plan_json(out: Path, cache: str, threads: int, *args: str) -> dict:
    code = "import sys; from cli.app import plan_main; sys.argv[0] = 'plan-trial'; plan_main()"
    argv = ["--out", str(out), "--start-time", START, *args]
    _python(f"import sys; sys.argv[1:] = {argv!r}; {code}", threads, SHIPTRIAL_CACHE_DIR=cache)

    def untimed(doc):
        if isinstance(doc, dict):
            return {k: untimed(v) for k, v in doc.items() if k not in TIMINGS}
        return [untimed(v) for v in doc] if isinstance(doc, list) else doc

    return untimed(json.loads((out / "plan.json").read_text()))


@pytest.mark.slow
def test_plan_json_identical_whatever_the_caches(tmp_path):
    """The default ``plan-trial`` with no caches (two threads), then with a cache filled by a run on one thread
    (the benchmarks' setting), read by a plain run (the plan cache hit) and by ``--no-cache`` (the kept first
    design): plan.json the same but its timings, and every other file byte for byte. Fails on the code before
    stop 59 (the design's weights 1e-13 apart in the no-cache run)."""
    cache = str(tmp_path / "cache")
    runs = [("none", "", 2, ()), ("miss", cache, 1, ()), ("hit", cache, 2, ()), ("no-cache", cache, 2, ("--no-cache",))]
    docs = {name: _plan_json(tmp_path / name, c, n, *args) for name, c, n, args in runs}
    assert all(doc == docs["none"] for doc in docs.values())
    files = {name: {p.name: p.read_bytes() for p in (tmp_path / name).iterdir() if p.name != "plan.json"} for name, *_ in runs}
    assert len(files["none"]) > 5 and all(f == files["none"] for f in files.values())
