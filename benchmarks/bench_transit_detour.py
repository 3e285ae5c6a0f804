"""Transit detours (issue 28): each transit of a plan against the shortest path through water.

    python benchmarks/bench_transit_detour.py [--ship kvlcc2] [--map maps/data/open-sea.geojson] [--start LAT,LON,HDG]

Plans the ship's default design on the map (``maps.planner.plan_with_design``) and, for every
transit step, prints the length sailed (the plan's own track, to the next step's entry point),
the shortest path through water between the same two points, computed independently of the
planner (``tests/water_path.py``: networkx Dijkstra on the visibility graph of the no-go
polygons' vertices), and the bound: 1.3 x that path + one full turn of the ship (2 pi x 1.5 L) +
two ship lengths.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ship", default="kvlcc2")
    ap.add_argument("--map", default=str(ROOT / "maps" / "data" / "open-sea.geojson"))
    ap.add_argument("--start", default=None, help="LAT,LON,HEADING_DEG (default: the map's start)")
    args = ap.parse_args()
    from maps.geo import load_map
    from maps.planner import plan_with_design
    from primitives.ship import load_profile
    from tests.water_path import transit_lengths

    prof = load_profile(args.ship)
    sea = load_map(args.map, draught_m=prof.draught_m)
    start = tuple(float(v) for v in args.start.split(",")) if args.start else None
    c0 = time.process_time()
    plan, _ = plan_with_design(sea, profile=prof, start=start)
    print(f"{args.ship} on {Path(args.map).name}: {len(plan.steps)} steps, planned in {time.process_time() - c0:.1f} CPU s")
    desc = {s.index: s.description for s in plan.steps}
    rows = transit_lengths(plan, sea, prof.length_m)
    for step, sailed, path, bound in rows:
        print(
            f"  step {step:3d} {desc[step][:48]:48s} sailed {sailed / 1000:6.2f} km, shortest through water "
            f"{path / 1000:6.2f} km, bound {bound / 1000:6.2f} km{'  OVER' if sailed > bound else ''}"
        )
    allowance = 2 * np.pi * 1.5 * prof.length_m + 2 * prof.length_m
    over = sum(sailed > bound for _, sailed, _, bound in rows)
    print(f"  {over} transit(s) over the bound (1.3 x shortest + 2 pi x 1.5 L + 2 L = 1.3 x shortest + {allowance:.0f} m)")


if __name__ == "__main__":
    main()
