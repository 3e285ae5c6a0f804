"""Manoeuvres sized to the sea room (issue 28): kvlcc2 on a synthetic 8 x 6 km bay, the library's
build time, and the short forms' (paid only where the long forms fit nowhere).

    nice -n 10 python benchmarks/bench_sea_room.py [--trial-length S] [--resolution M]

Prints the plan (manoeuvres, their lengths, time, held parameters) and CPU times (builds: median of
5; the plan: once, its forked children's CPU included).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from maps.planner import plan_with_design
from maps.sizing import row_text
from maps.testmaps import bay
from primitives.library import build_library, thesis_primitives
from primitives.ship import load_profile
from primitives.sized import short_form_table, short_forms


def cpu(fn, n: int = 5) -> float:
    out = []
    for _ in range(n):
        t = time.process_time()
        fn()
        out.append(time.process_time() - t)
    return statistics.median(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trial-length", type=float, default=360.0)
    ap.add_argument("--resolution", type=float, default=None, help="lattice spacing, m (default: the planner's)")
    a = ap.parse_args()
    kv = load_profile("kvlcc2")
    build_library(kv)  # warm-up (numba, caches)
    print(f"kvlcc2 build_library CPU {cpu(lambda: build_library(kv)):.3f} s (median of 5)")
    names = [p.name for p in thesis_primitives(kv)]
    print(f"kvlcc2 short forms of every manoeuvre CPU {cpu(lambda: short_forms(kv, names, short_form_table(kv))):.3f} s")
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "bay.geojson"
        path.write_text(json.dumps(bay()))
        t, t_child = time.process_time(), _children_cpu()
        plan, td = plan_with_design(path, profile=kv, trial_length_s=a.trial_length, resolution=a.resolution)
        cpu_s, child_s = time.process_time() - t, _children_cpu() - t_child
        print(
            f"plan on the 8 x 6 km bay, trial length {a.trial_length:g} s: CPU {cpu_s + child_s:.1f} s "
            f"({cpu_s:.1f} s here, {child_s:.1f} s in the lattice's forked children), feasible {plan.feasible}"
        )
    if not plan.feasible:
        print(f"  why: {plan.stats.get('reason')}")
    lat = plan.stats["lattice"]
    print(f"  lattice {lat['resolution_m']:.0f} m, {lat['headings']} headings, settling: {plan.stats['options']['settle']}")
    for n in plan.stats["notes"]:
        if "confined" in n or "executed off the steady approach" in n:
            print(f"  note: {n}")
    lib = {p.name: p for p in td.primitives}
    for name, n in td.record["counts"].items():
        b = lib[name].footprint.bounds
        print(
            f"  {name} x{n}: {lib[name].duration_s:.0f} s, {(b[2] - b[0]) / 1000:.1f} x {(b[3] - b[1]) / 1000:.1f} km  ({lib[name].description})"
        )
    print(
        f"  plan {plan.duration_s / 60:.1f} min, {plan.length_m / 1000:.1f} km; dropped {len(td.record['dropped'])} (fit nowhere or apart)"
    )
    print(f"  dropped: {', '.join(d['primitive'] + (' (apart)' if d.get('apart') else '') for d in td.record['dropped'])}")
    print("  (apart: passed the per-manoeuvre map check, but no path sails it with the rest of a designed mix)")
    for h in td.record.get("held_parameters", []):
        by = h["identified_by"]
        why = f"  (identified by {row_text(by)})" if by else ""
        print(f"  held {h['parameter']} = {h['value']:.4g}{why}")


def _children_cpu() -> float:
    """CPU of the reaped child processes (maps.forked runs half of the lattice's moves in one)."""
    t = os.times()
    return t.children_user + t.children_system


if __name__ == "__main__":
    main()
