"""The one instrumental-variable solve of the block-diagonal predictor (9.2), shared by
:func:`expdesign.estimators.estimate` and the Monte Carlo (:mod:`expdesign.montecarlo`): the
instrument mean removal (7.19)/(7.20) and the per-DOF systems, each judged before it is solved so
that a singular or ill-conditioned one is a failed estimate (NaN), never a number made of rounding.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from primitives import jitloop
from primitives.terms import TermSet

# A DOF's system fails (NaN) when the mean removal leaves one of its instruments constant to this
# relative precision (only rounding left: such columns in the Monte Carlo are below 4e-15 of their
# norm, its smallest real variation 1e-3), or when its condition number, rows scaled by the
# mean-removed instrument norms and columns by the regressor norms (units do not decide), exceeds
# MAX_CONDITION: eps * cond, the solution's relative error bound, above 2e-4 (the Monte Carlo's
# other systems, model-ship and full-scale, every protocol and mean subtraction, stay below 3e7).
CONSTANT_INSTRUMENT = 1e-10
MAX_CONDITION = 1e12


def remove_instrument_mean(z: np.ndarray, mean_subtraction: str, starts: Sequence[int] = (0,)) -> np.ndarray:
    """Instruments Z (..., N, p) with their mean removed: 'none'; per sub-experiment (7.19),
    'batchwise', the sub-experiments starting at the sample indices ``starts``; over the whole
    experiment (7.20), 'complete'."""
    if mean_subtraction == "complete":
        return z - z.mean(axis=-2, keepdims=True)
    if mean_subtraction == "batchwise":
        blocks = np.split(z, list(starts[1:]), axis=-2)
        return np.concatenate([c - c.mean(axis=-2, keepdims=True) for c in blocks], axis=-2)
    return z


def _solve_checked(a: np.ndarray, rhs: np.ndarray, row_norm: np.ndarray, col_norm: np.ndarray, fail: np.ndarray) -> np.ndarray:
    """x of a x = rhs for each system (a (..., n, n), rhs (..., n)); NaN where ``fail`` (...,) or
    where the system is not finite, singular, or its condition number scaled by ``row_norm`` and
    ``col_norm`` (..., n) exceeds MAX_CONDITION. Each system is solved on its own: the SVDs and
    solves of a stack are LAPACK's calls per matrix, the numbers of one system do not depend on
    the batch (a stack with a system LAPACK rejects is redone one system at a time)."""
    n = a.shape[-1]
    a2, r2 = a.reshape(-1, n, n), rhs.reshape(-1, n)
    x = np.full(r2.shape, np.nan)
    with np.errstate(all="ignore"):
        scaled = a2 / (row_norm.reshape(-1, n, 1) * col_norm.reshape(-1, 1, n))
        todo = np.flatnonzero(~np.reshape(fail, -1) & np.isfinite(scaled).all(axis=(1, 2)) & np.isfinite(a2).all(axis=(1, 2)))
        if not todo.size:
            return x.reshape(rhs.shape)
        try:
            s = np.linalg.svd(scaled[todo], compute_uv=False)
            good = todo[s[:, -1] * MAX_CONDITION >= s[:, 0]]
            x[good] = np.linalg.solve(a2[good], r2[good][..., None])[..., 0]
        except np.linalg.LinAlgError:  # an exact zero pivot (or an SVD that did not converge): one by one
            for k in todo:
                try:
                    s = np.linalg.svd(scaled[k], compute_uv=False)
                    if s[-1] * MAX_CONDITION >= s[0]:
                        x[k] = np.linalg.solve(a2[k], r2[k])
                except np.linalg.LinAlgError:
                    pass
    return x.reshape(rhs.shape)


def _column_norms(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...ki,...ki->...i", x, x))


def iv_solve(
    terms: TermSet, phi: np.ndarray, z: np.ndarray, tgt: np.ndarray, mean_subtraction: str = "none", starts: Sequence[int] = (0,)
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The block-diagonal IV estimate (2.18) of (9.2): per DOF i,
    theta_i = (sum Z~_i Phi_i^T)^-1 sum Z~_i (y_i(k+1) - y_i(k)), with Z~ the instruments with
    their mean removed (:func:`remove_instrument_mean`; Z = Phi gives least squares).

    phi, z (..., N, p), tgt (..., N, 3), any leading batch axes. A DOF whose system is singular
    or ill-conditioned (see CONSTANT_INSTRUMENT, MAX_CONDITION) gets NaN: a failed estimate to
    report, never a pseudo-inverse's number.
    Returns theta (..., p), Z~ and the DOFs' matrices sum Z~_i Phi_i^T [(..., p_i, p_i)].
    """
    zt = remove_instrument_mean(z, mean_subtraction, starts)
    zt_norm, phi_norm = _column_norms(zt), _column_norms(phi)
    with np.errstate(invalid="ignore"):
        constant = ~(zt_norm > CONSTANT_INSTRUMENT * _column_norms(z)) if mean_subtraction != "none" else zt_norm == 0
    theta = np.empty(phi.shape[:-2] + phi.shape[-1:])
    mats = []
    for i in range(3):
        s = terms.dof_slice(i)
        a = np.einsum("...ki,...kj->...ij", zt[..., s], phi[..., s])  # c_einsum, no BLAS: no thread-count rounding
        rhs = np.einsum("...ki,...k->...i", zt[..., s], tgt[..., i])
        theta[..., s] = _solve_checked(a, rhs, zt_norm[..., s], phi_norm[..., s], constant[..., s].any(axis=-1))
        mats.append(a)
    return theta, zt, mats


def iv_estimates(
    terms: TermSet, phi: np.ndarray, z: np.ndarray, tgt: np.ndarray, mean_subtraction: str = "none", starts: Sequence[int] = (0,)
) -> np.ndarray:
    """theta (B, p) of :func:`iv_solve` for phi, z (B, N, p), tgt (B, N, 3): the moments of each run
    in one compiled pass over its samples when numba is loaded (:mod:`primitives.jitloop`) and the
    mean is removed over the experiment or not at all, :func:`iv_solve` otherwise. The same
    systems, checks and solves, and sums over the samples in their order, one by one (as numpy's
    einsum and mean over that axis did in every Monte Carlo run measured: the same bits for all
    4,000 runs of 2,000 x 2; tests/test_ivsolve.py allows 1e-12, since numpy does not promise
    its order)."""
    if mean_subtraction == "batchwise" or phi.ndim != 3 or not jitloop.loaded():
        return iv_solve(terms, phi, z, tgt, mean_subtraction, starts)[0]
    dof = np.concatenate([np.full(terms.dof_slice(i).stop - terms.dof_slice(i).start, i) for i in range(3)])
    a, rhs, norms = _moments_pass(
        np.ascontiguousarray(phi), np.ascontiguousarray(z), np.ascontiguousarray(tgt), dof, mean_subtraction == "complete"
    )
    zt_norm, phi_norm, z_norm = np.sqrt(norms)
    with np.errstate(invalid="ignore"):
        constant = ~(zt_norm > CONSTANT_INSTRUMENT * z_norm) if mean_subtraction != "none" else zt_norm == 0
    theta = np.empty(phi.shape[:1] + phi.shape[-1:])
    for i in range(3):
        s = terms.dof_slice(i)
        theta[:, s] = _solve_checked(a[:, s, s], rhs[:, s], zt_norm[:, s], phi_norm[:, s], constant[:, s].any(axis=-1))
    return theta


@jitloop.compiled
def _moments_pass(phi, z, tgt, dof, complete):
    """Per run b: A[b, q, r] = sum_k Z~(k, q) Phi(k, r) within a DOF's block, rhs[b, q] =
    sum_k Z~(k, q) tgt(k, dof q), and the squared column norms of Z~, Phi and Z."""
    batch, n, p = phi.shape
    a = np.zeros((batch, p, p))
    rhs = np.zeros((batch, p))
    norms = np.zeros((3, batch, p))
    zbar = np.zeros(p)
    zt = np.empty(p)
    for b in range(batch):
        zbar[:] = 0.0
        if complete:
            for k in range(n):
                for q in range(p):
                    zbar[q] += z[b, k, q]
            for q in range(p):
                zbar[q] = zbar[q] / n
        for k in range(n):
            for q in range(p):
                zq = z[b, k, q]
                zt[q] = zq - zbar[q]
                ph = phi[b, k, q]
                norms[0, b, q] += zt[q] * zt[q]
                norms[1, b, q] += ph * ph
                norms[2, b, q] += zq * zq
                rhs[b, q] += zt[q] * tgt[b, k, dof[q]]
            for q in range(p):
                for r in range(p):
                    if dof[r] == dof[q]:
                        a[b, q, r] += zt[q] * phi[b, k, r]
    return a, rhs, norms
