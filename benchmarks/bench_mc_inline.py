"""Inline Monte Carlo of the model ship's optimized and random designs, output error (issue 30's
"2,000 runs x 2 designs under 5 s inline"): CPU and wall seconds of one timed
``evaluate_designs`` after a 20-run warm-up (numba loaded and the passes compiled), the digest
(the first 8 hex digits of each design's SHA-256, as ``benchmarks/run.py`` prints it) and the
parameter-error percentiles. Run it alternately from two checkouts for paired figures.

    python benchmarks/bench_mc_inline.py [--runs 2000] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.run import _design_setup  # noqa: E402
from expdesign.api import run_design  # noqa: E402
from expdesign.montecarlo import evaluate_designs  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2000)
    ap.add_argument("--profile", action="store_true", help="cProfile (CPU timer) of the timed call, by own time")
    args = ap.parse_args()
    prof, prims, _ = _design_setup()
    designs = {"optimized": run_design(prof, prims).weights, "random": "random"}
    evaluate_designs(prof, designs, runs=20, seed=0, primitives=prims)  # warm-up
    pr = cProfile.Profile(time.process_time) if args.profile else None
    c0, w0 = time.process_time(), time.perf_counter()
    if pr:
        pr.enable()
    res = evaluate_designs(prof, designs, runs=args.runs, seed=0, primitives=prims)
    if pr:
        pr.disable()
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    if pr:
        pstats.Stats(pr).sort_stats("tottime").print_stats(25)
    digest = "".join(r.digest()[:8] for r in res.values())
    print(
        f"Monte Carlo {args.runs} x {len(designs)} inline, output error: CPU {cpu:.2f} s, wall {wall:.2f} s, "
        f"{1e3 * cpu / (len(designs) * args.runs):.3f} ms CPU per run, digest {digest}, load {os.getloadavg()[0]:.1f}"
    )
    for name, r in res.items():
        s = r.summary()
        print(f"  {name}: parameter RMSE p50 {s['param_rmse_p50']:.4f} p90 {s['param_rmse_p90']:.4f}, diverged {s['diverged']}")


if __name__ == "__main__":
    main()
