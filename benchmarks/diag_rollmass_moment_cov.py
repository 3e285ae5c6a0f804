"""The moment methods' (``ls``, ``paper-iv``, ``improved``) sandwich ``(J^T J)^-1 J^T Sigma J (J^T J)^-1`` on the bundled
example, through ``inv(J^T J)`` (main before stop 52) and through the QR (``estimate.py`` since), against a 50-digit
mpmath reference on the Jacobian and moment covariance the fit has (docs/mass-accuracy.md, stop 52).

    shiptrial mass-sim /tmp/s52qr/ex --case case1 --seed 3
    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_moment_cov.py /tmp/s52qr/ex ls paper-iv improved
"""

from __future__ import annotations

import sys

import mpmath as mp
import numpy as np

from identify.rollmass import estimate as est
from identify.rollmass.api import estimate_from_files

seen = {}
orig_qr = np.linalg.qr


def qr(a, *k, **kw):
    seen["J"] = np.array(a)
    return orig_qr(a, *k, **kw)


est.np.linalg.qr = qr
mc = est._Problem.moment_cov


def moment_cov(self, x):
    seen["S"] = mc(self, x)
    return seen["S"]


est._Problem.moment_cov = moment_cov
E = sys.argv[1].rstrip("/") + "/"
for method in sys.argv[2:]:
    estimate_from_files(E + "nominal.csv", E + "calibration.csv", E + "loaded.csv", method=method)
    J, S = seen["J"], seen["S"]
    A = np.linalg.inv(J.T @ J)
    old = A @ J.T @ S @ J @ A
    Q, R = orig_qr(J)
    B = np.linalg.solve(R, Q.T)
    new = B @ S @ B.T
    mp.mp.dps = 50
    Jm, Sm = mp.matrix(J.tolist()), mp.matrix(S.tolist())
    Bm = (Jm.T * Jm) ** -1 * Jm.T
    ref = np.array((Bm * Sm * Bm.T).tolist(), dtype=float)
    d = np.sqrt(np.diag(ref))
    print(
        f"{method}: J {J.shape}, cond(J^T J) {np.linalg.cond(J.T @ J):.2g}; max |error| / (sd_i sd_j): inv {np.max(np.abs(old - ref) / np.outer(d, d)):.2g}, QR {np.max(np.abs(new - ref) / np.outer(d, d)):.2g}"
    )
