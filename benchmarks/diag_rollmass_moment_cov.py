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


def main(example: str, methods: list[str]) -> None:
    """Per method: the sandwich's worst error over ``sd_i sd_j`` through ``inv(J^T J)`` and through the QR."""
    from unittest import mock

    seen: dict[str, np.ndarray] = {}
    orig_qr, mc = np.linalg.qr, est._Problem.moment_cov

    def qr(a, *k, **kw):  # the Jacobian the moment method factors
        seen["J"] = np.array(a)
        return orig_qr(a, *k, **kw)

    def moment_cov(self, x):
        seen["S"] = mc(self, x)
        return seen["S"]

    E = example.rstrip("/") + "/"
    with mock.patch.object(est.np.linalg, "qr", qr), mock.patch.object(est._Problem, "moment_cov", moment_cov):
        for method in methods:
            estimate_from_files(E + "nominal.csv", E + "calibration.csv", E + "loaded.csv", method=method)
            print(_errors(method, seen["J"], seen["S"]))


def _errors(method: str, J: np.ndarray, S: np.ndarray) -> str:
    A = np.linalg.inv(J.T @ J)
    old = A @ J.T @ S @ J @ A
    Q, R = np.linalg.qr(J)
    B = np.linalg.solve(R, Q.T)
    new = B @ S @ B.T
    mp.mp.dps = 50
    Jm, Sm = mp.matrix(J.tolist()), mp.matrix(S.tolist())
    Bm = (Jm.T * Jm) ** -1 * Jm.T
    ref = np.array((Bm * Sm * Bm.T).tolist(), dtype=float)
    d = np.sqrt(np.diag(ref))
    return (
        f"{method}: J {J.shape}, cond(J^T J) {np.linalg.cond(J.T @ J):.2g}; max |error| / (sd_i sd_j): "
        f"inv {np.max(np.abs(old - ref) / np.outer(d, d)):.2g}, QR {np.max(np.abs(new - ref) / np.outer(d, d)):.2g}"
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
