"""IIR filters without :mod:`scipy.signal`: the Butterworth design (lowpass, bandpass, bandstop), its
transposed-direct-form-II initial state, and the filter itself, for the change detector's path and
``shiptrial mass``'s (its sign and heel-reference filters, stop 51).

``import scipy.signal`` costs about 2 s of CPU on the project's VM (it imports scipy.stats), half of
a ``shiptrial detect`` on one recording, which needs a handful of its functions only.

- :func:`butter`: scipy's ``butter(order, wn, btype, fs=fs)`` (Butterworth analog prototype poles
  ``-exp(j pi m / 2N)``, m = -N+1, -N+3, ..., N-1; frequency pre-warping ``4 tan(pi Wn / 2)``;
  lowpass, bandpass or bandstop transform; bilinear transform ``(4 + s) / (4 - s)``; Oppenheim & Schafer,
  *Discrete-Time Signal Processing*, 3rd ed., 7.1.2), in scipy's order of operations: the same bits.
- :func:`lfilter_zi`: the steady state ``(I - A) z = B`` of the transposed direct form II
  (A = companion(a)^T, B = b[1:] - a[1:] b0), solved as scipy solves it: the same bits.
- :func:`lfilter`: y[k] = sum b_j x[k-j] - sum a_j y[k-j] from the state ``zi``, computed block by
  block from the filter's state-space form (z' = A z + B x, y = z_0 + b_0 x): within a block of L
  samples the output is the impulse response's lower-triangular Toeplitz matrix times the block's
  inputs plus C A^j times the state at its start, and the states from block to block are
  s' = A^L s + G x_block. All rows and blocks go through a few matrix products, so a long chain of
  dependent operations per row becomes a short loop over blocks. Not the same bits as scipy's
  sample-by-sample loop: tests/test_iir.py bounds the difference against scipy.signal.lfilter on
  random inputs (relative to the output's largest value: 1e-11 for the detector's narrowest
  low-pass, a 0.05 Hz 2nd-order Butterworth at 10 Hz; 1e-12 for the others). A design whose
  clustered poles the blocks cannot carry (a high order or a low cutoff: the companion form's A^L
  then rounds into growth; a 4th-order low-pass at 1 % of Nyquist was 3e-4 off, a 6th-order one
  overflowed) is found once per design on a probe (:func:`_blockable`) and filtered sample by
  sample in scipy's order of operations instead: scipy's bits, slower. A NaN or inf input makes
  its row NaN from the start of its 64-sample block on (scipy's: from that sample on; the
  forward-backward filter is all NaN either way): rows stay apart.
- ``modal=True`` (:func:`lfilter`, :func:`filtfilt`; stop 53): opt-in, for a caller whose output only
  feeds a check's verdict, never an estimate (``shiptrial mass``'s sign and role checks,
  :mod:`identify.rollmass.signs`, :mod:`identify.rollmass.roles`). A design the companion blocks
  cannot carry then goes through the same blocks in its modal form (:mod:`primitives.iirmodal`:
  partial fractions, a diagonal state step) instead of sample by sample: not scipy's bits (on
  x86-64 nearer the exact filter than scipy's loop on mass's 50 Hz band-passes; where longdouble is
  double up to 10 times scipy's error: accuracy in :mod:`primitives.iirmodal`), 6 times faster (1.2 against 7.5 ms a forward-backward pass of 3,286
  samples, ``benchmarks/bench_iir_forms.py``). A design with no modal form (repeated poles,
  non-finite coefficients, :func:`primitives.iirmodal.modal_blocks`) or one whose modal form is
  more than :data:`MODAL_TOLERANCE` of the peak off the loop on the probe (near-repeated poles;
  a check in double precision: the same choice on every platform for mass's designs at 10-200 Hz)
  stays on the loop. Without it (the default: ``detect``, ``yawid``,
  :mod:`primitives.zerophase`, ``diagnose``, every other caller) the paths above, unchanged.
- :func:`filtfilt`: forward-backward filtering with scipy's odd (default) or even padding of
  3 max(len(a), len(b)) samples and initial state ``zi x_0`` for each pass.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from primitives import iirmodal
from primitives.threads import one_blas_thread

#: samples per block of :func:`lfilter`: the Toeplitz product costs L multiply-adds a sample, the
#: loop over blocks n / L steps of a few small products; 64 rather than 32 (about as fast): fewer
#: block-to-block steps, 30 times less rounding on a 4th-order 0.5 Hz low-pass at 10 Hz
BLOCK = 64
# the block products run on one BLAS thread (:func:`primitives.threads.one_blas_thread`): they are narrow (at
# most 64 + 4 columns), and a second OpenBLAS thread spent more CPU than it saved (400 rows x 5,090 samples,
# 4th order: 0.08 s CPU a pass with two threads, 0.03 s with one; scipy's loop 0.016 s); the process's other
# BLAS calls meanwhile run on one thread too


def _poly(roots: np.ndarray) -> np.ndarray:
    """scipy.signal._polyutils.poly (1-D np.poly by repeated convolution; real when the roots are
    conjugate pairs)."""
    a = np.ones((1,), dtype=roots.dtype)
    one = np.ones_like(roots[0])
    for zero in roots:
        a = np.convolve(a, np.stack((one, -zero)), mode="full")
    if np.iscomplexobj(a):
        r = np.asarray(roots, dtype=np.complex128)
        if np.all(np.sort(np.imag(r)) == np.sort(np.imag(np.conj(r)))):
            a = np.real(a).copy()
    return a


def butter(order: int, wn: float | tuple[float, float], btype: str = "lowpass", fs: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the digital Butterworth filter: ``scipy.signal.butter(order, wn, btype, fs=fs)`` for
    btype 'lowpass' ('low'), 'bandpass' ('band', 'pass') or 'bandstop' ('stop'), the same bits (module
    docstring; scipy's lp2lp_zpk, lp2bp_zpk, lp2bs_zpk and bilinear_zpk in their order of operations)."""
    kinds = {"low": "lowpass", "lowpass": "lowpass", "band": "bandpass", "pass": "bandpass", "bandpass": "bandpass"}
    kind = {**kinds, "stop": "bandstop", "bandstop": "bandstop"}.get(btype)
    if kind is None:
        raise ValueError(f"butter: btype {btype!r} not implemented (lowpass, bandpass or bandstop)")
    n = int(order)
    if n < 1 or n != order:
        raise ValueError("butter: the order must be a positive integer")
    w = np.asarray(wn, dtype=np.float64) / (fs / 2)
    if np.any(w <= 0) or np.any(w >= 1):
        raise ValueError(f"butter: critical frequencies must be 0 < Wn < fs/2 (fs={fs})")
    m = np.arange(-n + 1, n, 2, dtype=np.float64)
    p = -np.exp(1j * np.pi * m / (2 * n))  # the analog prototype's poles (no zeros, gain 1)
    z = np.asarray([], dtype=np.float64)
    k = 1.0
    warped = 2 * 2.0 * np.tan(np.pi * w / 2.0)
    if kind == "lowpass":
        if w.size != 1:
            raise ValueError("butter: a lowpass takes one critical frequency")
        wo = float(warped)
        z, p, k = wo * z, wo * p, k * wo ** (len(p) - len(z))
    else:
        if w.size != 2 or not w[0] < w[1]:
            raise ValueError(f"butter: a {kind} takes two increasing critical frequencies")
        bw, wo = float(warped[1] - warped[0]), float(np.sqrt(warped[0] * warped[1]))
        degree = len(p) - len(z)
    if kind == "bandpass":
        z_lp = (z * bw / 2).astype(np.complex128)
        p_lp = (p * bw / 2).astype(np.complex128)
        z_bp = np.concatenate((z_lp + np.sqrt(z_lp**2 - wo**2), z_lp - np.sqrt(z_lp**2 - wo**2)))
        p_bp = np.concatenate((p_lp + np.sqrt(p_lp**2 - wo**2), p_lp - np.sqrt(p_lp**2 - wo**2)))
        z, p, k = np.concatenate((z_bp, np.zeros(degree))), p_bp, k * bw**degree
    elif kind == "bandstop":
        z_hp = ((bw / 2) / z).astype(np.complex128)
        p_hp = ((bw / 2) / p).astype(np.complex128)
        z_bs = np.concatenate((z_hp + np.sqrt(z_hp**2 - wo**2), z_hp - np.sqrt(z_hp**2 - wo**2)))
        p_bs = np.concatenate((p_hp + np.sqrt(p_hp**2 - wo**2), p_hp - np.sqrt(p_hp**2 - wo**2)))
        z_bs = np.concatenate((z_bs, np.full(degree, +1j * wo), np.full(degree, -1j * wo)))
        k = k * np.real(np.prod(-z) / np.prod(-p))
        z, p = z_bs, p_bs
    degree = len(p) - len(z)  # the bilinear transform (fs 2: 2 fs = 4)
    z_z = np.concatenate(((4.0 + z) / (4.0 - z), -np.ones(degree)))
    p_z = (4.0 + p) / (4.0 - p)
    k_z = k * np.real(np.prod(4.0 - z) / np.prod(4.0 - p))
    k_z = np.atleast_1d(np.asarray(k_z, dtype=np.result_type(np.real(z_z), np.real(p_z), k_z)))
    return np.multiply(k_z, _poly(z_z)), np.atleast_1d(_poly(p_z))


def _normalized(b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """b and a divided by a[0] (leading zeros of a dropped) and zero-padded to one length."""
    b = np.atleast_1d(np.asarray(b, dtype=np.float64))
    a = np.atleast_1d(np.asarray(a, dtype=np.float64))
    if b.ndim != 1 or a.ndim != 1:
        raise ValueError("b and a must be 1-D")
    while len(a) > 1 and a[0] == 0.0:
        a = a[1:]
    if len(a) < 1 or a[0] == 0.0:
        raise ValueError("there must be at least one nonzero a coefficient")
    if a[0] != 1.0:
        b, a = b / a[0], a / a[0]
    n = max(len(a), len(b))
    return np.concatenate((b, np.zeros(n - len(b)))), np.concatenate((a, np.zeros(n - len(a))))


def _refuse_leading_zero(a: np.ndarray) -> None:
    """scipy's lfilter refuses a[0] == 0 (no causal filter); :func:`_normalized` would drop it, as
    lfilter_zi does, and shift the filter by a sample."""
    if np.atleast_1d(np.asarray(a, dtype=np.float64))[0] == 0.0:
        raise ValueError("the filter's first denominator coefficient a[0] must not be 0")


def lfilter_zi(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter_zi(b, a)``: the initial state of the step response's steady state,
    ``(I - A) zi = B`` with A = companion(a)^T, B = b[1:] - a[1:] b0 (the same bits)."""
    b, a = _normalized(b, a)
    n = len(a)
    companion = np.zeros((n - 1, n - 1))
    companion[0] = -a[1:] / a[0]
    companion[np.arange(1, n - 1), np.arange(0, n - 2)] = 1.0
    return np.linalg.solve(np.eye(n - 1) - companion.T, b[1:] - a[1:] * b[0])


@lru_cache(maxsize=64)
def _blocks(b_bytes: bytes, a_bytes: bytes, length: int) -> tuple[np.ndarray, ...]:
    """The block matrices of a normalised filter: T (L, L) lower-triangular Toeplitz of the impulse
    response h_0 = b_0, h_j = C A^(j-1) B; O (L, n) rows C A^j; G (n, L) columns A^(L-1-m) B; A^L."""
    b, a = np.frombuffer(b_bytes), np.frombuffer(a_bytes)
    order = len(a) - 1
    A = np.zeros((order, order))
    A[:, 0] = -a[1:]
    A[np.arange(order - 1), np.arange(1, order)] = 1.0
    B = b[1:] - a[1:] * b[0]
    h = np.empty(length)
    obs = np.empty((length, order))
    ctrl = np.empty((order, length))
    row = np.zeros(order)
    row[0] = 1.0  # C A^j, j = 0, 1, ...
    col = B.copy()  # A^j B
    h[0] = b[0]
    for j in range(length):
        obs[j] = row
        ctrl[:, length - 1 - j] = col
        if j + 1 < length:
            h[j + 1] = row @ B
        row = row @ A
        col = A @ col
    power = np.linalg.matrix_power(A, length)
    return tuple(np.ascontiguousarray(m) for m in (iirmodal.lower_toeplitz(h), obs, ctrl, power))


def _rows(b: np.ndarray, a: np.ndarray, x: np.ndarray, z0: np.ndarray | None, modal: bool = False) -> np.ndarray:
    """The normalised filter along the last axis of ``x`` (m, n) from the states ``z0`` (m, order)
    (zero when None); ``modal``: :func:`lfilter`'s."""
    m, n = x.shape
    if len(a) == 1:
        return b[0] * x
    buf = np.zeros((m, -(-n // BLOCK) * BLOCK))
    buf[:, :n] = x
    return _padded(b, a, buf, z0, modal)[:, :n]


def _padded(b: np.ndarray, a: np.ndarray, buf: np.ndarray, z0: np.ndarray | None, modal: bool = False) -> np.ndarray:
    """The filter over ``buf`` (m, a multiple of BLOCK: the signal, then zeros), whole blocks; sample
    by sample (:func:`_stepwise`, scipy's bits) for a design the blocks cannot carry (:func:`_blockable`) and
    for the rows that hold a NaN or inf. With ``modal`` (opt-in, module docstring) such a design goes
    through the modal form's blocks when it has one (:func:`primitives.iirmodal.modal_blocks`)."""
    z = None if z0 is None else np.broadcast_to(z0, (buf.shape[0], len(a) - 1))
    products = _block_form(b.tobytes(), a.tobytes(), modal)
    if products is None:
        return _stepwise_rows(b, a, buf, z)
    finite = np.isfinite(buf).all(axis=1)
    if not finite.all():
        # a NaN or inf spoils its whole block in the products (0 x NaN is NaN), scipy's output only from
        # that sample on: those rows sample by sample
        out = np.empty_like(buf)
        out[~finite] = _stepwise_rows(b, a, buf[~finite], None if z is None else z[~finite])
        if finite.any():
            out[finite] = _padded(b, a, buf[finite], None if z is None else z[finite], modal)
        return out
    with one_blas_thread():
        return products(buf, z0)


def _block_form(b_bytes: bytes, a_bytes: bytes, modal: bool):
    """The products :func:`_padded` filters whole blocks with (``f(buf, z0)``): the companion form's
    when :func:`_blockable`, else with ``modal`` the modal form's when the design has one; None: sample
    by sample."""
    if _blockable(b_bytes, a_bytes):
        toeplitz, obs, ctrl, power = _blocks(b_bytes, a_bytes, BLOCK)
        order = len(obs[0])
        return lambda buf, z0: _block_products(buf, order, toeplitz, obs, ctrl, power, z0)
    blocks = _modal_blocks(b_bytes, a_bytes) if modal else None
    return None if blocks is None else (lambda buf, z0: iirmodal.modal_products(buf, blocks, z0))


def _stepwise_rows(b: np.ndarray, a: np.ndarray, buf: np.ndarray, z0: np.ndarray | None) -> np.ndarray:
    """:func:`_stepwise` over each row of ``buf`` (m, n) from the states ``z0`` (m, order; zero when None)."""
    z = np.zeros((buf.shape[0], len(a) - 1)) if z0 is None else z0
    if buf.shape[0] == 1:  # one row: Python floats, ten times faster than one-element arrays
        return np.array([_stepwise(b.tolist(), a.tolist(), buf[0].tolist(), z[0].tolist())])
    return np.stack(_stepwise(b.tolist(), a.tolist(), buf.T, [z[:, i].copy() for i in range(len(a) - 1)]), axis=1)


def _stepwise(b: list[float], a: list[float], xs, z: list) -> list:
    """scipy's transposed direct form II loop (``_linear_filter``: y = z_0 + b_0 x; z_i = z_(i+1) +
    x b_(i+1) - y a_(i+1); the last z = x b_n - y a_n), in its order of operations, so its bits, over
    ``xs`` (one value per step: floats, or arrays of the rows' samples) from the states ``z`` (updated);
    the outputs, one per step."""
    order = len(a) - 1
    out = []
    for x in xs:
        y = z[0] + b[0] * x
        for i in range(order - 1):
            z[i] = z[i + 1] + x * b[i + 1] - y * a[i + 1]
        z[order - 1] = x * b[order] - y * a[order]
        out.append(y)
    return out


#: the block products must equal the sample-by-sample filter on a probe to this share of its peak
#: (the detector's designs: 5e-15 to 5e-13); a high order or a low cutoff (a 4th-order low-pass at
#: 1 % of Nyquist: 3e-4; 6th order at 1 %: overflow) puts clustered poles into the companion form's
#: A^L, whose rounding then grows from block to block
BLOCKABLE_TOLERANCE = 1e-11
#: the modal form's products must equal the sample-by-sample filter on the probe to this share of its peak
#: (opt-in callers only, whose output feeds a check's verdict). Measured on the probe (x86-64's 80-bit
#: longdouble / iirmodal's EXT patched to double): mass's 2nd-order 0.1-0.45 Hz band 3e-11 / 5e-10 at
#: 50 Hz, 7e-9 / 5e-8 at 200 Hz; the 0.1-2.0 Hz band at 25-200 Hz under 8e-10 on both; a triple pole at
#: 0.999 (split by numpy.roots) 4.3 / 3.8e3, poles 0.999, 0.9991, 0.9992 5e-5 / 2e-3: refused on both
MODAL_TOLERANCE = 1e-7


@lru_cache(maxsize=64)
def _blockable(b_bytes: bytes, a_bytes: bytes) -> bool:
    """Whether the block products of a normalised design are accurate: A^L's spectral radius below 1,
    and the blocks equal :func:`_stepwise` to :data:`BLOCKABLE_TOLERANCE` of the peak on a fixed
    random walk of 16 blocks from a random state (a few ms in Python floats, once per design)."""
    order = len(np.frombuffer(a_bytes)) - 1
    toeplitz, obs, ctrl, power = _blocks(b_bytes, a_bytes, BLOCK)
    if not np.all(np.isfinite(power)) or np.max(np.abs(np.linalg.eigvals(power))) >= 1.0:
        return False
    probe, z0, want = _probe(b_bytes, a_bytes)
    with one_blas_thread():
        got = _block_products(probe[None, :], order, toeplitz, obs, ctrl, power, z0[None, :])[0]
    return bool(np.max(np.abs(got - want)) <= BLOCKABLE_TOLERANCE * np.max(np.abs(want)))


@lru_cache(maxsize=64)
def _probe(b_bytes: bytes, a_bytes: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The block forms' probe of a normalised design: a fixed random walk of 16 blocks, a random start
    state, and :func:`_stepwise`'s output from them (double precision, scipy's bits)."""
    b, a = np.frombuffer(b_bytes), np.frombuffer(a_bytes)
    rng = np.random.default_rng(0)
    probe = rng.standard_normal(16 * BLOCK).cumsum()
    z0 = rng.standard_normal(len(a) - 1)
    return probe, z0, np.array(_stepwise(b.tolist(), a.tolist(), probe.tolist(), z0.tolist()))


@lru_cache(maxsize=64)
def _modal_blocks(b_bytes: bytes, a_bytes: bytes) -> tuple[np.ndarray, ...] | None:
    """:func:`primitives.iirmodal.modal_blocks` of a normalised design when its products are within
    :data:`MODAL_TOLERANCE` of the peak of :func:`_stepwise` on :func:`_probe`, else None: a guard
    against near-repeated poles (a triple pole at 0.999 that ``numpy.roots`` splits was 2.2 times
    the peak off), in double precision only, so that the choice is the same on every platform for
    the designs that take it."""
    blocks = iirmodal.modal_blocks(b_bytes, a_bytes, BLOCK)
    if blocks is None:
        return None
    probe, z0, want = _probe(b_bytes, a_bytes)
    with one_blas_thread():
        got = iirmodal.modal_products(probe[None, :], blocks, z0[None, :])[0]
    return blocks if np.max(np.abs(got - want)) <= MODAL_TOLERANCE * np.max(np.abs(want)) else None


def _block_products(
    buf: np.ndarray,
    order: int,
    toeplitz: np.ndarray,
    obs: np.ndarray,
    ctrl: np.ndarray,
    power: np.ndarray,
    z0: np.ndarray | None,
) -> np.ndarray:
    """:func:`_padded`'s products: the blocks' forced responses, their end states from block to
    block, and each block's response to its start state."""
    m, nb = buf.shape[0], buf.shape[1] // BLOCK
    xb = buf.reshape(m * nb, BLOCK)
    y = (xb @ toeplitz.T).reshape(m, nb, BLOCK)
    u = (xb @ ctrl.T).reshape(m, nb, order)  # each block's inputs carried to its end state
    s = np.empty((m, nb, order))
    cur = np.zeros((m, order)) if z0 is None else np.broadcast_to(z0, (m, order)).astype(np.float64)
    step = np.ascontiguousarray(power.T)
    for k in range(nb):
        s[:, k] = cur
        cur = cur @ step
        cur += u[:, k]
    y += (s.reshape(m * nb, order) @ obs.T).reshape(m, nb, BLOCK)
    return y.reshape(m, nb * BLOCK)


def lfilter(
    b: np.ndarray, a: np.ndarray, x: np.ndarray, axis: int = -1, zi: np.ndarray | None = None, *, modal: bool = False
) -> np.ndarray:
    """``scipy.signal.lfilter(b, a, x, axis, zi)``'s output (without the final state) to rounding
    (module docstring); ``zi`` is (order,) or x's shape with ``axis`` of length order. ``modal``: the
    modal form instead of scipy's loop for designs the companion blocks cannot carry (opt-in, module
    docstring: not scipy's bits there)."""
    _refuse_leading_zero(a)
    b, a = _normalized(b, a)
    x = np.asarray(x, dtype=np.float64)
    order = len(a) - 1
    moved = np.moveaxis(x, axis, -1)
    lead = moved.shape[:-1]
    rows = moved.reshape(-1, moved.shape[-1])
    z0 = None
    if zi is not None and order:
        zi = np.asarray(zi, dtype=np.float64)
        z0 = zi if zi.ndim == 1 else np.moveaxis(zi, axis, -1).reshape(-1, order)
    y = _rows(b, a, rows, z0, modal).reshape(*lead, moved.shape[-1])
    return np.moveaxis(y, -1, axis)


def filtfilt(
    b: np.ndarray, a: np.ndarray, x: np.ndarray, axis: int = -1, padtype: str = "odd", *, modal: bool = False
) -> np.ndarray:
    """``scipy.signal.filtfilt(b, a, x, axis, padtype)`` (odd or even padding of 3 max(len(a), len(b))
    samples, each pass from ``lfilter_zi x_0``) to rounding (module docstring); ``modal`` as
    :func:`lfilter`'s."""
    if padtype not in ("odd", "even"):
        raise ValueError(f"filtfilt: padtype must be 'odd' or 'even', not {padtype!r}")
    x = np.asarray(x, dtype=np.float64)
    edge = 3 * max(len(np.atleast_1d(a)), len(np.atleast_1d(b)))
    _refuse_leading_zero(a)
    b, a = _normalized(b, a)
    moved = np.moveaxis(x, axis, -1)
    n = moved.shape[-1]
    if n <= edge:
        raise ValueError(f"filtfilt: the signal's length along axis {axis} must exceed {edge} samples")
    lead = moved.shape[:-1]
    rows = moved.reshape(-1, n)
    total = n + 2 * edge
    zi = lfilter_zi(b, a)
    # the extension written straight into the first pass's block buffer (zeros after it): scipy's odd_ext
    # (2 x_0 - x_i) or even_ext (x_i), mirrored about the end samples
    buf = np.zeros((rows.shape[0], -(-total // BLOCK) * BLOCK))
    left, right = rows[:, edge:0:-1], rows[:, -2 : -edge - 2 : -1]
    odd = padtype == "odd"
    buf[:, :edge] = 2 * rows[:, :1] - left if odd else left
    buf[:, edge : edge + n] = rows
    buf[:, edge + n : total] = 2 * rows[:, -1:] - right if odd else right
    y = _padded(b, a, buf, zi[None, :] * buf[:, :1], modal)
    back = np.zeros(buf.shape)  # the forward output reversed, for the backward pass
    back[:, :total] = y[:, total - 1 :: -1]
    y = _padded(b, a, back, zi[None, :] * back[:, :1], modal)
    return np.moveaxis(y[:, total - 1 - edge : edge - 1 : -1].reshape(*lead, n), -1, axis)
