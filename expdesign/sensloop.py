"""The output-error estimator's sensitivity recursion, compiled with numba when it is available
(:mod:`primitives.jitloop` decides, as for the simulation kernel), the numpy loop otherwise.

S(k+1) = (I + d inc/d nu (k)) S(k) + Phi(k), the block-diagonal recursion of the output
sensitivities (seed 001 (9.2)), in single precision as the estimator keeps it. Both paths do the
same float32 operations in the same order, per element: S(k+1) = (((Phi(k) + S(k)) + J_0 S_0(k))
+ J_1 S_1(k)) + J_2 S_2(k), so they give the same bits (tests/test_jitloop.py).
"""

from __future__ import annotations

import numpy as np

from primitives import jitloop


def recurse(sens: np.ndarray, jac: np.ndarray) -> None:
    """Run the recursion in place: ``sens`` (n+1, b, 3, p) float32 holding S(0) in row 0 and
    Phi(k) (in the rows of its DOF) in row k+1; ``jac`` (n, 3, b, 3) float32, d inc_i / d nu_col
    at step k as jac[k, col, run, i]. Overflow of an unstable estimate gives inf or NaN, silently."""
    if jitloop.use(jac.shape[0] * jac.shape[2]):
        _compiled_recursion(sens, np.ascontiguousarray(jac))
        return
    n, b, _, p = sens.shape
    tmp = np.empty((3, b, 3, p), np.float32)
    with np.errstate(all="ignore"):
        for k in range(n - 1):
            s, out = sens[k], sens[k + 1]
            out += s
            # the three columns' products in one call, added one by one in column order
            np.multiply(jac[k][:, :, :, None], s.transpose(1, 0, 2)[:, :, None, :], out=tmp)
            out += tmp[0]
            out += tmp[1]
            out += tmp[2]


@jitloop.compiled
def _compiled_recursion(sens, jac):
    n, b, nd, p = sens.shape[0] - 1, sens.shape[1], sens.shape[2], sens.shape[3]
    for k in range(n):
        for a in range(b):
            for i in range(nd):
                j0, j1, j2 = jac[k, 0, a, i], jac[k, 1, a, i], jac[k, 2, a, i]
                for q in range(p):
                    x = sens[k + 1, a, i, q] + sens[k, a, i, q]
                    x = x + j0 * sens[k, a, 0, q]
                    x = x + j1 * sens[k, a, 1, q]
                    x = x + j2 * sens[k, a, 2, q]
                    sens[k + 1, a, i, q] = x
