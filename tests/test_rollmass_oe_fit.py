"""The oe fit as a numerical procedure: a residual smooth enough to differentiate, a stop short of
the optimum said (never a silent "converged"), and the roll-centre prior's uncertainty in the interval."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import OptimizeResult
from scipy.signal import lfilter, ss2tf

from identify.rollmass import oe_fit as fit
from identify.rollmass import output_error as oe
from identify.rollmass import sandwich
from identify.rollmass.estimate import estimate
from identify.rollmass.model import Load, load_profile
from identify.rollmass.simulate import Noise, simulate_case

PROF = load_profile()
CAL = Load(0.2, -0.256)


@pytest.fixture(scope="module")
def case2():
    return simulate_case(PROF, "case2", Noise.from_profile(PROF, 0.05), seed=3, length_factor=0.3)


def _problem(datasets) -> tuple[oe._Problem, np.ndarray]:
    kn = PROF.known
    free = oe.SHARED + ("z_f", "m", "zbar_m")
    w = np.array([1.0 / oe._measured(d).std(axis=0) for d in datasets])
    start = oe.start_values(PROF)
    x = np.array([start[k] for k in oe.SHARED] + [kn.z_f_prior, 0.4, -0.268])
    return oe._Problem(datasets, kn, CAL, kn.z_f_prior, free, w, None, kn.z_f_prior_sd), x


@pytest.mark.parametrize("name", ["Y_r", "Y_pdot", "K_vdot", "X_v", "zbar_m"])
def test_the_residual_is_smooth_enough_for_finite_differences(case2, name):
    """Central differences at steps 1e-6 and 1e-8 agree: the fit's Jacobian is a derivative, not
    rounding noise. Through the transfer function (ss2tf + order-4 lfilter) they differed by 10-800 %
    and LM stopped on xtol far from the optimum (basin truth base, case 2: 0.347 kg for 0.400)."""
    prob, x = _problem(case2)
    j = prob.free.index(name)
    d = []
    for h in (1e-6, 1e-8):
        e = np.zeros_like(x)
        e[j] = h * max(1.0, abs(x[j]))
        d.append((prob.residual(x + e) - prob.residual(x - e)) / (2 * e[j]))
    assert np.linalg.norm(d[0] - d[1]) < 1e-3 * np.linalg.norm(d[0])


def test_a_fit_stopped_short_of_a_stationary_point_is_said(case2, monkeypatch):
    """An optimiser that stops where it started (as LM's xtol test did on the ridge) with
    ``success`` set must not yield a silent "converged": the Newton decrement check says it. The
    exact-Jacobian path ending so is redone on forward differences, and when that path ends short
    too the user is told (the fallback hides no failure)."""
    calls = []

    def stuck_as(name):
        def stuck(prob, x0, tol):
            calls.append(name)
            f = prob.residual(x0)
            jac = oe.central_jacobian(prob.residual, x0)
            return OptimizeResult(
                x=x0, fun=f, cost=0.5 * f @ f, jac=jac, success=True, message="`xtol` termination condition is satisfied."
            )

        return stuck

    monkeypatch.setattr(fit, "_lm", stuck_as("fd"))
    monkeypatch.setattr(fit, "_lm_exact", stuck_as("exact"))
    monkeypatch.setattr(fit, "_lm_geodesic", stuck_as("continue"))  # the continuation's LM since stop 59
    monkeypatch.setattr(fit, "FINISH_STEPS", 0)
    e = estimate(case2, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    assert not e.converged
    assert any("not at a stationary point" in w for w in e.warnings)
    # the whole fit on each path: ship start, two joint starts, two reweights; between them (stop 56) the exact path's
    # last stage continued once from where it stopped
    assert calls == ["exact"] * 5 + ["continue"] + ["fd"] * 5


def _spy(monkeypatch, name: str) -> list:
    """Record the evaluation counts of every call of ``oe_fit.<name>`` (an LM)."""
    calls, real = [], getattr(fit, name)

    def spy(prob, x0, tol):
        res = real(prob, x0, tol)
        calls.append(res.nfev)
        return res

    monkeypatch.setattr(fit, name, spy)
    return calls


def test_lm_runs_on_the_exact_jacobian(monkeypatch):
    """On the bundled example (``mass-sim --case case1 --seed 3``, full length, MTi-G noise) every LM
    of the fit (ship start, two joint starts, two reweighted fits) runs on the sensitivity Jacobian,
    none on forward differences, and the fit ends at a stationary point."""
    ds = simulate_case(PROF, "case1", Noise.from_profile(PROF), seed=3)
    exact, fd = _spy(monkeypatch, "_lm_exact"), _spy(monkeypatch, "_lm")
    e = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    assert e.converged and len(exact) == 5 and not fd
    # the path is recorded (stop 55): exact, each LM call's evaluations as scipy counted them, none at a cap
    p = e.fit_path
    assert p.path == "exact" and p.why == "" and p.redo is None
    assert [n for n, _ in p.exact.lm] == exact and all(s > 0 for _, s in p.exact.lm)
    # every residual counted: the LMs' (scipy's nfev) plus the Gauss-Newton finish's; a Jacobian per LM step at least
    assert p.exact.residuals >= sum(exact) + 1 and p.exact.jacobians >= len(exact)
    assert p.record()["exact"]["lm"] == [list(c) for c in p.exact.lm]


def test_an_exact_path_ending_unconverged_is_redone_on_forward_differences(case2, monkeypatch):
    """Exact-Jacobian LMs at their evaluation cap (here 2: each one) go on from where they stopped (stop 55), and
    the path ending not stationary (here: no finishing steps) is redone on forward differences (here a stub that
    stays where it starts); that path's answer is the one returned."""
    monkeypatch.setattr(fit, "LM_NFEV_EXACT", 2)
    monkeypatch.setattr(fit, "GEODESIC_STEPS", 2)  # the continuation (stop 56; geodesic, stop 59) stops short too
    monkeypatch.setattr(fit, "FINISH_STEPS", 0)
    starts = []

    def stays(prob, x0, tol):
        starts.append(x0)
        f = prob.residual(x0)
        return OptimizeResult(x=x0, fun=f, cost=0.5 * f @ f, jac=prob.jacobian(x0), success=True, status=2, message="stub")

    monkeypatch.setattr(fit, "_lm", stays)
    e = estimate(case2, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    assert len(starts) == 5  # ship start, two joint starts, two reweighted fits
    assert (e.m, e.zbar_m) == (CAL.m, CAL.zbar)  # the stub's: where the joint fits start
    # the path is recorded (stop 55): the redo and why; on the exact path all five LMs ran, each to its cap
    p = e.fit_path
    assert p.path == "redo" and p.why.startswith("not converged: ") and "not at a stationary point" in p.why
    assert [s for _, s in p.exact.lm] == [0] * 5 and p.exact.residuals >= 10
    assert len(p.continued.lm) == 1 and p.continued.lm[0][1] == 0 and "continued (geodesic), still not converged" in p.why
    assert p.continued.lm[0][0] <= 2 * 2 + 1  # at most two residuals a geodesic step and the start's
    assert len(p.redo.lm) == 5 and p.redo.residuals == 6  # the stub once a call, the finish once at its start


def test_a_capped_exact_lm_goes_on_to_a_converged_exact_fit(monkeypatch):
    """Stop 55's rule, fast: on the bundled example (``mass-sim --case case1 --seed 3``) with the exact LM's cap at
    12, the joint start from the fitted ship stops at the cap (measured calls [(6, 2), (7, 2), (11, 2), (12, 0),
    (7, 2)]); its point goes on, the finish judges it stationary, and the fit ends on the exact path at the uncapped
    fit's load (moved 6e-7 kg, 0.00006 SE). Main's rule (any capped exact LM abandons the path) fails this test."""
    ds = simulate_case(PROF, "case1", Noise.from_profile(PROF), seed=3)
    free = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    monkeypatch.setattr(fit, "LM_NFEV_EXACT", 12)
    e = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    assert (12, 0) in e.fit_path.exact.lm  # an LM did stop at its cap
    assert e.fit_path.path == "exact" and e.fit_path.redo is None and e.converged
    assert abs(e.m - free.m) < 0.01 * e.m_sd and abs(e.zbar_m - free.zbar_m) < 0.01 * e.zbar_m_sd


@pytest.mark.parametrize("continuation", ["exact", "geodesic"])
def test_an_exact_path_ending_unconverged_goes_on_from_where_it_stopped(monkeypatch, continuation):
    """Stop 56: where the exact path ends unconverged, its last stage goes on from where it stopped (one exact LM of
    at most ``LM_NFEV_CONTINUE`` evaluations, or since stop 59 the geodesic LM, then the finish) before any
    forward-difference redo; the path is named by the continuation (``"continued"`` / ``"geodesic"``). Bundled example
    (``mass-sim --case case1 --seed 3``) with every exact LM capped at 2 evaluations and no finishing steps: the exact
    path ends not stationary, the continuation converges (measured: 5 evaluations), no forward-difference LM runs.
    Its load is 0.13 / 0.15 SE from the uncapped fit's: the same data, but the reweighting stages ran from capped LMs'
    points, so the last stage's weights and whiteners (its cost) differ. Main (the redo at once) fails: its path is
    ``"redo"``."""
    ds = simulate_case(PROF, "case1", Noise.from_profile(PROF), seed=3)
    free = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    monkeypatch.setattr(fit, "LM_NFEV_EXACT", 2)
    monkeypatch.setattr(fit, "FINISH_STEPS", 0)
    monkeypatch.setattr(fit, "CONTINUATION", continuation)
    fd = _spy(monkeypatch, "_lm")
    e = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    p = e.fit_path
    assert p.path == {"exact": "continued", "geodesic": "geodesic"}[continuation]
    assert p.redo is None and not fd and e.converged
    assert [s for _, s in p.exact.lm] == [0] * 5 and "not at a stationary point" in p.why
    assert len(p.continued.lm) == 1 and p.continued.lm[0][1] > 0  # one LM, ended by its tolerance, not its cap
    assert p.continued.residuals > p.continued.lm[0][0]  # its LM's evaluations and the finish's
    assert p.record()["continued"]["lm"] == [list(p.continued.lm[0])]
    assert abs(e.m - free.m) < 0.2 * e.m_sd and abs(e.zbar_m - free.zbar_m) < 0.2 * e.zbar_m_sd


def test_an_exact_end_the_finish_never_judged_is_redone_not_continued(case2, monkeypatch):
    """Stop 56 review: the continuation is for an end the finish judged short of stationary (a finite decrement). An
    exact path whose last LM failed (here a stub: not successful, not at its cap) is never finished, so it goes to the
    forward-difference redo from both starts as before, not on from its point. The guard on a finite point alone fails."""
    calls = []

    def as_(name, ok):
        def lm(prob, x0, tol):
            calls.append(name)
            f = prob.residual(x0)
            status, msg = (2, "stub") if ok else (-1, "diverged stub")
            return OptimizeResult(x=x0, fun=f, cost=0.5 * f @ f, jac=prob.jacobian(x0), success=ok, status=status, message=msg)

        return lm

    monkeypatch.setattr(fit, "_lm_exact", as_("exact", False))
    monkeypatch.setattr(fit, "_lm_continue", as_("continue", True))
    monkeypatch.setattr(fit, "_lm_geodesic", as_("continue", True))
    monkeypatch.setattr(fit, "_lm", as_("fd", True))
    e = estimate(case2, PROF.known, CAL, "oe", with_ci=True, start=oe.start_values(PROF))
    p = e.fit_path
    assert calls == ["exact"] * 5 + ["fd"] * 5 and p.continued is None
    assert p.path == "redo" and p.why == "not converged: diverged stub"


@pytest.mark.slow
def test_without_the_covariance_a_capped_exact_lm_is_still_redone(monkeypatch):
    """Without ``with_cov`` there is no finish to judge a capped LM's point stationary: main's rule holds there (any
    exact LM at its cap sends the fit to the forward-difference redo; review of stop 55, finding 7). Same example and
    cap as above; measured ~14 s CPU, the answer bit-identical to main's (m 0.18298299230882503 kg)."""
    ds = simulate_case(PROF, "case1", Noise.from_profile(PROF), seed=3)
    monkeypatch.setattr(fit, "LM_NFEV_EXACT", 12)
    e = estimate(ds, PROF.known, CAL, "oe", with_ci=False, start=oe.start_values(PROF))
    assert (12, 0) in e.fit_path.exact.lm and e.fit_path.path == "redo" and "with_cov off" in e.fit_path.why
    assert e.converged and e.fit_path.redo is not None


def test_the_sandwich_carries_a_priors_uncertainty():
    """Two parameters the data see only as their sum, the second with a prior of sd 1: the
    covariance of the second is the prior's (1), not the near-zero the data rows alone give."""
    rng = np.random.default_rng(0)
    n = 400
    col = rng.standard_normal(3 * n)
    J = np.vstack([np.column_stack([col, col]), [[0.0, 1.0]]])
    f = np.r_[rng.standard_normal(3 * n), 0.0]
    cov = sandwich.sandwich_cov(J, f, [n], lags=0)
    assert cov[1, 1] == pytest.approx(1.0, rel=0.05)
    assert cov[0, 0] + cov[1, 1] + 2 * cov[0, 1] == pytest.approx(1 / (col @ col), rel=0.2)


def test_the_bartlett_meat_is_the_newey_west_sum_over_lags():
    """:func:`sandwich.bartlett_meat` (one FFT convolution) is Newey-West's ``G_0 + sum_k w_k (G_k + G_k^T)``
    with ``G_k = sum_t h_t h_{t-k}^T`` and ``w_k = 1 - k/(L+1)`` (1987, eq. 2), a window beyond the data
    cut at ``n - 1`` lags with its weights kept."""
    from identify.rollmass.sandwich import bartlett_meat

    h = np.random.default_rng(1).standard_normal((60, 3)).cumsum(axis=0)  # correlated scores
    for lags, n in ((0, 60), (7, 60), (100, 60)):
        S = h.T @ h
        for k in range(1, min(lags, n - 1) + 1):
            G = h[k:].T @ h[:-k]
            S += (1 - k / (lags + 1)) * (G + G.T)
        assert np.allclose(bartlett_meat(h, lags), S, rtol=1e-10, atol=1e-9)


def test_the_modal_simulation_is_the_state_space_model(case2):
    """The modal recursion gives the Tustin model's response to its inputs (the rudder and the heel signal
    of the recording's roll angle) to rounding (against the plain state recursion), the old
    transfer-function route (``ss2tf`` + ``lfilter``, one input at a time) to within its own rounding
    (about 1e-9 of the signal), and its free-response basis spans every initial state's response."""
    kn = PROF.known
    v = {**oe.start_values(PROF), "m": 0.4, "zbar_m": -0.268}
    for rec in case2:
        load = rec.load if rec.load is not None else Load(0.4, -0.268)
        out, basis = oe._simulate(v, kn, kn.z_f_prior, load, rec)
        Ad, Bd, Cd, Dd = oe._bilinear(*oe.model_matrices(v, kn, kn.z_f_prior, load, rec.U), rec.T)
        inputs = oe.model_inputs(v, kn, rec)
        cols = [j for j, _ in inputs]
        # the case has phi, the profile a BM; with a u column also the turn input (speed.speed_inputs)
        assert cols == ([0, 1, 2] if rec.u is not None else [0, 1])
        U = np.column_stack([u for _, u in inputs])
        x, ref = np.zeros(len(Ad)), np.empty((rec.n, 3))
        for k, u in enumerate(U):
            ref[k] = Cd @ x + Dd[:, cols] @ u
            x = Ad @ x + Bd[:, cols] @ u
        scale = np.abs(ref).max(axis=0)
        assert np.all(np.abs(out - ref).max(axis=0) < 1e-11 * scale)
        old = 0.0
        for c, j in enumerate(cols):
            num, den = ss2tf(Ad, Bd, Cd, Dd, input=j)
            old = old + np.column_stack([lfilter(num[i], den, U[:, c]) for i in range(3)])
        assert np.all(np.abs(out - old).max(axis=0) < 1e-7 * scale)
        x = np.random.default_rng(0).standard_normal(len(Ad))
        free = np.empty((rec.n, 3))
        for k in range(rec.n):
            free[k], x = Cd @ x, Ad @ x
        left = free - basis @ np.linalg.lstsq(basis, free, rcond=None)[0]
        assert np.all(np.abs(left).max(axis=0) < 1e-11 * np.abs(free).max(axis=0))


def test_stationarity_is_judged_in_the_reported_standard_errors():
    """A linear fit with slow regressors and residuals (AR(1), 0.95), stopped 0.05 of the mass's
    reported (sandwich) sd from its optimum, is stationary; stopped 1 sd away, it is not. The Newton
    decrement, which measures the step in ``(J^T J)^-1``, flags the first too (the correlation makes
    the naive sd about four times too small)."""
    rng = np.random.default_rng(1)
    n, lags = 3000, 250
    # per sample (n, 3 channels), regressors and residual both low-passed, as slow signals are
    J = lfilter([1.0], [1.0, -0.95], rng.standard_normal((n, 3, 4)), axis=0).reshape(3 * n, 4)
    y = lfilter([np.sqrt(1 - 0.95**2)], [1.0, -0.95], rng.standard_normal((n, 3)), axis=0).ravel()  # unit variance
    x_opt = np.linalg.lstsq(J, y, rcond=None)[0]
    sd_m = np.sqrt(sandwich.sandwich_cov(J, J @ x_opt - y, [n], lags)[-2, -2])
    for t, stationary in ((0.05, True), (1.0, False)):
        x = x_opt + np.r_[0.0, 0.0, t * sd_m, 0.0]
        f = J @ x - y
        assert (fit.load_decrement(sandwich.load_basis(J), f, [n], lags) < fit.STATIONARY) is stationary
    g = J.T @ (J @ (x_opt + np.r_[0.0, 0.0, 0.05 * sd_m, 0.0]) - y)
    assert g @ np.linalg.solve(J.T @ J, g) > fit.STATIONARY


def test_the_imu_lag_is_held_within_its_physical_range(case2):
    """``t_imu`` is a sensor filter's delay: not negative, and within half a sample (10 ms at 50 Hz).
    Inside that range the fit sees no wall (no information added); outside it a wall residual
    grows with the distance, so a fit cannot wander to a lag no IMU has."""
    prob, x = _problem(case2)
    i, T = oe.SHARED.index("t_imu"), case2[0].T

    def wall(t: float) -> float:
        y = x.copy()
        y[i] = t
        return float(prob.prior(y)[-1])

    assert wall(0.0) == wall(0.005) == wall(0.5 * T) == 0.0
    assert wall(-0.001) == pytest.approx(-0.001 / oe.T_IMU_WALL)
    assert wall(0.5 * T + 0.002) == pytest.approx(0.002 / oe.T_IMU_WALL)
    assert len(prob.residual(x)) == 3 * sum(d.n for d in case2) + 2  # the z_f prior and the wall


@pytest.mark.slow
def test_a_slowing_ship_whose_sway_row_walked_now_converges(tmp_path):
    """Basin truth ``combined`` run 1 case 1 (the bench's seed, full length, through the files): on main the
    sway row's nearly free scale walked (X_v 1,856 -> 24,440 in the finish, the roll row's K_vdot and A_x
    after it) and Gauss-Newton stalled (5-10 halvings a step, the load 0.41 of its sd from stationary after
    10 steps and 0.38 after 80): not converged, 63 s cpu. With the sway mass's prior (fits of a followed
    speed) it converges where the whitened cost is lower, and its interval holds the load (0.2 kg at -0.256 m)."""
    from identify.rollmass.api import estimate_from_files
    from tests.physics import basin_truth as bt

    ship, data = bt.simulate_runs("combined", 2, bt.variant_seed(2015, "combined"))
    paths = [bt.write_csv(r, tmp_path / f"{r.role}.csv") for r in bt.case_recordings(ship, data, "case1", 1)]
    e = estimate_from_files(*paths)
    assert e.converged, e.warnings
    (mlo, mhi), (zlo, zhi) = e.ci()
    assert mlo <= 0.2 <= mhi and zlo <= -0.256 <= zhi, (e.m, e.zbar_m, e.ci())
    assert 10.0 < e.params["X_v"] + PROF.known.M < 400.0, e.params["X_v"]  # a sway mass near the profile's 42 kg


def test_the_same_convolution_is_scipys_fftconvolve():
    """:func:`sandwich.same_convolution` (numpy's FFT, without scipy.signal's import) is
    ``scipy.signal.fftconvolve(h, kernel[:, None], mode="same", axes=0)`` to 1e-13 of its largest value,
    on the Bartlett kernels the sandwich uses (a window shorter and longer than the data)."""
    from scipy.signal import fftconvolve

    from identify.rollmass.sandwich import same_convolution

    rng = np.random.default_rng(2)
    for n, lags in ((3286, 250), (1936, 250), (60, 7), (61, 100)):
        h = rng.standard_normal((n, 21)).cumsum(axis=0)
        L = min(lags, n - 1)
        kernel = 1.0 - np.abs(np.arange(-L, L + 1)) / (lags + 1)
        want = fftconvolve(h, kernel[:, None], mode="same", axes=0)
        got = same_convolution(h, kernel)
        assert got.shape == want.shape
        assert np.max(np.abs(got - want)) <= 1e-13 * np.max(np.abs(want)), (n, lags)


@pytest.mark.slow
def test_a_capped_exact_lm_goes_on_to_the_redos_answer_at_a_fraction_of_its_evaluations():
    """Stop 55: the basin truth family's base run 2 case 1 (``bench_rollmass_truth.py --runs 30``) was redone on
    forward differences (27 s CPU at stop 54) because its exact joint start from the fitted ship reached
    ``LM_NFEV_EXACT``. Going on from that LM's point, the exact path converges to the redo's load (+8.77 %, +19.8 mm
    at stop 54) in 126 residual evaluations (measured; the redo's LMs ran to their cap of 200 each, 16 residuals
    a forward-difference Jacobian besides)."""
    from benchmarks import bench_rollmass_truth as bench  # noqa: F401  (one BLAS thread, as the bench)
    from identify.rollmass.api import estimate_from_files
    from tests.physics import basin_truth as bt

    ship, data = bt.simulate_runs("base", 30, bt.variant_seed(2015, "base"))
    m_true, z_true = bt.truth_load("case1")
    with tempfile.TemporaryDirectory() as d:
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv", True) for r in bt.case_recordings(ship, data, "case1", 2)]
        e = estimate_from_files(*paths, method="oe")
    p = e.fit_path
    assert e.converged and p.path == "exact" and p.redo is None
    assert (fit.LM_NFEV_EXACT, 0) in p.exact.lm  # the redo-prone case: an exact LM at its cap
    assert p.exact.residuals < 200 and p.exact.jacobians < 150
    assert 100 * (e.m / m_true - 1) == pytest.approx(8.77, abs=0.1)
    assert 1000 * (e.zbar_m - z_true) == pytest.approx(19.8, abs=0.3)


def _coloured_then_whitened(seed: int = 7, n: int = 4000) -> tuple[list[np.ndarray], list[list[np.ndarray]]]:
    """A stage's errors as ``_Problem.errors`` gives them: raw AR(1) errors (pole 0.8, a wave-coloured channel)
    already whitened by the stage's whitener, here the exact one, so what reaches ``_reweighted`` is white."""
    rng = np.random.default_rng(seed)
    white = rng.standard_normal((n, 3)) * np.array([1.0, 3.0, 0.5])
    raw = lfilter([1.0], [1.0, -0.8], white, axis=0)
    old = np.array([1.0, -0.8])
    return [lfilter(old, [1.0], raw, axis=0)], [[old] * 3]


def test_errors_white_after_the_stages_whitener_get_their_own_sd_as_innovation_sd():
    # stop 61: the legacy sd applied the composite whitener (new factor * old) to errors the old one had already
    # whitened, the old whitener twice: here sqrt(1 + 0.8^2) = 1.28 times the innovation sd, channel by channel (fails
    # on main's code of stop 61, INNOVATION_SD "legacy" its default)
    errs, old = _coloured_then_whitened()
    ar, sd, w = fit._reweighted(errs, old, 2)
    np.testing.assert_allclose(sd[0], errs[0].std(axis=0), rtol=0.01)
    np.testing.assert_allclose(w, 1.0 / sd)
    # the whiteners returned are still the composite for the raw error: the old factor times a near-identity new one
    assert all(len(a) == 4 for a in ar[0])
    for a in ar[0]:
        np.testing.assert_allclose(a[:2], old[0][0], atol=0.05)


def test_the_innovation_sd_before_any_whitener_is_the_new_factors_on_the_raw_error():
    # stage 1 (no whitener yet): the sd is the error's own after the stage's new AR(2) factor, which removes the AR(1)
    # colour: the white drive's sd (1, 3, 0.5), not the coloured error's (1 / sqrt(1 - 0.8^2) = 1.67 times that)
    rng = np.random.default_rng(7)
    raw = lfilter([1.0], [1.0, -0.8], rng.standard_normal((4000, 3)) * np.array([1.0, 3.0, 0.5]), axis=0)
    ar, sd, _ = fit._reweighted([raw], None, 2)
    np.testing.assert_allclose(sd[0], [1.0, 3.0, 0.5], rtol=0.04)
    assert all(len(a) == 3 for a in ar[0])
