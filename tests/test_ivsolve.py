"""The stacked solve of expdesign.ivsolve._solve_checked against a per-system reference: the same
bits for every well-posed system and NaN exactly for the failed, non-finite, singular and
ill-conditioned ones, with the whole stack in LAPACK's batched calls and through the one-by-one
fallback that runs when LAPACK rejects the stack: a zero matrix passes the SVD test (0 >= 0) and
takes it; otherwise it is forced by a solve that refuses stacks."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign import ivsolve


def _stack(seed: int = 4, zero: bool = False):
    rng = np.random.default_rng(seed)
    n = 4
    a = rng.normal(size=(12, n, n)) + 3.0 * np.eye(n)
    rhs = rng.normal(size=(12, n))
    row, col = rng.uniform(0.5, 2.0, (12, n)), rng.uniform(0.5, 2.0, (12, n))
    fail = np.zeros(12, bool)
    if zero:
        a[1] = 0.0  # zero matrix: LAPACK rejects the stack
    else:
        a[1, :, 1] = 0.0  # a zero column: its scaled matrix is finite, its smallest singular value 0
    a[2, 3] = a[2, 0]  # exactly singular
    a[3] = a[3] @ np.diag([1.0, 1.0, 1.0, 1e-14])  # condition ~1e14
    a[4, 1, 2] = np.nan
    a[5, 0, 0] = np.inf
    rhs[6, 2] = np.nan  # a NaN right-hand side: NaN from the solve itself
    col[7, 1] = 0.0  # zero column norm: the scaled matrix is not finite
    fail[8] = True
    return a, rhs, row, col, fail, {1, 2, 3, 4, 5, 6, 7, 8}


def _reference(a, rhs, row, col, fail):
    """The per-system loop the stacked solve replaced."""
    x = np.full(rhs.shape, np.nan)
    with np.errstate(all="ignore"):
        for k in range(len(a)):
            scaled = a[k] / (row[k][:, None] * col[k][None, :])
            if fail[k] or not (np.isfinite(scaled).all() and np.isfinite(a[k]).all()):
                continue
            s = np.linalg.svd(scaled, compute_uv=False)
            try:
                if s[-1] * ivsolve.MAX_CONDITION >= s[0]:
                    x[k] = np.linalg.solve(a[k], rhs[k])
            except np.linalg.LinAlgError:
                pass
    return x


def _check(x, ref, nan_rows):
    assert {k for k in range(len(x)) if np.isnan(x[k]).all()} == nan_rows
    assert np.isfinite(np.delete(x, sorted(nan_rows), axis=0)).all()
    assert np.array_equal(x, ref, equal_nan=True)


def _spy(monkeypatch, refuse_stacks: bool = False) -> list[int]:
    """The dimensions of every np.linalg.solve call; with ``refuse_stacks`` a 3-D call raises."""
    solve, calls = np.linalg.solve, []

    def spy(m, b):
        calls.append(np.ndim(m))
        if refuse_stacks and np.ndim(m) == 3:
            raise np.linalg.LinAlgError("Singular matrix")
        return solve(m, b)

    monkeypatch.setattr(np.linalg, "solve", spy)
    return calls


def test_stacked_solve_matches_the_per_system_loop(monkeypatch):
    a, rhs, row, col, fail, nan_rows = _stack()
    ref = _reference(a, rhs, row, col, fail)
    calls = _spy(monkeypatch)
    x = ivsolve._solve_checked(a, rhs, row, col, fail)
    assert calls == [3]  # one batched solve, no fallback
    _check(x, ref, nan_rows)
    # two batch axes: the same systems, the same bits
    x2 = ivsolve._solve_checked(
        a.reshape(3, 4, 4, 4), rhs.reshape(3, 4, 4), row.reshape(3, 4, 4), col.reshape(3, 4, 4), fail.reshape(3, 4)
    )
    assert np.array_equal(x2.reshape(x.shape), x, equal_nan=True)


def test_a_zero_matrix_takes_the_one_by_one_fallback(monkeypatch):
    a, rhs, row, col, fail, nan_rows = _stack(zero=True)
    ref = _reference(a, rhs, row, col, fail)
    calls = _spy(monkeypatch)
    x = ivsolve._solve_checked(a, rhs, row, col, fail)
    assert calls[0] == 3 and calls[1:] and set(calls[1:]) == {2}  # the stack, then one system at a time
    _check(x, ref, nan_rows)


def test_one_by_one_fallback_when_lapack_rejects_the_stack(monkeypatch):
    """An SVD that does not converge, or a zero pivot LAPACK finds where the SVD did not."""
    a, rhs, row, col, fail, nan_rows = _stack()
    ref = _reference(a, rhs, row, col, fail)
    calls = _spy(monkeypatch, refuse_stacks=True)
    x = ivsolve._solve_checked(a, rhs, row, col, fail)
    assert calls[0] == 3 and calls[1:] and set(calls[1:]) == {2}  # the stack, then one system at a time
    _check(x, ref, nan_rows)


def test_every_system_failing_gives_nan_without_error():
    a, rhs, row, col, fail, _ = _stack()
    a[:] = 0.0
    assert np.isnan(ivsolve._solve_checked(a, rhs, row, col, fail)).all()
    assert ivsolve._solve_checked(a[:0], rhs[:0], row[:0], col[:0], fail[:0]).shape == (0, 4)


def test_compiled_moments_give_the_numpy_estimates(monkeypatch):
    """iv_estimates' compiled per-run moments against iv_solve: the same estimates (within 1e-12;
    sequential sums over the samples like numpy's over that axis) and NaN for the same runs, over
    the experiment's mean or none; batchwise stays on iv_solve."""
    from primitives import jitloop
    from primitives.ship import load_profile

    if not jitloop.use(jitloop.MIN_WORK):
        pytest.skip("no compiler: iv_estimates is iv_solve (the subprocess test of test_oekernel covers that path)")
    terms = load_profile("model-ship").predictor
    rng = np.random.default_rng(3)
    b, n, p = 5, 400, terms.n_params
    phi = rng.normal(size=(b, n, p))
    z = phi + 0.3 * rng.normal(size=(b, n, p))
    tgt = rng.normal(size=(b, n, 3))
    z[1, :, 0] = 2.5  # a constant instrument: removed by the mean, that run's surge DOF fails
    phi[2, :, 5] = phi[2, :, 4]  # two equal regressors: singular, that run's sway DOF fails
    for mode in ("complete", "none"):
        got = ivsolve.iv_estimates(terms, phi, z, tgt, mode)
        want = ivsolve.iv_solve(terms, phi, z, tgt, mode)[0]
        assert np.array_equal(np.isnan(got), np.isnan(want))
        assert np.allclose(got, want, rtol=1e-12, atol=0.0, equal_nan=True)
    assert np.isnan(ivsolve.iv_estimates(terms, phi, z, tgt, "complete")[1, terms.dof_slice(0)]).all()
    assert np.isnan(ivsolve.iv_estimates(terms, phi, z, tgt, "complete")[2, terms.dof_slice(1)]).all()
    monkeypatch.setattr(jitloop, "_LOADED", False)  # not loaded: the numpy path, the same numbers
    assert np.array_equal(
        ivsolve.iv_estimates(terms, phi, z, tgt, "complete"), ivsolve.iv_solve(terms, phi, z, tgt, "complete")[0], equal_nan=True
    )
