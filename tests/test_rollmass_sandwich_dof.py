"""The load's Satterthwaite degrees of freedom (:func:`identify.rollmass.sandwich.load_dof`, Bell & McCaffrey 2002)
against the dense ``n x n`` computation, the interval's Student critical value against scipy.stats, and the
`mass` path's imports (docs/mass-accuracy.md, stop 51 continued). Its coverage on the linear model with AR(1)
errors is in tests/test_rollmass_sandwich_leverage.py (the same 1,500 fits)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import stats

from identify.rollmass import sandwich as sw
from identify.rollmass.estimate import MassEstimate

LENGTHS, LAGS = [40, 30, 5], 6  # the last dataset shorter than the window: the kernel is cut, as bartlett_meat's


def _jacobian() -> np.ndarray:
    """Three channels per sample of each dataset, then two prior rows (a standardised observation each)."""
    rng = np.random.default_rng(0)
    n = 3 * sum(LENGTHS)
    J = rng.standard_normal((n + 2, 7))
    J[:n] += np.repeat(np.cos(np.arange(n // 3) / 7.0), 3)[:, None]  # a slow common part: a real leverage loss
    return J


def _dense(J: np.ndarray, col: int) -> tuple[float, float]:
    """``E[V]`` and ``tr((W Sigma)^2)`` by the n x n matrices: ``W`` the Bartlett-weighted outer product of ``u``
    per dataset, ``Sigma = (I - H)`` on the data rows, the prior rows' ``u_p^T u_p`` added to ``E[V]``."""
    Ainv = np.linalg.inv(J.T @ J)
    nd = 3 * sum(LENGTHS)
    Sigma = np.eye(nd) - J[:nd] @ Ainv @ J[:nd].T
    u = J @ Ainv[:, col]
    W, i = np.zeros((nd, nd)), 0
    for n in LENGTHS:
        t = np.repeat(np.arange(n), 3)
        w = np.clip(1 - np.abs(t[:, None] - t[None, :]) / (LAGS + 1), 0.0, None)
        W[i : i + 3 * n, i : i + 3 * n] = np.outer(u[i : i + 3 * n], u[i : i + 3 * n]) * w
        i += 3 * n
    WS = W @ Sigma
    return float(np.trace(WS) + u[nd:] @ u[nd:]), float(np.trace(WS @ WS))


def test_the_band_and_low_rank_terms_are_the_dense_ones():
    J = _jacobian()
    Ainv = np.linalg.inv(J.T @ J)
    for k, col in enumerate((-2, -1)):
        ev, t2 = _dense(J, col)
        mom = sw.load_moments(sw.load_basis(J), LENGTHS, LAGS)
        ev_k, t2_k, var_k = mom.ev[k], mom.t2[k], mom.var[k]
        assert np.allclose((ev_k, t2_k, var_k), (ev, t2, Ainv[col, col]), rtol=1e-10)
        assert sw.load_dof(J, LENGTHS, LAGS)[k] == pytest.approx(ev * ev / t2, rel=1e-10)
        assert sw.leverage_factors(J, LENGTHS, LAGS)[k] == pytest.approx(ev / Ainv[col, col], rel=1e-10)


def test_the_dof_is_the_meats_own_under_gaussian_residuals():
    """The meat ``a^T S a`` of 4,000 fitted residuals ``(I - H) e`` (white Gaussian ``e``): its ``2 mean^2 / var``
    is the Satterthwaite ``nu`` to its sampling error (about 2.3 % on the variance)."""
    J = _jacobian()
    Ainv = np.linalg.inv(J.T @ J)
    rng = np.random.default_rng(5)
    V = []
    for _ in range(4000):
        e = rng.standard_normal(len(J))
        f = e - J @ (Ainv @ (J.T @ e))
        V.append(np.diag(Ainv @ sw._meat(J, f, LENGTHS, LAGS) @ Ainv)[-2:])
    V = np.array(V)
    assert np.all(np.abs(2 * V.mean(axis=0) ** 2 / V.var(axis=0) / sw.load_dof(J, LENGTHS, LAGS) - 1) < 0.08)


def test_the_critical_value_is_students_and_196_without_dof():
    nu = np.array([2.5, 4.0, 9.3, 17.0, 27.6, 120.0, 1e4])
    e = MassEstimate("oe", {}, 0.2, -0.256, m_sd=0.01, zbar_m_sd=0.005)
    assert e.critical() == (1.96, 1.96)  # the other methods, and an oe fit without a covariance
    for d in nu:
        e.m_dof, e.zbar_m_dof = d, 2 * d
        assert np.allclose(e.critical(), stats.t.ppf(0.975, [d, 2 * d]), rtol=1e-12)
    e.m_dof, e.zbar_m_dof = 20.0, 40.0
    (mlo, mhi), (zlo, zhi) = e.ci()
    assert (mhi - 0.2) / 0.01 == pytest.approx(stats.t.ppf(0.975, 20.0)) and (zhi + 0.256) / 0.005 == pytest.approx(
        stats.t.ppf(0.975, 40.0)
    )


def test_the_mass_path_does_not_import_scipy_stats():
    """scipy.stats costs about 1 s of start-up (removed from `mass` at stop 51); the t quantile is scipy.special's."""
    code = (
        "import sys, cli.mass_cmd, identify.rollmass.api, identify.rollmass.estimate, identify.rollmass.oe_fit\n"
        "print(sorted(m for m in sys.modules if m.startswith('scipy.stats')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_andrews_window_of_ar1_load_scores_is_the_plug_in_formula():
    # stop 62: the load's two scores are the residual's channels p and a_s themselves (J's two columns pick them,
    # A = n I), each an AR(1) of pole 0.9: alpha(1) = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2) (Andrews 1991, eq. 6.4) and
    # S_T = 1.1447 (alpha n)^(1/3) = 175.0 samples (eq. 6.2), a window of 174 lags (a white score would get 1)
    from scipy.signal import lfilter

    n, rho = 40000, 0.9
    J = np.zeros((3 * n, 2))
    J[0::3, 0], J[1::3, 1] = 1.0, 1.0
    f = np.zeros(3 * n)
    drive = np.random.default_rng(3).standard_normal((n, 3))
    f[0::3], f[1::3], f[2::3] = (lfilter([1.0], [1.0, -rho], drive[:, c]) for c in range(3))
    expected = 1.1447 * (4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2) * n) ** (1 / 3) - 1
    assert abs(sw.andrews_lags(sw.load_basis(J), f, [n]) - expected) <= 0.05 * expected
    assert sw.andrews_lags(sw.load_basis(J), drive.ravel(), [n]) <= 3


def _family_like_design(T: float) -> tuple[np.ndarray, list[int]]:
    """The family's three records of case 1 (3277, 1927 and 2677 samples at 50 Hz: 66, 39 and 54 s) at sample time
    ``T``, three channels a sample: four slow cosines over each record (the nuisance), then two load columns driven by
    +-turns of 20 s and a 13 s sine with some fast content (a few slow components, as the oe fit's load scores)."""
    rng = np.random.default_rng(1)
    lengths = [round(n * 0.02 / T) for n in (3277, 1927, 2677)]
    blocks = []
    for n in lengths:
        t = np.arange(n) * T
        cols = [np.repeat(np.cos(np.pi * (j + 1) * t / t[-1])[:, None], 3, axis=1).ravel() for j in range(4)]
        turn = np.sign(np.sin(2 * np.pi * t / 20.0))
        cols.append((np.outer(turn, [1.0, 0.5, -0.3]) + 0.3 * rng.standard_normal((n, 3))).ravel())
        cols.append((np.outer(np.sin(2 * np.pi * t / 13.0), [0.2, 1.0, 0.4]) + 0.3 * rng.standard_normal((n, 3))).ravel())
        blocks.append(np.column_stack(cols))
    return np.vstack(blocks), lengths


def test_the_student_interval_holds_95_percent_at_the_5_and_20_s_windows():
    """Review of stop 62 (the interval's window went 5 -> 20 s: the dof fall about 21 -> 8 on the family, and the t
    gives most of the wider interval). White Gaussian errors, the working model of :attr:`LoadMoments.dof`, so the
    answer is known: over 4,000 fits on a family-like design (records of 39-66 s at 5 Hz, 20 s = 0.3-0.5 of a
    record) ``estimate +- t_{0.975, nu} sd`` holds the truth 95 % of the time (measured 94.6 / 95.3 % at 5 s, nu
    44.5 / 41.0; 95.3 / 95.3 % at 20 s, nu 11.9 / 11.5; Monte Carlo sd 0.34 pp) and the meat's ``2 mean^2 / var`` is
    ``nu`` (46.2 / 40.3 and 12.4 / 10.9). A wrong dof fails it: 1.96 (no dof) holds 92.9 / 92.6 % at 20 s, t at
    twice the dof 94.1 / 94.0 %; the dof x 2, x 0.5, x 1.25 or without the 2 of ``2 E[V]^2 / Var[V]`` fail the
    ``nu`` check. It passes on main's code too: the dof is main's, this pins it at the window now used."""
    T = 0.2
    X, lengths = _family_like_design(T)
    basis = sw.load_basis(X)
    rng = np.random.default_rng(2)
    e = rng.standard_normal((4000, len(X)))
    est = e @ basis.u  # the load's least-squares estimate, truth 0 (u = J a_j)
    f = e - (e @ basis.Q) @ basis.Q.T  # fitted residuals
    for window in (5.0, 20.0):
        lags = round(window / T)
        mom = sw.load_moments(basis, lengths, lags)
        V = np.array([np.diag(sw._meat(basis.u, fk, lengths, lags)) for fk in f])
        sd = np.sqrt(V / mom.rho)
        assert np.all(np.abs(2 * V.mean(axis=0) ** 2 / V.var(axis=0) / mom.dof - 1) < 0.1)
        held = np.mean(np.abs(est) <= stats.t.ppf(0.975, mom.dof) * sd, axis=0)
        assert np.all(np.abs(held - 0.95) < 0.01), (window, held, mom.dof)
        if window == 20.0:
            assert np.all(np.mean(np.abs(est) <= 1.96 * sd, axis=0) < 0.94)  # the test sees a dof error of this size
