"""CPU of the lattice moves' placements made against read back from the cache (issue 30, stop 57).

    SHIPTRIAL_CACHE_DIR=DIR python benchmarks/bench_placements_kept.py [--repeat 5]

On the bundled map for the default ship (its first design's manoeuvres, as ``plan-trial`` plans them), each repeat
in a fresh lattice: :meth:`maps.chain.Lattice.placements` with its cache entry removed (made: this process's
half, the forked helper's half not counted) and then read back (:func:`maps.mapcache.kept_placements`), the
digest of its inputs included. Prints this process's CPU seconds (least and median) of both, and of
:func:`maps.plancache.code_version` in a fresh interpreter. Needs a cache directory (the default one otherwise).
"""

from __future__ import annotations

import argparse
import functools
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _lattice(prof, support, counts, moves):
    import maps.geo as geo
    from maps.chain import PlanOptions, build_lattice
    from maps.mapcache import load_map_kept

    geo._NO_GO.clear()  # as a new process
    sea = load_map_kept(None, draught_m=prof.draught_m)
    return build_lattice(sea, prof, support, counts, options=PlanOptions(), cache=moves)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error(f"--repeat {args.repeat}: give at least 1 timed repeat")
    from maps import mapcache, plancache
    from maps.trialdesign import design_counts
    from primitives.ship import load_profile

    if plancache.default_dir() is None:
        sys.exit("error: no cache directory (SHIPTRIAL_CACHE_DIR is empty): nothing is kept to read back")
    prof = load_profile("full-scale")
    td = design_counts(prof)
    moves: dict = {}
    made, read = [], []
    for _ in range(args.repeat):
        lat = _lattice(prof, td.support(), td.counts, moves)
        shape = (len(lat.moves), len(lat.table), lat.window.ni, lat.window.nj)
        where = mapcache._placements_key(lat.sea, functools.partial(lat.placement_inputs, 0.0), shape)
        (where[0] / f"{where[1]}.map").unlink(missing_ok=True)  # made, then
        t = time.process_time()
        lat.placements()
        made.append(time.process_time() - t)
        lat = _lattice(prof, td.support(), td.counts, moves)
        t = time.process_time()
        lat.placements()  # read back
        read.append(time.process_time() - t)
    code = "import time, maps.plancache as p; t = time.process_time(); p.code_version(); print(time.process_time() - t)"
    hashed = [
        float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT).stdout) for _ in range(3)
    ]
    for name, xs in (("placements made (this process's half)", made), ("placements read back", read), ("code_version", hashed)):
        print(f"{name}: {min(xs):.4f} s least, {statistics.median(xs):.4f} s median CPU ({len(xs)} runs)")


if __name__ == "__main__":
    main()
