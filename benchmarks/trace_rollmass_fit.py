"""Trace one oe fit of the basin truth bench: every LM call and every Gauss-Newton finishing step.

The recordings are the ones ``bench_rollmass_truth.py`` fits (same seeds, written as three CSVs and read by
``estimate_from_files`` as a user's would); the fit's LMs and its Gauss-Newton finish are wrapped to print,
per call, the path (exact Jacobian or forward differences), the datasets, the whitener's length, the
evaluations, the status, the cost and the parameters that absorb a mismatch (m, zbar_m, X_v, Y_pdot, K_vdot,
A_x, K_ur, kappa); per finishing step the load decrement, the cost, the step halvings and the parameters whose
relative step is largest. Stop 50 found with it why ``combined`` run 1 cases 1-2 did not converge
(docs/mass-accuracy.md).

    python benchmarks/trace_rollmass_fit.py --variant combined --run 1 --case case1
    python benchmarks/trace_rollmass_fit.py --variant combined --run 1 --case case1 --finish-steps 80
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from identify.rollmass.sandwich import load_basis, load_decrement  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

SHOWN = ("m", "zbar_m", "X_v", "Y_pdot", "K_vdot", "A_x", "K_ur", "kappa")


def _shown(free: tuple[str, ...], x: np.ndarray) -> str:
    return " ".join(f"{k} {x[free.index(k)]:.5g}" for k in SHOWN if k in free)


def _traced_lm(lm, name: str):
    def inner(prob, x0, tol):
        c0 = time.process_time()
        head = f"{name:8} datasets {len(prob.datasets)} whitener {prob.ar[0][0].size:2d}"
        res = lm(prob, x0, tol)  # status 0: the evaluation cap (stop 55: a capped exact LM goes on)
        print(f"{head} nfev {res.nfev:3d} status {res.status} cost {res.cost:.4f} {time.process_time() - c0:.1f} s cpu")
        print(f"         -> {_shown(prob.free, res.x)}")
        return res

    return inner


def _traced_gauss_newton(prob, x, steps, lags):
    """:func:`oe_fit._gauss_newton`, step for step, printing each step."""
    lengths = [d.n for d in prob.datasets]
    f, J = prob.residual(x), prob.jacobian(x)
    dec = load_decrement(load_basis(J), f, lengths, lags)
    print(f"GN start decrement {dec:.4f} cost {f @ f / 2:.4f} {_shown(prob.free, x)}")
    for i in range(steps):
        if dec < oe_fit.STATIONARY:
            break
        dx, cost, halvings = -np.linalg.lstsq(J, f, rcond=None)[0], f @ f, 0
        for _ in range(12):
            f_new = prob.residual(x + dx)
            if f_new @ f_new < cost:
                break
            dx, halvings = 0.5 * dx, halvings + 1
        else:
            print(f"GN {i + 1}: no descent along the Gauss-Newton direction")
            break
        x, f = x + dx, f_new
        J = prob.jacobian(x)
        dec = load_decrement(load_basis(J), f, lengths, lags)
        rel = dx / np.maximum(np.abs(x), 1e-9)
        big = ", ".join(f"{prob.free[j]} {rel[j]:+.3f}" for j in np.argsort(-np.abs(rel))[:3])
        print(
            f"GN {i + 1:3d} decrement {dec:.4f} cost {f @ f / 2:.6f} halvings {halvings} m {x[-2]:.5f} z {x[-1]:.5f}; largest relative steps {big}"
        )
    print(f"GN end {_shown(prob.free, x)}")
    return x, J, dec, f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="combined", choices=bt.VARIANTS + ("base",))
    ap.add_argument("--run", type=int, default=1, help="run index (the bench's --runs must exceed it)")
    ap.add_argument("--case", default="case1", choices=tuple(bt.CASES))
    ap.add_argument("--seed", type=int, default=2015)
    ap.add_argument("--finish-steps", type=int, default=oe_fit.FINISH_STEPS, help="Gauss-Newton finishing steps")
    a = ap.parse_args()
    seed = bt.variant_seed(a.seed, a.variant)
    ship, data = bt.simulate_runs(a.variant, a.run + 1, seed)
    oe_fit.FINISH_STEPS = a.finish_steps
    oe_fit._lm_exact, oe_fit._lm = _traced_lm(oe_fit._lm_exact, "exact"), _traced_lm(oe_fit._lm, "fwd-diff")
    oe_fit._gauss_newton = _traced_gauss_newton
    m_true, z_true = bt.truth_load(a.case)
    with tempfile.TemporaryDirectory() as d:
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, a.case, a.run)]
        c0 = time.process_time()
        e = estimate_from_files(*paths)
    print(
        f"\n{a.variant} run {a.run} {a.case}: {e.m:.4f} kg at {e.zbar_m:+.4f} m (truth {m_true} kg at {z_true} m), "
        f"sd {e.m_sd:.4f} kg / {1000 * e.zbar_m_sd:.0f} mm, converged {e.converged}, {time.process_time() - c0:.1f} s cpu"
    )
    for w in e.warnings:
        print(f"warning: {w}")


if __name__ == "__main__":
    main()
