"""The output-error fit's covariance and stationarity check: a central-difference Jacobian, the
Newey-West sandwich covariance of a least-squares fit, its leverage correction and degrees of freedom for
the load, and the load's Gauss-Newton decrement in it (used by :mod:`identify.rollmass.oe_fit`). All from
one QR of the Jacobian a fit (:class:`LoadBasis`), never from ``(J^T J)^-1``."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


def central_jacobian(fun, x: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of ``fun`` at ``x``, step ``eps^(1/3) max(1, |x_j|)``.

    The covariance and the stationarity check need it along the ill-conditioned mass-height ridge:
    on ``mass-sim --case case1 --seed 3`` the fit's own forward-difference Jacobian (step
    ``sqrt(eps)``) gave a sensitivity of the load to z_f of -14.7 kg/m where this one gave -0.66.
    """
    steps = np.finfo(float).eps ** (1 / 3) * np.maximum(1.0, np.abs(x))
    cols = []
    for j, hj in enumerate(steps):
        e = np.zeros_like(x)
        e[j] = hj
        cols.append((fun(x + e) - fun(x - e)) / (2 * hj))
    return np.column_stack(cols)


def bartlett_meat(h: np.ndarray, lags: int) -> np.ndarray:
    """Long-run ``sum_|k|<=L w_k sum_t h_t h_{t+k}^T`` of one dataset's scores ``h`` (n x p), Bartlett
    weights ``w_k = 1 - |k|/(lags+1)`` over ``|k| <= min(lags, n-1)`` samples (Newey & West 1987, eq. 2).
    Summed over every lag at once: ``h^T (K h)``, ``K_ts = w_|t-s|`` the Bartlett band, ``K h`` a
    convolution of each score column with the kernel (one FFT, not a product per lag)."""
    L = min(lags, len(h) - 1)
    kernel = 1.0 - np.abs(np.arange(-L, L + 1)) / (lags + 1)  # a window beyond the data: cut, not rescaled
    Kh = same_convolution(h, kernel)
    return 0.5 * (h.T @ Kh + Kh.T @ h)


def same_convolution(h: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Each column of ``h`` (n, p) convolved with ``kernel`` (odd length), the ``n`` central samples:
    ``scipy.signal.fftconvolve(h, kernel[:, None], mode="same", axes=0)`` by numpy's real FFT, to rounding
    (1e-15 of the largest value, tests/test_rollmass_oe_fit.py), without scipy.signal's import (2 s of CPU)."""
    n, k = len(h), len(kernel)
    size = n + k - 1
    nfft = 1 << (size - 1).bit_length()  # a power of two: numpy's FFT has no fast-length helper
    full = np.fft.irfft(np.fft.rfft(h, nfft, axis=0) * np.fft.rfft(kernel, nfft)[:, None], nfft, axis=0)
    start = (k - 1) // 2
    return full[start : start + n]


def _meat(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """The sandwich's ``S``: each dataset's per-sample scores ``h_t = sum_channels J_t f_t`` in
    :func:`bartlett_meat` (datasets independent); rows after the datasets' (a Gaussian prior, as a
    standardised observation) add ``J_p^T J_p``."""
    S = np.zeros((J.shape[1], J.shape[1]))
    i = 0
    for n in lengths:
        rows = slice(i, i + 3 * n)
        S += bartlett_meat((J[rows] * f[rows, None]).reshape(n, 3, -1).sum(axis=1), lags)
        i += 3 * n
    return S + J[i:].T @ J[i:]


# the largest 1/sin of the angle between a load column of the Jacobian and the span of the columns before it
# (LoadBasis.kappa) for which a variance is computed: Householder QR is column-wise backward stable (Higham 2002,
# thm. 19.4), so rounding moves the load's variance by about eps * kappa relative, 2e-7 here; beyond it the data
# do not resolve the load from the other parameters to rounding (UnresolvedLoad)
LOAD_KAPPA_MAX = 1e9


class UnresolvedLoad(np.linalg.LinAlgError):
    """The load's Jacobian columns are numerically dependent on the others (:data:`LOAD_KAPPA_MAX`): no variance.
    A ``LinAlgError``, as a singular ``J^T J`` was, so that callers catching that catch this."""


@dataclass(frozen=True, eq=False)  # numpy arrays: no == or hash
class LoadBasis:
    """A fit's Jacobian ``J`` (rows: each dataset's samples x 3 channels, then prior rows; the load ``m``,
    ``zbar_m`` its last two columns) with its QR factors ``J = Q R`` (Golub & Van Loan 2013, sec. 5.2.2): what the
    load's interval and stationarity check need, without ``A^-1 = (J^T J)^-1``, whose condition number is
    ``cond(J)^2`` (1.2e19 on a basin-truth waves fit, stop 51). Made once per Jacobian by :func:`load_basis`."""

    J: np.ndarray
    Q: np.ndarray  # (rows, p), orthonormal columns spanning J's
    R: np.ndarray  # (p, p), upper triangular

    @property
    def kappa(self) -> np.ndarray:
        """``|J_j| / |R_jj|`` of the load's two columns: ``1 / sin`` of each one's angle to the span of the columns
        before it, by which rounding in ``J`` is magnified in the load's variance (inf: a column in that span)."""
        d = np.abs(np.diag(self.R)[-2:])
        return np.divide(np.linalg.norm(self.J[:, -2:], axis=0), d, out=np.full(2, np.inf), where=d > 0)

    @cached_property
    def u(self) -> np.ndarray:
        """``u_j = J a_j`` (rows, 2), ``a_j = A^-1 e_j`` for the load's columns ``j``: ``a_j = R^-1 R^-T e_j`` and
        the last two rows of ``R^-1`` are ``[0, R_ll^-1]`` (``R_ll`` the trailing 2 x 2 block), so ``u = Q_l
        R_ll^-T``, ``Q_l`` the last two columns of ``Q``. Raises :class:`UnresolvedLoad` past :data:`LOAD_KAPPA_MAX`."""
        kappa = self.kappa
        bad = [name for name, k in zip(("m", "zbar_m"), kappa) if not k <= LOAD_KAPPA_MAX]
        if bad:
            raise UnresolvedLoad(
                f"the data do not resolve the load from the other parameters (the Jacobian column of "
                f"{' and '.join(bad)} is within sin {1 / np.max(kappa):.1e} of the span of the columns before it, "
                f"1/sin {np.max(kappa):.2g} > {LOAD_KAPPA_MAX:.0e}): no interval"
            )
        return np.linalg.solve(self.R[-2:, -2:], self.Q[:, -2:].T).T

    @property
    def var(self) -> np.ndarray:
        """``(A^-1)_jj`` of the load, ``|R_ll^-T e_j|^2``."""
        return np.sum(np.linalg.inv(self.R[-2:, -2:]) ** 2, axis=1)


def load_basis(J: np.ndarray) -> LoadBasis:
    """The Jacobian's :class:`LoadBasis` (one QR, numpy's reduced ``qr``: Householder, LAPACK ``dgeqrf``)."""
    if J.shape[0] < J.shape[1]:  # a wide J's reduced R is not square: its trailing block is not the load's
        raise UnresolvedLoad(f"{J.shape[0]} residuals for {J.shape[1]} parameters: the load is not resolved, no interval")
    Q, R = np.linalg.qr(J)
    return LoadBasis(J, Q, R)


def sandwich_cov(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """Sandwich (Huber-White, Newey-West) covariance ``A^-1 S A^-1`` of a least-squares fit, ``A = J^T J``,
    ``S`` from :func:`_meat` (a prior row adds its information ``1/sd^2``). Unlike ``s^2 A^-1`` it
    allows for residuals that stay correlated after the whitening (unmodelled dynamics); it does not
    allow for a bias. Formed as ``R^-1 S_Q R^-T`` (``J = Q R``, ``S_Q`` the meat of ``Q``: ``_meat`` is
    bilinear in the columns and ``J R^-1 = Q``), never ``A^-1``: the error is ``eps cond(J)``, not ``eps cond(J)^2``.
    """
    Q, R = np.linalg.qr(J)
    Rinv = np.linalg.solve(R, np.eye(len(R)))  # LU of a triangular R: no row swaps, back substitution in effect
    return Rinv @ _meat(Q, f, lengths, lags) @ Rinv.T


def load_decrement(basis: LoadBasis, f: np.ndarray, lengths: list[int], lags: int) -> float:
    """Squared length ``d^T C^-1 d`` of the load part ``d = dx[-2:]`` (``m``, ``zbar_m``, the last two
    parameters) of the Gauss-Newton step ``dx = -(J^T J)^-1 J^T f``, in the load's sandwich covariance
    ``C`` (:func:`sandwich_cov`) over ``lags``: how far a further step would move the reported load, in its standard
    errors over that window (the fit passes the stationarity check's, ``output_error.SANDWICH_LAG_S`` = 5 s; the
    reported interval's, ``INTERVAL_LAG_S`` = 20 s since stop 62, is wider). With white, unit-variance residuals and every parameter counted it is the
    Newton decrement (Boyd & Vandenberghe 2004, sec. 9.5.1), the step in ``(J^T J)^-1``; that metric
    is not the interval's when the residual is structure rather than noise, and on a noise-free basin
    run (base, case 1) it was 0.13 where the load's step was 0.055 of its reported sd. NaN when the
    covariance is singular (then not stationary).

    ``d`` is the load's part of the step the fit's finisher takes (``lstsq``'s, whose SVD cut drops directions with
    singular values under ``eps * rows`` of the largest); ``C^-1 = R_ll^T S_l^-1 R_ll`` (:class:`LoadBasis`: ``C =
    R_ll^-1 S_l R_ll^-T``, ``S_l`` the meat of ``Q_l``, :func:`_meat` being bilinear in the columns), so the
    decrement is ``y^T S_l^-1 y``, ``y = R_ll d``: no inverse of ``R`` or ``A``. The exact step's ``d = -R_ll^-1
    Q_l^T f`` would give ``g^T S_l^-1 g``, ``g = Q_l^T f``; at a basin-truth waves fit's end (cond(A) 1.2e19) the cut step's
    decrement is 1.5e-4 where the exact one is 0.0119, along a nuisance ridge that 10 exact steps do not finish
    (docs/mass-accuracy.md, stop 52): kept as main's, the fit's verdict unchanged."""
    d = -np.linalg.lstsq(basis.J, f, rcond=None)[0][-2:]
    y = basis.R[-2:, -2:] @ d
    try:
        return float(y @ np.linalg.solve(_meat(basis.Q[:, -2:], f, lengths, lags), y))
    except np.linalg.LinAlgError:  # a singular meat: no interval to measure in
        return float("nan")


@dataclass(frozen=True, eq=False)  # numpy arrays: no == or hash
class LoadMoments:
    """The load's (``m``, ``zbar_m``) meat moments under the white working error (:func:`load_moments`)."""

    ev: np.ndarray  # E[V_j]
    t2: np.ndarray  # tr((W_j (I - H))^2)
    var: np.ndarray  # (A^-1)_jj

    @property
    def rho(self) -> np.ndarray:
        """How much of the load's Newey-West meat the fitted residual keeps, ``rho_j = E[a_j^T S a_j] / Var``,
        under a white, unit-variance working error.

        The meat is built from the fitted residual ``f = (I - H) e``, ``H = J A^-1 J^T``: the share of the
        disturbance in the span of the Jacobian (every nuisance parameter's column) is gone from it, and the
        Bartlett window's cross-products lose it with it (Kiefer & Vogelsang 2005 give the location model's
        ``1 - b + b^2/3``, ``b`` = window / record). With ``E[f f^T] = I - H``, ``u = J a_j`` and ``K`` the Bartlett
        band over time (channels summed, as :func:`_meat`): ``E[a_j^T S a_j] = u^T u - tr(A^-1 M_j)`` with ``M_j =
        sum_ts w_|t-s| q_t q_s^T``, ``q_t = sum_channels J_t u_t``, and ``Var = (A^-1)_jj``; the prior rows are exact
        and cancel. The HAC analogue of MacKinnon & White's (1985) HC2 and of Bell & McCaffrey's (2002)
        bias-reduced cluster meat, as a factor on the load's variance. On one basin-truth ship fitted on 16 seas
        (docs/mass-accuracy.md, stop 51) it was 0.85 and 0.81 where the meat from the fitted residual over the meat
        from the sea's own response at fixed parameters was 0.86-0.88 and 0.81-0.83."""
        return self.ev / self.var

    @property
    def dof(self) -> np.ndarray:
        """Satterthwaite degrees of freedom ``nu_j = 2 E[V_j]^2 / Var[V_j] = E[V_j]^2 / tr((W_j (I-H))^2)`` of the
        load's meat ``V_j``, Gaussian working error (``Var[f^T W f] = 2 tr((W Sigma)^2)``): the second half of Bell &
        McCaffrey (2002), whose interval takes ``t_{0.975, nu}`` for 1.96. Few effective windows in the record (a
        long Bartlett window, a load driven by a few slow components) give a small ``nu``, a meat that varies from
        sea to sea, and a wider interval."""
        t2 = self.t2
        # nu >= 1 for a PSD W ((tr B)^2 >= tr B^2): below it is rounding, not information
        return np.where(t2 > 0, np.maximum(self.ev * self.ev / np.where(t2 > 0, t2, 1.0), 1.0), np.inf)


def load_moments(basis: LoadBasis, lengths: list[int], lags: int) -> LoadMoments:
    """For the load parameters ``j`` = ``m``, ``zbar_m`` (``u = J a_j``, :attr:`LoadBasis.u`): ``E[V]``,
    ``tr((W (I-H))^2)`` and ``Var = (A^-1)_jj``, ``V = a^T S a = f^T W f + u_p^T u_p`` the meat under the working
    model ``E[f f^T] = I - H`` (white unit error), ``W_(tc),(sd) = u_tc w_|t-s| u_sd`` per dataset (channels ``c``,
    ``d``; the Bartlett band ``K``), ``u_p`` the prior rows (constant: exact, no variance).

    In the orthonormal basis ``Q`` (``H = Q Q^T``; no ``A^-1`` of an ill-conditioned ``A``: its cancellations cost
    a waves fit ``nu`` < 1, impossible for a PSD ``W``): ``q_t = sum_c Q_tc u_tc``, ``U_t = sum_c u_tc^2``, ``M =
    sum_ts w q_t q_s^T = Q^T W Q``; then ``E[V] = u^T u - tr(M)``, ``tr(W W) = U^T K^(2) U`` (squared weights),
    ``tr(W H W) = tr((K q)^T diag(U) (K q))``, ``tr(W H W H) = |M|_F^2``: no n x n matrix, one convolution per
    dataset (tests/test_rollmass_sandwich_dof.py checks the dense one)."""
    Q, p = basis.Q, basis.Q.shape[1]
    ev, t2 = np.empty(2), np.empty(2)
    for k in range(2):
        u = basis.u[:, k]
        M, trG, ww, i = np.zeros((p, p)), 0.0, 0.0, 0
        for n in lengths:
            rows = slice(i, i + 3 * n)
            q = (Q[rows] * u[rows, None]).reshape(n, 3, -1).sum(axis=1)
            U = (u[rows] ** 2).reshape(n, 3).sum(axis=1)
            L = min(lags, n - 1)
            kernel = 1.0 - np.abs(np.arange(-L, L + 1)) / (lags + 1)  # as bartlett_meat's
            Kq = same_convolution(q, kernel)
            M += 0.5 * (q.T @ Kq + Kq.T @ q)
            trG += float(np.einsum("ti,t,ti->", Kq, U, Kq))
            ww += float(U @ same_convolution(U[:, None], kernel**2)[:, 0])
            i += 3 * n
        ev[k], t2[k] = u @ u - np.trace(M), ww - 2.0 * trG + float(np.sum(M * M))
    return LoadMoments(ev, t2, basis.var)


@dataclass(frozen=True, eq=False)  # numpy arrays: no == or hash
class LoadInterval:
    """What the fit reports of the load's (``m``, ``zbar_m``) uncertainty, from one :class:`LoadBasis`."""

    plain: np.ndarray  # (2, 2) the sandwich's load block (sandwich_cov's)
    cov: np.ndarray  # (2, 2) the reported one: plain, each sd over sqrt(rho)
    rho: np.ndarray  # (2,) the leverage factors (LoadMoments.rho)
    dof: np.ndarray  # (2,) the Satterthwaite degrees of freedom (LoadMoments.dof)


def load_interval(basis: LoadBasis, f: np.ndarray, lengths: list[int], lags: int) -> LoadInterval:
    """The load's covariance and degrees of freedom from one QR of the Jacobian. The plain sandwich's load block is
    ``a_j^T S a_k`` = the meat of ``u`` (:func:`_meat` of the two columns ``u = J a``, :attr:`LoadBasis.u`); the
    reported one divides each sd by ``sqrt(rho)`` (:attr:`LoadMoments.rho`, :func:`leverage_scale`), the
    correlation kept (a symmetric scaling: it stays positive semi-definite). Only the reported interval uses it;
    the stationarity check (:func:`load_decrement`) keeps the plain sandwich, so the fit stops where it did.
    Raises :class:`UnresolvedLoad` when the data do not resolve the load to rounding."""
    plain = _meat(basis.u, f, lengths, lags)
    moments = load_moments(basis, lengths, lags)
    s = leverage_scale(moments.rho)
    return LoadInterval(plain, plain * np.outer(s, s), moments.rho, moments.dof)


def load_cov(J: np.ndarray, f: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """:attr:`LoadInterval.cov` of ``J`` (one QR; the fit calls :func:`load_interval` on the basis it has: this one
    is for the tests' and benchmarks' wrappers, which take a Jacobian)."""
    return load_interval(load_basis(J), f, lengths, lags).cov


def leverage_factors(J: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """:attr:`LoadMoments.rho` of ``J`` (one QR; for tests and benchmarks)."""
    return load_moments(load_basis(J), lengths, lags).rho


def load_dof(J: np.ndarray, lengths: list[int], lags: int) -> np.ndarray:
    """:attr:`LoadMoments.dof` of ``J`` (one QR; for tests and benchmarks)."""
    return load_moments(load_basis(J), lengths, lags).dof


# the smallest leverage factor :func:`leverage_scale` divides by: below it almost no meat is left to scale
LEVERAGE_MIN = 0.05


def leverage_scale(rho: np.ndarray) -> np.ndarray:
    """The factor on each load sd, ``1 / sqrt(rho)`` with ``rho`` (:attr:`LoadMoments.rho`) clipped to
    [:data:`LEVERAGE_MIN`, 1] (``rho`` <= 1 for a PSD meat; the upper clip guards rounding)."""
    return 1.0 / np.sqrt(np.clip(rho, LEVERAGE_MIN, 1.0))


# the largest AR(1) coefficient :func:`andrews_lags` plugs in: at 1 its formula's bandwidth is infinite (a unit root
# in a score, not a long-run variance); 0.99 bounds the window at about 1.1447 (4 * 0.99^2 / 0.01^2 / 1.99^2 n)^(1/3)
ANDREWS_RHO_MAX = 0.99


def andrews_lags(basis: LoadBasis, f: np.ndarray, lengths: list[int], block: int = 1) -> int:
    """The Bartlett window's lags (samples) by Andrews' (1991) AR(1) plug-in, on the load's score series: for each
    dataset and load parameter ``j`` the per-sample score ``h_t = sum_channels u_tc f_tc`` (``u = J a_j``,
    :attr:`LoadBasis.u`; the series :func:`_meat` of ``u`` sums), its least-squares AR(1) ``rho_a`` and innovation
    variance ``s_a^2``; ``alpha(1) = sum_a 4 rho_a^2 s_a^4 / ((1 - rho_a)^6 (1 + rho_a)^2) / sum_a s_a^4 / (1 -
    rho_a)^4`` (Andrews 1991, eq. 6.4, unit weights) and the bandwidth ``S_T = 1.1447 (alpha(1) T)^(1/3)`` (eq. 6.2,
    Bartlett kernel, ``T`` the mean dataset length), whose weights ``1 - k / S_T`` are :func:`bartlett_meat`'s ``1 - k
    / (lags + 1)``: ``lags = round(S_T) - 1``, at least 1 and below the shortest dataset.

    ``block`` > 1 applies the rule to the scores summed over blocks of that many samples (their long-run variance is
    the samples', ``block`` times): an AR(1) of the samples sees only the lag-1 correlation, which a whitened residual
    leaves near 0 at 50 Hz however slow the errors that remain (stop 62); ``S_T`` is then in blocks, ``block`` times
    as many samples."""
    u = basis.u
    num = den = 0.0
    i = 0
    for n in lengths:
        h = (u[i : i + 3 * n] * f[i : i + 3 * n, None]).reshape(n, 3, 2).sum(axis=1)
        h = h[: n - n % block].reshape(-1, block, 2).sum(axis=1)
        for a in h.T:
            x, y = a[:-1], a[1:]
            rho = float(np.clip(x @ y / max(x @ x, 1e-300), -ANDREWS_RHO_MAX, ANDREWS_RHO_MAX))
            s4 = float(np.mean((y - rho * x) ** 2)) ** 2
            num += 4 * rho * rho * s4 / ((1 - rho) ** 6 * (1 + rho) ** 2)
            den += s4 / (1 - rho) ** 4
        i += 3 * n
    s_t = block * 1.1447 * (num / max(den, 1e-300) * float(np.mean(lengths)) / block) ** (1 / 3)
    return int(min(max(round(s_t) - 1, 1), min(lengths) - 1))
