"""Inline Monte Carlo of the model ship's optimized and random designs, output error (issue 30's
"2,000 runs x 2 designs under 5 s inline"): CPU and wall seconds of one timed
``evaluate_designs`` after a 20-run warm-up (numba loaded and the passes compiled), the digest
(the first 8 hex digits of each design's SHA-256, as ``benchmarks/run.py`` prints it) and the
parameter-error percentiles. Run it alternately from two checkouts for paired figures.
``--stages`` adds the CPU of each stage of the timed call (data simulation, IV estimate, the
output-error fit's candidate simulations, Gauss-Newton moments and Levenberg-Marquardt steps,
validation, scoring; timers wrapped around the module functions, a few microseconds a call).
The chunks run on ``primitives.threads.count()`` threads (``OMP_NUM_THREADS``, else the cores; set
``OMP_NUM_THREADS=1`` for one): the line after the figures gives each thread's CPU in its chunks
(``time.thread_time``), the largest of which bounds the wall from below on idle cores.

    python benchmarks/bench_mc_inline.py [--runs 2000] [--profile] [--stages]
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import os
import pstats
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.run import _design_setup  # noqa: E402
from benchmarks.stagetimer import time_stages  # noqa: E402
from expdesign import montecarlo, oekernel, oerefine  # noqa: E402
from expdesign.api import run_design  # noqa: E402
from expdesign.montecarlo import evaluate_designs  # noqa: E402
from primitives import threads  # noqa: E402

# (module, function, label) of each stage --stages times; indented labels are parts of the one above
STAGES = (
    (montecarlo, "simulate_data", "data simulation (noise, true system)"),
    (montecarlo, "_estimate_fused", "IV estimate (fused instrument pass)"),
    (montecarlo, "_estimate", "IV estimate (unfused)"),
    (montecarlo, "output_error", "output-error fit"),
    (oekernel, "simulate", "  candidate simulations + mean squares"),
    (oekernel, "moments_t", "  Gauss-Newton moments (sensitivities, H, g)"),
    (oerefine, "_lm_steps", "  Levenberg-Marquardt steps"),
    (montecarlo, "validate", "validation simulation"),
    (montecarlo, "scored", "scoring"),
)


def _time_threads(cpu: dict[int, float]) -> None:
    """Wrap montecarlo.run_chunk to add each thread's CPU seconds in its chunks to ``cpu``."""
    fn = montecarlo.run_chunk

    def timed(*a, **k):
        t = time.thread_time()
        try:
            return fn(*a, **k)
        finally:
            cpu[threading.get_ident()] += time.thread_time() - t

    montecarlo.run_chunk = timed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2000)
    ap.add_argument("--profile", action="store_true", help="cProfile (CPU timer) of the timed call, by own time")
    ap.add_argument("--stages", action="store_true", help="CPU of each stage of the timed call")
    args = ap.parse_args()
    cpu_stage: dict[str, float] = collections.defaultdict(float)
    if args.stages:
        time_stages(STAGES, cpu_stage)  # thread_time: the chunks' threads run the same stage at once
    prof, prims, _ = _design_setup()
    designs = {"optimized": run_design(prof, prims).weights, "random": "random"}
    cpu_thread: dict[int, float] = collections.defaultdict(float)
    _time_threads(cpu_thread)
    evaluate_designs(prof, designs, runs=20, seed=0, primitives=prims)  # warm-up
    cpu_stage.clear()
    cpu_thread.clear()
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
    per = sorted(cpu_thread.values(), reverse=True)
    print(
        f"  {threads.count()} threads; CPU in chunks per thread: {' / '.join(f'{c:.2f}' for c in per)} s (largest {per[0]:.2f} s)"
    )
    for _, _, label in STAGES:
        if label in cpu_stage:
            print(f"  {label:46s} {cpu_stage[label]:7.3f} s CPU  {100 * cpu_stage[label] / cpu:5.1f} %")
    for name, r in res.items():
        s = r.summary()
        print(f"  {name}: parameter RMSE p50 {s['param_rmse_p50']:.4f} p90 {s['param_rmse_p90']:.4f}, diverged {s['diverged']}")


if __name__ == "__main__":
    main()
