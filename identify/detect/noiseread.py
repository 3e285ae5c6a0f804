"""A recorded channel's measurement noise read as white noise behind a first-order low-pass (a
sensor's own filter), from the recording alone, and that noise drawn again for the prior's
bootstrap refits and no-change records (stop 55).

Model: the recorded noise is ``e_k = a e_(k-1) + (1 - a) w_k``, ``w`` white of sd ``sigma``,
``a = exp(-dt / tau)`` (a causal first-order low-pass of time constant ``tau`` at sample time
``dt``; ``a = 0``: white noise, ``e = w``). It is the stationary AR(1) process of variance
``V = sigma^2 (1 - a) / (1 + a)`` and autocovariance ``V a^|k|`` (eq. N1).

The channel's q-th differences at a step of m samples, ``(1 - B^m)^q x`` (q = :data:`ORDER` = 4: a
cubic of the ship's motion taken out; its remainder grows as ``(m dt)^2q`` and stays below the noise
at the steps :data:`STEPS` = 1-10), are its noise's high-frequency part. Their variance per unit ``V``
is ``f_m(a) = sum_(i,l) c_i c_l a^(m |i - l|)``, ``c`` the alternating binomials of ``(1 - B)^q``
(eq. N2): flat in ``m`` for white noise, rising towards ``2^q choose q`` for a corner of several
samples. The robust variances (1.4826 MAD, squared: a sudden helm order's few large differences do not
pass for noise) are fitted in the logs (eq. N3: ``log s_m^2 = log V + log f_m(a)``, ``log V`` profiled out,
``a`` on a grid then by golden section), ``sigma`` follows from (N1). A fit at ``a`` = :data:`A_MAX`
(no corner the steps resolve: the ship's own motion fills them, as a measured moment's steering transients
do) falls back to :func:`identify.detect.priorfit.white_noise_sd`'s reading, second difference / sqrt(6).
On the podded truth (docs/detect-accuracy.md, stop 55) it reads u, v, phi and p at 0.93-1.14 of their sd,
r at 1.07-1.44 and v_dot at 1.3-3.1 (their ship's own yaw acceleration and sway jerk read as noise).
"""

from __future__ import annotations

import math

import numpy as np

#: ``a`` beyond which the reading is not trusted (a corner 100 samples long: the short-step second
#: differences then carry too little of the noise for the ship's own curvature not to compete)
A_MAX = 0.99
#: the second differences' steps (samples) read: 1 to 6 cover the corners a ship's sensors have at 10 Hz (the
#: truth family's 0.2-0.5 s: 2-5 samples), while the ship's own curvature, growing as m^4, stays below the noise
STEPS = np.arange(1, 11)
#: the differences' order q: (1 - B^m)^q takes a cubic out of the ship's motion
ORDER = 4


def _coef(order: int = 0) -> np.ndarray:
    """The difference's coefficients ``(1 - B)^q``, alternating binomials."""
    q = order or ORDER
    return np.array([(-1) ** i * math.comb(q, i) for i in range(q + 1)], float)


def _f(a: float, m: np.ndarray) -> np.ndarray:
    """``var((1 - B^m)^q e) / V`` for the AR(1) noise of eq. N1: ``sum_(i,l) c_i c_l a^(m |i - l|)`` (eq. N2)."""
    c = _coef()
    lag = np.abs(np.subtract.outer(np.arange(len(c)), np.arange(len(c))))
    w = np.outer(c, c)
    return np.array([float(np.sum(w * a ** (mi * lag))) for mi in np.atleast_1d(m)])


def _diff(x: np.ndarray, m: int) -> np.ndarray:
    """``(1 - B^m)^q x``: the q-th difference at step m samples."""
    for _ in range(ORDER):
        x = x[m:] - x[:-m]
    return x


def _robust_sd(x: np.ndarray) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def lowpass_noise(x: np.ndarray, dt: float) -> tuple[float, float]:
    """``(sigma, tau)``: the sd of the white noise and the time constant (s; 0 for white noise) of
    the first-order low-pass it passed through, read from the recorded channel ``x`` (eq. N1-N3).
    The noise the channel carries has sd ``sigma * sqrt((1 - a) / (1 + a))``, ``a = exp(-dt / tau)``."""
    x = np.asarray(x, float)
    steps = STEPS[ORDER * STEPS < len(x) - 8]
    if len(steps) < 2:
        return 0.0, 0.0
    s2 = np.array([_robust_sd(_diff(x, int(m))) ** 2 for m in steps])
    if not np.all(s2 > 0):
        return 0.0, 0.0
    a = _fit_a(np.log(s2), steps)
    if a >= 0.999 * A_MAX:
        # no corner the steps resolve: the channel's high-frequency part is the ship's own (a measured moment's
        # steering transients), not noise; read it as white noise, as before stop 55 (eq. N2 at a = 0, m = 1)
        return _robust_sd(np.diff(x, 2)) / math.sqrt(6.0), 0.0
    v = float(np.exp(np.mean(np.log(s2) - np.log(_f(a, steps)))))
    sigma = math.sqrt(v * (1 + a) / (1 - a))
    return sigma, (-dt / math.log(a) if a > 0 else 0.0)


def _misfit(a: float, log_s2: np.ndarray, steps: np.ndarray) -> float:
    """Least squares in the logs of eq. N3, the level ``log V`` profiled out (the mean difference)."""
    d = log_s2 - np.log(_f(a, steps))
    return float(np.sum((d - d.mean()) ** 2))


def _fit_a(log_s2: np.ndarray, steps: np.ndarray) -> float:
    """``a`` in [0, A_MAX] minimising :func:`_misfit`: a grid of 100, then golden-section search
    around its best point (the misfit is smooth in ``a``)."""
    grid = np.linspace(0.0, A_MAX, 100)
    k = int(np.argmin([_misfit(a, log_s2, steps) for a in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(40):
        c, d = hi - g * (hi - lo), lo + g * (hi - lo)
        lo, hi = (lo, d) if _misfit(c, log_s2, steps) < _misfit(d, log_s2, steps) else (c, hi)
    return 0.5 * (lo + hi)


def stationary_lowpass(w: np.ndarray, tau: float, dt: float, axis: int = -1) -> np.ndarray:
    """White draws ``w`` (sd ``sigma``) through the first-order low-pass of time constant ``tau``,
    started in its stationary state (eq. N1: the first sample scaled to the sd ``sigma sqrt((1 - a) /
    (1 + a))`` the filter settles at, as a sensor running long before the record starts), along
    ``axis``; ``w`` itself when ``tau`` is 0. Linear in ``w``, so the no-change records' split of
    signal and noise (:func:`identify.detect.nullsim._linear_inputs`) still holds."""
    if tau <= 0:
        return w
    a = math.exp(-dt / tau)
    w = np.moveaxis(np.asarray(w, float), axis, -1)
    out = np.empty_like(w)
    out[..., 0] = math.sqrt((1 - a) / (1 + a)) * w[..., 0]
    # the recursion e_k = a e_(k-1) + (1 - a) w_k, in closed form by blocks: cheap, and exact to rounding
    _recurse(out, w, a)
    return np.moveaxis(out, -1, axis)


def _recurse(out: np.ndarray, w: np.ndarray, a: float, block: int = 64) -> None:
    """``out[..., k] = a out[..., k-1] + (1 - a) w[..., k]`` for k >= 1 (``out[..., 0]`` given): within a
    block of L samples ``e_(s+j) = a^(j+1) e_s + sum_(i<=j) a^(j-i) (1 - a) w_(s+1+i)``, a lower-triangular
    matrix product per block (numpy, no sample loop)."""
    n = out.shape[-1]
    j = np.arange(block)
    T = np.tril(a ** (j[:, None] - j[None, :]).clip(0)) * (1 - a)
    T[j[:, None] < j[None, :]] = 0.0
    p = a ** (j + 1)
    s = 0
    while s < n - 1:
        m = min(block, n - 1 - s)
        out[..., s + 1 : s + 1 + m] = out[..., s : s + 1] * p[:m] + w[..., s + 1 : s + 1 + m] @ T[:m, :m].T
        s += m
