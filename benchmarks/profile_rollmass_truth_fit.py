"""Where one truth-bench ``oe`` fit spends its CPU (stop 54): cProfile of one
:mod:`benchmarks.bench_rollmass_truth` fit (same seeds: variant, run, case pair with it), split by stage.

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD nice -n 10 python benchmarks/profile_rollmass_truth_fit.py base 0 case1 --runs 2

Prints the CPU (process_time) of the truth simulation of the variant's family and of writing the CSVs, then
the fit's cumulative CPU per stage (a stage's time includes the stages it calls: _best_start holds its LMs'
residuals and Jacobians) and the calls of the residual and the Jacobian.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identify.rollmass.api import estimate_from_files  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

# (file suffix, function name, label): the stages of identify/rollmass/oe_fit.py and what they call
STAGES = (
    ("api.py", "estimate_from_files", "whole fit (estimate_from_files)"),
    ("api.py", "order_check", "  role/order check"),
    ("api.py", "check_recorded_signs", "  sign check"),
    ("oe_fit.py", "fit_output_error", "  fit_output_error"),
    ("oe_fit.py", "_fit", "    _fit (each path)"),
    ("oe_fit.py", "_best_start", "      _best_start (2 starts + ship-only LM)"),
    ("oe_fit.py", "_lm_exact", "      LM calls (exact Jacobian)"),
    ("oe_fit.py", "_lm", "      LM calls (forward differences)"),
    ("gyro_bias.py", "speed_terms", "      speed_terms (gyro bias, sway)"),
    ("oe_fit.py", "_whitener", "      AR whiteners"),
    ("oe_fit.py", "_gauss_newton", "      Gauss-Newton finish"),
    ("sandwich.py", "load_interval", "      load interval (sandwich)"),
    ("sandwich.py", "load_decrement", "      load decrement"),
    ("linalg.py", "svd", "      svd (rel_singular etc.)"),
    ("output_error.py", "residual", "  residual evaluations"),
    ("output_error.py", "errors", "    errors (simulate + project)"),
    ("output_error.py", "_simulate", "      _simulate"),
    ("output_error.py", "jacobian", "  Jacobian evaluations"),
    ("sensitivity.py", "dataset_jacobian", "    dataset_jacobian"),
    ("output_error.py", "discrete", "    discrete (batched model matrices)"),
    ("sandwich.py", "central_jacobian", "  central-difference Jacobian fallback"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("variant")
    ap.add_argument("run", type=int)
    ap.add_argument("case")
    ap.add_argument("--runs", type=int, default=2, help="the family's size (its ships depend on it)")
    ap.add_argument("--seed", type=int, default=2015)
    ap.add_argument("--top", type=int, default=0, help="also print the top N functions by own time")
    a = ap.parse_args()
    c0 = time.process_time()
    seed = bt.variant_seed(a.seed, a.variant)
    ship, data = bt.simulate_runs(a.variant, a.runs, seed)
    c_sim = time.process_time() - c0
    recs = bt.case_recordings(ship, data, a.case, a.run)
    with tempfile.TemporaryDirectory() as d:
        c0 = time.process_time()
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv", True) for r in recs]
        c_csv = time.process_time() - c0
        prof = cProfile.Profile(time.process_time)
        c0 = time.process_time()
        prof.enable()
        e = estimate_from_files(*paths, method="oe")
        prof.disable()
        c_fit = time.process_time() - c0
    m_true, z_true = bt.truth_load(a.case)
    print(
        f"{a.variant} run {a.run} {a.case} (--runs {a.runs}): m {e.m:.6f} (truth {m_true}), z {e.zbar_m:.6f} "
        f"(truth {z_true}), converged {e.converged}; load {os.getloadavg()[0]:.2f}"
    )
    print(
        f"truth simulation of the family ({a.runs} runs): {c_sim:.2f} s cpu; CSVs: {c_csv:.2f} s; fit {c_fit:.2f} s cpu (profiled)"
    )
    st = pstats.Stats(prof).stats
    for suffix, name, label in STAGES:
        hits = [(v[1], v[3]) for (f, _, fn), v in st.items() if fn == name and f.endswith(suffix)]
        if hits:
            calls, cum = sum(h[0] for h in hits), sum(h[1] for h in hits)
            print(f"{label:48} {cum:8.2f} s  {100 * cum / c_fit:5.1f} %  {calls:6d} calls")
    if a.top:
        pstats.Stats(prof).sort_stats("tottime").print_stats(a.top)


if __name__ == "__main__":
    main()
