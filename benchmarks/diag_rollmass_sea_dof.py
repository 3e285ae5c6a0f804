"""Coverage of the load's interval with 1.96 and with Student's ``t_{0.975, nu}`` (:func:`sandwich.load_dof`,
docs/mass-accuracy.md stop 51 continued) on the fits ``bench_rollmass_coverage.py repeat --store`` kept (one ship,
many seas; each ``sea*.npz`` holds its Jacobian ``J`` and residual ``f``), with the leverage-corrected covariance
the fit reports (:func:`sandwich.load_cov`).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_sea_dof.py /tmp/s51/base0c1 /tmp/s51/imu0c1
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread: CPU seconds without spinning threads

import numpy as np  # noqa: E402
from scipy.special import stdtrit  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identify.rollmass import sandwich as sw  # noqa: E402


def one_dir(d: Path) -> None:
    """One line per directory: ``nu`` (median, range), ``t``, and how many seas' intervals hold the truth."""
    nus, ts, zs, cpu = [], [], [], 0.0
    for p in sorted(d.glob("sea*.npz")):
        z = dict(np.load(p))
        lengths, lags = [int(x) for x in z["lengths"]], int(z["lags"])
        c0 = time.process_time()
        interval = sw.load_interval(sw.load_basis(z["J"]), z["f"], lengths, lags)  # as the fit: one QR
        cpu += time.process_time() - c0
        sd, nu = np.sqrt(np.diag(interval.cov)), interval.dof
        nus.append(nu)
        ts.append(stdtrit(nu, 0.975))
        zs.append(np.abs([(z["m"] - z["m_true"]) / sd[0], (z["z"] - z["z_true"]) / sd[1]]))
    if not nus:
        return
    nu, t, a = np.array(nus), np.array(ts), np.array(zs)
    print(
        f"{d.name:14} n {len(a):2d} | nu m {np.median(nu[:, 0]):5.1f} ({nu[:, 0].min():.1f}-{nu[:, 0].max():.1f}) "
        f"z {np.median(nu[:, 1]):5.1f} | t {np.median(t, axis=0).round(3)} | holds m/z/both with 1.96 "
        f"{(a <= 1.96).sum(axis=0)} {(a <= 1.96).all(axis=1).sum()}, with t {(a <= t).sum(axis=0)} "
        f"{(a <= t).all(axis=1).sum()} | load_interval {cpu / len(a):.3f} s CPU a fit"
    )


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        one_dir(Path(arg))
