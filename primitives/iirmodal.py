"""An IIR filter's block products in its modal (parallel first-order) form, for the designs whose
companion-form blocks round into growth (:func:`primitives.iir._blockable` false: clustered poles near
z = 1, e.g. ``shiptrial mass``'s 2nd-order 0.1-0.45 Hz band-pass at 50 Hz), which
:mod:`primitives.iir` otherwise filters sample by sample in Python. Opt-in: only callers that pass
``modal=True`` to :func:`primitives.iir.filtfilt` / :func:`~primitives.iir.lfilter` (mass's sign and
role checks, whose output feeds a verdict, never an estimate) reach it (stop 53).

The normalised filter ``H(z) = B(z) / A(z)`` with distinct poles ``p_i`` is, by partial fractions
(Oppenheim & Schafer, *Discrete-Time Signal Processing*, 3rd ed., 6.3.3, the parallel form),

    H(z) = b_0 + sum_i r_i z^-1 / (1 - p_i z^-1),   r_i = N(p_i) / A'(p_i),

with ``N(z) = sum_{k>=1} (b_k - b_0 a_k) z^(n-k)`` (the transposed direct form II's input vector) and
``A(z) = z^n + a_1 z^(n-1) + ... + a_n``. Each mode is a complex first-order recursion
``s_i[k+1] = p_i s_i[k] + r_i x[k]``, ``y[k] = b_0 x[k] + Re sum_i s_i[k]``: its state matrix is
diagonal, so the block-to-block step ``s' = p^L s + G x`` only decays (no rounding growth). The
transposed direct form II state ``z`` (scipy's ``zi``) has the zero-input response
``Y(z) = sum_k z_k z^-k / A(z)``, so the modal state is ``s_i = M_z(p_i) / A'(p_i)`` with
``M_z(p) = sum_k z_k p^(n-1-k)``: one matrix ``R`` maps ``zi`` (and ``N``'s coefficients) to the modes.

The poles are ``numpy.roots`` polished by three Newton steps, and ``R``, the residues and the powers
``p^j`` are formed in :data:`EXT` (``numpy.longdouble``: 80-bit on x86-64), then rounded once to
complex128. Accuracy, measured (``benchmarks/bench_iir_modal_accuracy.py``; tests/test_iirmodal.py
pins it): the largest error from a state over a 3,000-sample random walk's output peak, against
scipy's loop run in x86-64's longdouble:

- x86-64: mass's 0.1-0.45 Hz band at 50 Hz 2.3e-13 (scipy's double loop 8.7e-11), its 0.1-2.0 Hz
  band 9.1e-13 (scipy 3.9e-12); the 0.1-0.45 Hz band at 100 Hz 8.9e-12 (scipy 8.6e-10).
- where ``numpy.longdouble`` is double (Windows, macOS arm64; measured with :data:`EXT`, :data:`CEXT`
  patched to float64, complex128): 6.0e-10 (0.1-0.45 Hz at 50 Hz), 7.7e-12 (0.1-2.0 Hz at 50 Hz),
  1.3e-9 (0.1-0.45 Hz at 100 Hz): up to 10 times scipy's error, still far below what the checks
  judge (correlations against 0.4, ratios against 3): ``shiptrial mass`` prints byte-identical text
  and ``--json`` either way on the example (docs/mass-accuracy.md, stop 53).
  :func:`primitives.iir._modal_blocks` refuses a form more than 1e-7 off the loop on its probe.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

#: the extended precision the poles, residues and powers are formed in (module docstring); module
#: constants so that tests can measure the form where ``numpy.longdouble`` is double
EXT, CEXT = np.longdouble, np.clongdouble


def lower_toeplitz(h: np.ndarray) -> np.ndarray:
    """The (L, L) lower-triangular Toeplitz matrix of the impulse response ``h`` (L,): a block's forced
    response is it times the block's inputs (both block forms, :func:`primitives.iir._blocks` too)."""
    length = len(h)
    toeplitz = np.zeros((length, length))
    for j in range(length):
        toeplitz[j:, j] = h[: length - j]
    return toeplitz


def _poles(a: np.ndarray) -> np.ndarray:
    """The roots of ``a`` (highest power first) in extended precision: ``numpy.roots`` (the companion
    matrix's eigenvalues) then three Newton steps on ``a`` evaluated in :data:`EXT`."""
    p = np.roots(a).astype(CEXT)
    a_ext = a.astype(EXT)
    slope = np.polyder(a_ext)
    for _ in range(3):
        p = p - np.polyval(a_ext, p) / np.polyval(slope, p)
    return p


@lru_cache(maxsize=64)
def modal_blocks(b_bytes: bytes, a_bytes: bytes, length: int) -> tuple[np.ndarray, ...] | None:
    """The block matrices of a normalised filter (``b``, ``a`` float64 bytes, a[0] = 1) in modal form:
    T (L, L) lower-triangular Toeplitz of the impulse response ``h_0 = b_0, h_j = Re sum r_i p_i^(j-1)``;
    O (L, n) ``p_i^j``; G (n, L) ``r_i p_i^(L-1-m)``; P (n,) ``p_i^L``; R (n, n) the map from the
    transposed direct form II state to the modes (module docstring). None when a pole is repeated or
    not inside the unit circle, or a matrix is not finite: no modal form (the caller filters stepwise)."""
    b, a = np.frombuffer(b_bytes), np.frombuffer(a_bytes)
    n = len(a) - 1
    if n == 0 or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return None  # np.roots raises on NaN or inf; main's path then gives scipy's NaN output
    with np.errstate(all="ignore"):
        try:
            p = _poles(a)
        except np.linalg.LinAlgError:  # the companion matrix's eigenvalues did not converge
            return None
        slope = np.polyval(np.polyder(a.astype(EXT)), p)
        if np.any(slope == 0) or not np.all(np.abs(p) < 1):
            return None
        R = p[:, None] ** np.arange(n - 1, -1, -1)[None, :] / slope[:, None]
        r = R @ (b[1:] - a[1:] * b[0]).astype(EXT)
        powers = p[None, :] ** np.arange(length)[:, None]  # (L, n): p_i^j
        h = np.empty(length)
        h[0] = b[0]
        h[1:] = np.real(powers[: length - 1] @ r).astype(np.float64)
        ctrl = (powers[::-1] * r[None, :]).T
        out = tuple(np.ascontiguousarray(m, dtype=np.complex128) for m in (powers, ctrl, p**length, R))
    if not all(np.all(np.isfinite(m)) for m in (h, *out)):
        return None
    return (lower_toeplitz(h), *out)


def modal_products(buf: np.ndarray, blocks: tuple[np.ndarray, ...], z0: np.ndarray | None) -> np.ndarray:
    """The filter over ``buf`` (m, a multiple of L) from the transposed direct form II states ``z0``
    (m, n; zero when None): each block's forced response ``T x``, the modes' states from block to block
    ``s' = P s + G x`` (elementwise P: the modes are independent), and each block's response to its start
    state ``Re(O s)``. Complex products as real ones on the real and imaginary parts (no complex copy of
    the input)."""
    toeplitz, obs, ctrl, power, R = blocks
    length, order = obs.shape
    m, nb = buf.shape[0], buf.shape[1] // length
    xb = buf.reshape(m * nb, length)
    y = (xb @ toeplitz.T).reshape(m, nb, length)
    u = ((xb @ ctrl.real.T) + 1j * (xb @ ctrl.imag.T)).reshape(m, nb, order)
    s = np.empty((m, nb, order), dtype=np.complex128)
    cur = np.zeros((m, order), dtype=np.complex128)
    if z0 is not None:
        cur = np.broadcast_to(z0, (m, order)).astype(np.float64) @ R.T
    for k in range(nb):
        s[:, k] = cur
        cur = cur * power + u[:, k]
    flat = s.reshape(m * nb, order)
    y += (flat.real @ obs.real.T - flat.imag @ obs.imag.T).reshape(m, nb, length)
    return y.reshape(m, nb * length)
