"""The oe fit's per-stage innovation sds, legacy and fixed (stop 61; "fixed" the only fit since stop 62), on one truth-bench fit.

``oe_fit._reweighted`` gets each stage's output errors already whitened by that stage's whiteners; it fits a new
factor to them and convolves it with the old one (the next stage's composite whitener, right for the raw error). The
legacy sd applies that composite to the whitened errors (the old whitener twice); the fixed sd applies the new factor
alone (= the composite on the raw error, up to the nuisance projection). Per ``_reweighted`` call it prints both, per
dataset and channel (p, a_s, r), and their ratio; the fit itself runs with the fixed sd (the legacy one is computed
here beside it: the composite whitener ``_reweighted`` returns, applied to the errors it got).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_innovation_sd.py --runs 30 --fit waves/0/case1
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from identify.rollmass.sensitivity import fir  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

CHANNELS = ("p", "a_s", "r")


def _both(original, calls: list):
    """``_reweighted`` that also records each call's legacy sd (the returned composite applied to the already whitened
    errors) beside the fixed one it returns."""

    def wrapped(errs, ar, ar_order):
        comp, sd, w = original(errs, ar, ar_order)
        legacy = np.array([[fir(comp[i][j], e[:, j]).std() for j in range(3)] for i, e in enumerate(errs)])
        calls.append((ar is None, legacy, sd))
        return comp, sd, w

    return wrapped


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30, help="the family's --runs (run k's ship depends on it)")
    ap.add_argument("--seed", type=int, default=2015)
    ap.add_argument("--fit", default="waves/0/case1", help="variant/run/case")
    a = ap.parse_args()
    variant, run, case = a.fit.split("/")
    ship, data = bt.simulate_runs(variant, a.runs, bt.variant_seed(a.seed, variant))
    recs = bt.case_recordings(ship, data, case, int(run))
    calls: list = []
    oe_fit._reweighted = _both(oe_fit._reweighted, calls)
    with tempfile.TemporaryDirectory() as d:
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs]
        e = estimate_from_files(*paths, method="oe")
    m_true, z_true = bt.truth_load(case)
    print(
        f"{a.fit} fitted with the fixed innovation sd: mass {100 * (e.m / m_true - 1):+.3f} %, "
        f"height {1000 * (e.zbar_m - z_true):+.2f} mm, path {e.fit_path.path if e.fit_path else '-'}"
    )
    for k, (first, leg, fix) in enumerate(calls):
        print(f"\n_reweighted call {k + 1}{' (no whitener yet)' if first else ''}: sd legacy / fixed / ratio")
        for i in range(leg.shape[0]):
            cells = "  ".join(
                f"{c:>3} {leg[i, j]:.4g} / {fix[i, j]:.4g} / {leg[i, j] / fix[i, j]:.3f}" for j, c in enumerate(CHANNELS)
            )
            print(f"  dataset {i}: {cells}")
        w_leg, w_fix = 1 / leg, 1 / fix
        print(
            f"  weight ratio legacy/fixed, spread over the 9 cells (max/min): {np.ptp(np.log(w_leg / w_fix)):.3f} in log, "
            f"{(w_leg / w_fix).max() / (w_leg / w_fix).min():.2f}x"
        )


if __name__ == "__main__":
    main()
