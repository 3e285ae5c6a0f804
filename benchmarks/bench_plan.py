"""Benchmarks of the sea maps and the A* lattice planner (issue 4).

    python benchmarks/bench_plan.py [--repeat 5] [--five-repeat 3]

Cases (median of the repeats after one warm-up; ratio < 1 is within target):
* ``map_load``: load and project the bundled Helsinki map (target 0.5 s: "well under a second").
* ``scenario``: the section 9.4 scenario (three primitives used three times each, 4 headings,
  >= 35 x 44 lattice, full-scale ship) on Helsinki. Target 1 s for the search (A*, including
  the admissible cost-to-go table); the thesis reports about 40 s for a plain A*. The time of
  the whole ``plan_trial`` call (motion set, collision tables, search, re-simulation) is
  printed beside it.
* ``five_by_five``: five primitives used five times each (the thesis's 19 M-state case; here
  35 x 44 x 4 x 6^5 lattice states): search target 30 s, peak memory < 2 GiB. Runs in a fresh
  subprocess so its peak resident memory (resource.getrusage) is its own.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

FIVE = ["steep_zigzag_surge", "wide_zigzag_surge", "wide_zigzag_sway", "tau17", "tau19"]


def _plan(counts: dict[str, int] | None, heuristic: str = "admissible") -> dict:
    from maps.geo import load_map
    from maps.planner import plan_trial
    from primitives.ship import load_profile

    prof = load_profile("full-scale")
    sea = load_map(draught_m=prof.draught_m)
    t0 = time.perf_counter()
    plan = plan_trial(sea, profile=prof, counts=counts, heuristic=heuristic)
    total = time.perf_counter() - t0
    st = plan.stats
    return {"total_s": total, "search_s": st["plan_time_s"], "setup_s": st["setup_time_s"], "expansions": st["expansions"],
            "states_visited": st["states_visited"], "expansions_per_s": st["expansions_per_s"], "feasible": plan.feasible,
            "optimal": plan.optimal, "counts_ok": plan.counts == plan.targets, "basic_moves": plan.basic_moves,
            "lattice_states": st["lattice"]["states"], "min_clearance_m": plan.min_clearance_m}


def _median(rows: list[dict], key: str) -> float:
    return statistics.median(r[key] for r in rows)


def bench_map_load(repeat: int) -> dict:
    from maps.geo import load_map

    load_map()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        load_map(draught_m=2.5)
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    return {"median_s": med, "target_s": 0.5, "ratio_to_target": med / 0.5}


def bench_scenario(repeat: int, heuristic: str = "admissible") -> dict:
    _plan(None, heuristic)  # warm-up
    rows = [_plan(None, heuristic) for _ in range(repeat)]
    med = _median(rows, "search_s")
    return {"median_search_s": med, "median_total_s": _median(rows, "total_s"), "median_setup_s": _median(rows, "setup_s"),
            "target_s": 1.0, "ratio_to_target": med / 1.0, "thesis_plain_astar_s": 40.0, **{k: rows[-1][k] for k in (
                "expansions", "states_visited", "expansions_per_s", "feasible", "optimal", "counts_ok", "basic_moves",
                "lattice_states", "min_clearance_m")}}


def bench_five(repeat: int) -> dict:
    rows = [_plan(dict.fromkeys(FIVE, 5)) for _ in range(repeat)]
    med = _median(rows, "search_s")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # KiB -> GiB
    return {"median_search_s": med, "median_total_s": _median(rows, "total_s"), "target_s": 30.0, "ratio_to_target": med / 30.0,
            "peak_rss_gib": peak, "memory_target_gib": 2.0, **{k: rows[-1][k] for k in (
                "expansions", "states_visited", "expansions_per_s", "feasible", "optimal", "counts_ok", "basic_moves",
                "lattice_states")}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--five-repeat", type=int, default=3)
    ap.add_argument("--case", choices=["five"], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case == "five":
        print(json.dumps(bench_five(args.five_repeat)))
        return
    out = {"map_load": bench_map_load(args.repeat), "scenario": bench_scenario(args.repeat),
           "scenario_thesis_heuristic": bench_scenario(args.repeat, "thesis")}
    proc = subprocess.run([sys.executable, __file__, "--case", "five", "--five-repeat", str(args.five_repeat)],
                          capture_output=True, text=True, check=True)
    out["five_by_five"] = json.loads(proc.stdout.strip().splitlines()[-1])
    for name, r in out.items():
        med = r.get("median_s", r.get("median_search_s"))
        extra = ", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()
                          if k not in ("median_s", "median_search_s", "target_s", "ratio_to_target"))
        print(f"{name:28s} median {med:8.3f} s  target {r['target_s']:5.1f} s  ratio {r['ratio_to_target']:.3f}  ({extra})")


if __name__ == "__main__":
    main()
