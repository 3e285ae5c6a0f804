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
(eq. N2): flat in ``m`` for white noise (``f_m(0) = (2q choose q) = 70``), and for a corner of several
samples rising from below towards that same limit as ``m`` grows. The robust variances (1.4826 MAD, squared: a sudden helm order's few large differences do not
pass for noise) are fitted in the logs (eq. N3: ``log s_m^2 = log V + log f_m(a)``, ``log V`` profiled out,
``a`` on a grid then by golden section), ``sigma`` follows from (N1). It falls back to :func:`white_noise_sd`'s
reading (second difference / sqrt(6), tau = 0) when no corner is resolved: a fit at ``a`` = :data:`A_MAX` (the
ship's own motion fills the steps, as a measured moment's steering transients do), a fit below :data:`A_MIN`
(the grid's first step) or one that does not lower the misfit clearly (:data:`F_MIN`): white noise, snapped
to tau = 0 rather than left as a corner of a few ms; or a record too
short, constant or non-finite to fit (a NaN then reads NaN, and the prior's validation refuses it).
On the podded truth (docs/detect-accuracy.md, stop 55) it reads u, v, phi and p at 0.93-1.14 of their sd,
and r at 1.07-1.44 and v_dot at 1.3-3.1 (means per variant over 4 ships; one record's range is wider: r
1.00-1.78, v_dot 0.19-6.47): their ship's own yaw acceleration and sway jerk read as noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from primitives.iir import lfilter  # scipy.signal's, without its import

#: ``a`` beyond which the reading is not trusted (a corner 100 samples long: the short-step 4th differences
#: then carry too little of the noise for the ship's own motion not to compete)
A_MAX = 0.99
#: ``a`` below which the noise reads white (tau = 0): the fit's grid step, the resolution it has
A_MIN = A_MAX / 99
#: the corner must lower the misfit of eq. N3 clearly to be kept: ``F = (S_0 - S_a) / (S_a / (M - 2))`` above the
#: 99 % point of F(1, 8) (M = 10 steps, 2 fitted: log V and a); below it the reading is white (tau = 0). The log
#: variances at overlapping steps are correlated, so this is a stated rule rather than an exact test: white
#: Table 4.1 noise read corners of 0.03-0.06 s (a 0.02-0.17) at F 0.3-3.7, behind 0.2-0.5 s corners F is far above
F_MIN = 11.26
#: the 4th differences' steps (samples) read: 1 to 10 cover the corners a ship's sensors have at 10 Hz (the
#: truth family's 0.2-0.5 s: 2-5 samples), while the ship's own motion's remainder, its variance growing as
#: m^8 (``(m dt)^2q``), stays below the noise
STEPS = np.arange(1, 11)
#: the differences' order q: (1 - B^m)^q takes a cubic out of the ship's motion
ORDER = 4


def _coef() -> np.ndarray:
    """The difference's coefficients ``(1 - B)^q``, alternating binomials."""
    return np.array([(-1) ** i * math.comb(ORDER, i) for i in range(ORDER + 1)], float)


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


def robust_sigma(e: np.ndarray) -> float:
    """1.4826 median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(e - np.median(e))))


def white_noise_sd(x: np.ndarray) -> float:
    """Standard deviation of the white measurement noise on a signal that is smooth at its sample
    rate: robust sigma of the second difference / sqrt(6) (eq. N2 at a = 0 with q = 2, m = 1; the
    signal's own curvature is far below the noise at 10 Hz)."""
    return robust_sigma(np.diff(np.asarray(x, float), 2)) / np.sqrt(6.0)


def lowpass_noise(x: np.ndarray, dt: float) -> tuple[float, float]:
    """``(sigma, tau)``: the sd of the white noise and the time constant (s; 0 for white noise) of
    the first-order low-pass it passed through, read from the recorded channel ``x`` (eq. N1-N3).
    The noise the channel carries has sd ``sigma * sqrt((1 - a) / (1 + a))``, ``a = exp(-dt / tau)``."""
    x = np.asarray(x, float)
    steps = STEPS[ORDER * STEPS < len(x) - 8]
    s2 = np.array([robust_sigma(_diff(x, int(m))) ** 2 for m in steps])
    if len(steps) < 2 or not np.all(np.isfinite(s2) & (s2 > 0)):
        # too short, constant (quantised) or non-finite: nothing to fit; the white reading (NaN stays NaN)
        return white_noise_sd(x), 0.0
    a = _fit_a(np.log(s2), steps)
    if a >= 0.999 * A_MAX or a < A_MIN or not _resolved(a, np.log(s2), steps):
        # no corner the steps resolve: the channel's high-frequency part is the ship's own (a measured moment's
        # steering transients), not noise; or white noise (a within the grid's first step of 0); read it as
        # white noise, as before stop 55, bit for bit
        return white_noise_sd(x), 0.0
    v = float(np.exp(np.mean(np.log(s2) - np.log(_f(a, steps)))))
    sigma = math.sqrt(v * (1 + a) / (1 - a))
    return sigma, (-dt / math.log(a) if a > 0 else 0.0)


def _misfit(a: float, log_s2: np.ndarray, steps: np.ndarray) -> float:
    """Least squares in the logs of eq. N3, the level ``log V`` profiled out (the mean difference)."""
    d = log_s2 - np.log(_f(a, steps))
    return float(np.sum((d - d.mean()) ** 2))


def _resolved(a: float, log_s2: np.ndarray, steps: np.ndarray) -> bool:
    """Whether the corner ``a`` lowers eq. N3's misfit against white noise (a = 0) by :data:`F_MIN`."""
    s_a, s_0 = _misfit(a, log_s2, steps), _misfit(0.0, log_s2, steps)
    return s_0 - s_a > F_MIN * s_a / (len(steps) - 2)


def _fit_a(log_s2: np.ndarray, steps: np.ndarray) -> float:
    """``a`` in [0, A_MAX] minimising :func:`_misfit`: a grid of 100, then golden-section search
    around its best point (the misfit is smooth in ``a``)."""
    grid = np.linspace(0.0, A_MAX, 100)
    k = int(np.argmin([_misfit(a, log_s2, steps) for a in grid]))
    return golden_refine(lambda a: _misfit(a, log_s2, steps), grid, k, 40)


def golden_refine(fun: Callable[[float], float], grid: np.ndarray, i: int, iters: int) -> float:
    """The minimum of the smooth ``fun`` between the neighbours of its best grid point ``grid[i]``: ``iters`` steps of
    golden-section search (Kiefer 1953), the bracket's midpoint. The one search of both noise readers (eq. N3 here,
    eq. S3 in :mod:`identify.detect.noisespec`)."""
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(iters):
        c, d = hi - g * (hi - lo), lo + g * (hi - lo)
        lo, hi = (lo, d) if fun(c) < fun(d) else (c, hi)
    return 0.5 * (lo + hi)


def stationary_lowpass(w: np.ndarray, tau: float, dt: float, axis: int = -1) -> np.ndarray:
    """White draws ``w`` (sd ``sigma``) through the first-order low-pass of time constant ``tau``,
    started in its stationary state (eq. N1: the first sample scaled to the sd ``sigma sqrt((1 - a) /
    (1 + a))`` the filter settles at, as a sensor running long before the record starts), along
    ``axis``; ``w`` itself when ``tau`` is 0. Linear in ``w``, so the no-change records' split of
    signal and noise (:func:`identify.detect.nullsim.null_records`: the clean share from ``_linear_inputs``, the
    noise's added in the yaw loop, ``simulate_r(extra=)``) still holds."""
    if tau <= 0:
        return w
    a = math.exp(-dt / tau)
    w = np.moveaxis(np.asarray(w, float), axis, -1)
    first = math.sqrt((1 - a) / (1 + a)) * w[..., :1]
    # the recursion e_k = a e_(k-1) + (1 - a) w_k after the first sample: a first-order filter started from it
    rest = lfilter(np.array([1 - a]), np.array([1.0, -a]), w[..., 1:], axis=-1, zi=a * first)
    return np.moveaxis(np.concatenate([first, rest], axis=-1), -1, axis)
