"""The output-error fit's Jacobian from the sensitivity equations, in the modal coordinates the
simulation runs in (used by :mod:`identify.rollmass.output_error`).

A dataset's response to each input (the rudder; a known heel signal; they add) is the discrete model ``x(k+1) = Ad x(k) + Bd u(k)``,
``y = Cd x + Dd u``; in the modal coordinates ``z = V^-1 x`` (``Ad V = V Lambda``) each mode is the
first-order filter ``F_i = 1 / (q - lambda_i)``, ``z_i = b_i F_i u`` with ``b = V^-1 Bd``. A parameter
``theta`` moves ``(Ad, Bd, Cd, Dd)``; the state's sensitivity obeys the forward sensitivity equation
``dx(k+1) = Ad dx(k) + dAd x(k) + dBd u(k)`` (e.g. Ljung 1999, sec. 10.3), in modal coordinates

    dz_i = sum_j E_ij b_j F_i F_j u + f_i F_i u,   E = V^-1 dAd V,  f = V^-1 dBd,
    F_i F_j = (F_i - F_j) / (lambda_i - lambda_j)  (i != j, partial fractions),

so every parameter's output sensitivity ``dy = Re(c dz + dc z) + dDd u`` (``c = Cd V``,
``dc = dCd V``) is a combination of the same few filtered signals ``F_i u`` and ``F_i F_i u``:
two filter passes a mode, however many parameters (off the diagonal, ``sum_ij k_ij F_i F_j u``
is ``sum_i F_i u sum_j (k_ij + k_ji) / (lambda_i - lambda_j)``). The IMU's lag moves the input itself
(:func:`lag_derivative`) and takes one more pass a mode. The residual projects the free response
out (variable projection); its derivative carries the basis's own (Golub & Pereyra 1973, eq. 5.3):
with ``B`` the whitened basis ``Q R``, ``P = I - Q Q^T``, ``beta = B^+ W e`` and ``r = P W e``,

    d r = -P W dy - P dB beta - Q R^-T dB^T r,

and ``dB`` is the whitened ``k lambda_i^(k-1) dlambda_i``, ``dlambda_i = E_ii``.

Only ``(Ad, Bd, Cd, Dd)``'s derivatives are finite differences (central, of 4x4 matrices: smooth,
about 1e-10 relative); the model equations stay where they are (``output_error.model_matrices``)
and this module never sees them: a change of the equations or a new parameter that enters them
needs nothing here. What is mirrored here, and must change with ``output_error`` if it changes:
the inputs (``output_error.model_inputs``: the rudder delayed by ``t_imu``, ``output_error.delayed``, whose
derivative is :func:`lag_derivative`, a known heel signal, and the speed's turn and sway inputs, signals held fixed
within a fit's stage, each through its column of ``Bd``), the simulation from rest in modal form, the free-response basis
(:func:`free_basis`), and the residual's per-channel whitening, projection and weights
(``_Problem.errors``, ``weighted``). tests/test_rollmass_oe_jacobian.py checks every column against
central differences of the whole residual (agreement to about 1e-6 of a column), so a change on one
side only fails there.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg import solve_triangular

Matrices = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Inputs = list[tuple[int, np.ndarray]]  # (column of Bd and Dd, input signal)


def fir(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``lfilter(a, [1.0], x, axis=0)`` (zero initial conditions) as a sum of shifted copies: scipy
    filters a 2-D array by an FIR one column at a time (``apply_along_axis``): 13 % of a profiled fit."""
    y = a[0] * x
    for k in range(1, min(len(a), len(x))):
        y[k:] += a[k] * x[:-k]
    return y


def basis_modes(lam: np.ndarray) -> list[int]:
    """The modes whose powers span the free response: every real one and one of each conjugate pair."""
    return [i for i, li in enumerate(lam) if li.imag >= 0.0]


def mode_powers(lam: np.ndarray, n: int) -> np.ndarray:
    """``lambda_i^k`` (n, modes of :func:`basis_modes`), complex. A pair's powers in polar form,
    ``|lambda|^k (cos k theta + i sin k theta)``: numpy's complex power of an integer array
    (``lambda**k``) took 2.6 ms of 3,000 samples against 0.4 ms, and the polar form is the closer
    to the exact power of the two (relative error 4e-16 against 3e-14 at ``|lambda| = 0.9994``)."""
    k = np.arange(n)
    cols = []
    for i in basis_modes(lam):
        li = lam[i]
        if li.imag == 0.0:
            cols.append((li.real**k).astype(complex))
        else:
            ang = k * np.angle(li)
            cols.append(abs(li) ** k * (np.cos(ang) + 1j * np.sin(ang)))
    return np.column_stack(cols)


def free_basis(lam: np.ndarray, n: int, pw: np.ndarray | None = None) -> np.ndarray:
    """The free response's span, ``lambda_i^k`` (real and imaginary parts of one of each conjugate
    pair), and a constant (the sensor's bias): (n, 5) for four modes. ``pw``: ``mode_powers(lam, n)``
    when the caller has it already."""
    cols = []
    for i, pk in zip(basis_modes(lam), (mode_powers(lam, n) if pw is None else pw).T):
        cols += [pk.real] if lam[i].imag == 0.0 else [pk.real, pk.imag]
    return np.column_stack(cols + [np.ones(n)])


def modal(Ad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues and eigenvectors of a stable ``Ad`` with distinct modes; raises otherwise (the
    residual then takes its penalty, the Jacobian its finite differences)."""
    lam, V = np.linalg.eig(Ad)
    if not np.all(np.isfinite(lam)) or np.any(np.abs(lam) >= 1.0):
        raise FloatingPointError("unstable model")
    if np.linalg.cond(V) > 1e8:  # (nearly) repeated modes: no well-conditioned modal form
        raise np.linalg.LinAlgError("defective model")
    return lam, V


# samples a block of :func:`_first_order`'s scaled running sums: at most this many, and fewer where a fast
# mode's lambda^-k would exceed MODE_SCALE_MAX within a block
MODE_BLOCK = 256
MODE_SCALE_MAX = 1e150


@lru_cache(maxsize=8)
def _block_powers(lam_bytes: bytes, n: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_first_order`'s block length ``L`` for ``n`` samples and its powers ``lambda^k``, ``lambda^-k``
    (modes, L) and ``lambda^L``, as ``exp(k log lambda)``; cached, as one Jacobian filters the same modes
    five times a dataset."""
    lam = np.frombuffer(lam_bytes, dtype=complex)
    smallest = min(abs(li) for li in lam.tolist()) if len(lam) else 1.0
    if smallest == 0.0:
        L = 1
    else:
        L = MODE_BLOCK if smallest >= 1.0 else int(math.log(MODE_SCALE_MAX) / -math.log(smallest))
    L = max(1, min(L, MODE_BLOCK, n))
    with np.errstate(divide="ignore", invalid="ignore"):  # log 0: a mode at 0 takes only lambda^0
        up = np.exp(np.log(lam)[:, None] * np.arange(L))
    up[:, 0] = 1.0
    return L, up, 1.0 / up, up[:, -1] * lam


def _first_order(lam: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``y_i(0) = 0``, ``y_i(k) = lambda_i y_i(k-1) + x_i(k-1)`` along each row of ``x`` (modes, n), complex.

    Block by block: within a block of ``L`` samples ``y(t) = lambda^t y(0) + lambda^(t-1) sum_(s<t)
    lambda^-s x(s)``, one running sum (O(n) vectorised work; each scaled term is multiplied back, so
    its rounding is relative to the term as in the sample-by-sample recursion), and the block starts
    ``y(0)`` carried from block to block (``n / L`` steps). ``L`` keeps ``|lambda|^-L`` under
    :data:`MODE_SCALE_MAX` (a mode at 0: one sample a block). scipy's ``lfilter([0, 1], [1, -lambda], x)``
    to 2e-15 of the output's peak on the model's modes (tests/test_rollmass_oe_jacobian.py), without
    scipy.signal's import (2 s of CPU)."""
    m, n = x.shape
    L, up, down, step = _block_powers(np.ascontiguousarray(lam, dtype=complex).tobytes(), n)
    nb = -(-n // L)
    buf = np.zeros((m, nb * L), complex)
    buf[:, :n] = x
    run = np.cumsum(buf.reshape(m, nb, L) * down[:, None, :], axis=2)  # sum_(s<=t) lambda^-s x(s), a block
    y = np.empty((m, nb, L), complex)
    y[:, :, 0] = 0.0
    np.multiply(run[:, :, :-1], up[:, None, :-1], out=y[:, :, 1:])
    end = run[:, :, -1] * up[:, -1:]  # each block's own share of the next block's y(0)
    start = np.array([_carry(si, ei) for si, ei in zip(step.tolist(), end.tolist())]).reshape(m, nb)
    y += start[:, :, None] * up[:, None, :]
    return y.reshape(m, nb * L)[:, :n]


def _carry(step: complex, ends: list[complex]) -> list[complex]:
    """The block starts ``c_0 = 0``, ``c_(b+1) = step c_b + end_b`` (Python complex numbers: faster than
    numpy's on a few values)."""
    c, out = 0j, []
    for e in ends:
        out.append(c)
        c = step * c + e
    return out


def mode_filter(lam: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``F_i u``, ``F_i(k) = lambda_i F_i(k-1) + u(k-1)`` from rest, (n, modes) complex, of one real signal
    ``u`` (n,). A real input gives a conjugate pair conjugate outputs: one filter a pair (:func:`_twins`)."""
    own, twin = _twins(lam)
    y = _first_order(lam[own], np.broadcast_to(u, (len(own), len(u))))
    return _with_twins(y, own, twin, len(lam))


def mode_filter_again(lam: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``F_i F_i u`` (n, modes) from ``g = mode_filter(lam, u)``: each mode's filter on its own column of ``g``
    (a pair's columns are conjugates, and so are their outputs)."""
    own, twin = _twins(lam)
    y = _first_order(lam[own], g[:, own].T)
    return _with_twins(y, own, twin, len(lam))


def _twins(lam: np.ndarray) -> tuple[list[int], list[int]]:
    """The modes filtered (every real one and the first of each conjugate pair) and, for every mode, the
    one whose conjugated output it takes (-1: its own): ``np.linalg.eig`` of a real matrix gives a pair
    exactly conjugate."""
    twin = [-1] * len(lam)
    for i, li in enumerate(lam):
        for j in range(i):
            if li.imag != 0.0 and twin[j] < 0 and lam[j] == np.conj(li):
                twin[i] = j
                break
    return [i for i, t in enumerate(twin) if t < 0], twin


def _with_twins(y: np.ndarray, own: list[int], twin: list[int], m: int) -> np.ndarray:
    """(n, m) from the filtered rows ``y`` (own modes, n), each twin its partner's conjugate."""
    out = np.empty((m, y.shape[1]), complex)
    out[own] = y
    for i, j in enumerate(twin):
        if j >= 0:
            out[i] = np.conj(out[j])
    return out.T


def lag_derivative(x: np.ndarray, lag: float, T: float) -> np.ndarray:
    """d/d lag of ``output_error.delayed(x, lag, T) = x - lag x' + lag^2 x'' / 2``."""
    d1 = np.gradient(x, T)
    return -d1 + lag * np.gradient(d1, T)


def _output_sensitivities(
    lam: np.ndarray, V: np.ndarray, mats: Matrices, dmats: list[Matrices], inputs: Inputs, du: np.ndarray | None, lag_col: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The forced response ``y`` (n, 3), every parameter's ``dy`` (3 channels, n, P) and ``E = V^-1 dAd V``
    (P, modes, modes), summed over the ``inputs`` (``(column of Bd, signal)``; a linear model's responses
    add). ``du``: the first input's derivative by the parameter ``lag_col`` (None: none)."""
    Vi = np.linalg.inv(V)
    E = np.einsum("ab,pbc,cd->pad", Vi, np.array([d[0] for d in dmats]), V)
    # what does not depend on the input, once: the output map in modal coordinates, its derivatives,
    # and the partial-fraction weights 1 / (lambda_i - lambda_j) (zero on the diagonal)
    modal_out = (mats[2] @ V, np.einsum("pcb,bi->pci", np.array([d[2] for d in dmats]), V))
    inv = 1.0 / (lam[:, None] - lam[None, :] + np.eye(len(lam)))
    np.fill_diagonal(inv, 0.0)
    y, sigs, weights, lag = 0.0, [], [], None
    for i, (col, u) in enumerate(inputs):
        yi, sig, weight, lag_i = _input_sensitivities(lam, inv, Vi, E, modal_out, mats, dmats, col, u, du if i == 0 else None)
        y, lag = y + yi, lag_i if lag_i is not None else lag
        sigs.append(sig)
        weights.append(weight)
    # every input's signals side by side: one real product a channel, (n, 17 inputs) x (17 inputs, P)
    sig, weight = np.hstack(sigs), np.concatenate(weights, axis=1)
    dy = np.empty((3, len(sig), len(dmats)))
    for ch in range(3):
        np.matmul(sig, weight[ch], out=dy[ch])
    if lag is not None:
        dy[:, :, lag_col] += lag
    return y, dy, E


def _input_sensitivities(
    lam: np.ndarray,
    inv: np.ndarray,
    Vi: np.ndarray,
    E: np.ndarray,
    modal_out: tuple[np.ndarray, np.ndarray],
    mats: Matrices,
    dmats: list[Matrices],
    col: int,
    u: np.ndarray,
    du: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """One input's share of :func:`_output_sensitivities`: ``y`` of the input signal ``u`` entering through
    column ``col`` of ``Bd`` and ``Dd``, its ``dy`` as signals (n, 17) and their weights (3 channels, 17, P)
    (``dy[ch] = signals @ weights[ch]``), and with ``du`` the lag parameter's share (3, n); ``modal_out`` is
    ``(Cd V, dCd V)`` and ``inv`` the partial-fraction weights, both the same for every input."""
    _, Bd, _, Dd = mats
    (c, dc), b, D = modal_out, Vi @ Bd[:, col], Dd[:, col]
    g = mode_filter(lam, u)
    h = mode_filter_again(lam, g)  # F_i F_i u
    f = np.einsum("ab,pb->pa", Vi, np.array([d[1][:, col] for d in dmats]))
    dD = np.array([d[3][:, col] for d in dmats])  # (P, 3)
    cb = c * b  # (3, modes): each mode's residue per channel
    y = (g @ cb.T).real + u[:, None] * D
    # sum_ij F_i F_j u * k_ij, k_ij = c_i E_ij b_j: the diagonal on F_i F_i u, and off it, by partial
    # fractions, sum_i F_i u * sum_j (k_ij + k_ji) / (lambda_i - lambda_j)
    k = np.einsum("ci,pij,j->pcij", c, E, b)
    on_g = np.einsum("pcij,ij->pci", k + k.transpose(0, 1, 3, 2), inv) + c[None] * f[:, None, :] + dc * b[None, None, :]
    on_h = np.einsum("pcii->pci", k)
    # Re(z w) = Re z Re w - Im z Im w: real signals and their weights, (P, 3, modes) -> (3, modes, P)
    sig = np.column_stack([g.real, g.imag, h.real, h.imag, u])
    on_g, on_h = on_g.transpose(1, 2, 0), on_h.transpose(1, 2, 0)
    weight = np.concatenate([on_g.real, -on_g.imag, on_h.real, -on_h.imag, dD.T[:, None, :]], axis=1)
    lag = None if du is None else ((mode_filter(lam, du) @ cb.T).real + du[:, None] * D).T
    return y, sig, weight, lag


def dataset_jacobian(
    mats: Matrices,
    dmats: list[Matrices],
    inputs: Inputs,
    du: np.ndarray | None,
    lag_col: int,
    Y: np.ndarray,
    ar: list[np.ndarray],
    w: np.ndarray,
) -> np.ndarray:
    """One dataset's rows of the fit's Jacobian, (3 n, P) in the residual's order (sample-major,
    channels ``p, a_s, r``): the whitened (``ar``), weighted (``w``) output error with its free
    response and bias projected out per channel, differentiated by every parameter whose discrete
    matrices move by ``dmats`` (and the lag parameter ``lag_col`` by ``du``, the first input's derivative);
    ``inputs`` as ``output_error.model_inputs`` gives them."""
    lam, V = modal(mats[0])
    y, dy, E = _output_sensitivities(lam, V, mats, dmats, inputs, du, lag_col)
    n, P = len(Y), len(dmats)
    e = Y - y
    modes = basis_modes(lam)
    pw = mode_powers(lam, n)
    basis = free_basis(lam, n, pw)
    # d lambda^k / d lambda = k lambda^(k-1): the basis's own derivative, per basis mode
    kpow = np.arange(n)[:, None] * np.vstack([np.zeros((1, len(modes))), pw[:-1]])
    dlam = np.array([E[:, i, i] for i in modes])  # (basis modes, P)
    real = np.array([lam[i].imag == 0.0 for i in modes])
    dlam[real] = dlam[real].real
    J = np.empty((n, 3, P))
    for ch in range(3):
        a = ar[ch]
        Q, R = np.linalg.qr(fir(a, basis))
        We = fir(a, e[:, ch])
        beta = solve_triangular(R, Q.T @ We)
        r = We - Q @ (Q.T @ We)
        Wk = fir(a, kpow)
        # beta's weights of each basis mode's power: a real mode's column, or a pair's (re, im) as re - i im
        gamma, j = [], 0
        for is_real in real:
            gamma.append(beta[j] if is_real else beta[j] - 1j * beta[j + 1])
            j += 1 if is_real else 2
        dB_beta = (Wk @ (np.array(gamma)[:, None] * dlam)).real
        s = (Wk.T @ r)[:, None] * dlam  # (basis modes, P): d(column)^T r as complex
        dBt_r = np.zeros((basis.shape[1], P))
        j = 0
        for m, is_real in enumerate(real):
            dBt_r[j] = s[m].real
            if not is_real:
                dBt_r[j + 1] = s[m].imag
            j += 1 if is_real else 2
        X = fir(a, dy[ch]) + dB_beta
        J[:, ch, :] = -w[ch] * (X - Q @ (Q.T @ X) + Q @ solve_triangular(R, dBt_r, trans="T"))
    return J.reshape(3 * n, P)
