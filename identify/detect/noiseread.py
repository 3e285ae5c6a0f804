"""A recorded channel's measurement noise: the model (white noise behind a first-order low-pass, a sensor's own
filter), its white reading and the noise drawn again for the prior's bootstrap refits and no-change records
(stop 55; the corner and sd are read by :mod:`identify.detect.noisespec`, stop 56).

Model: the recorded noise is ``e_k = a e_(k-1) + (1 - a) w_k``, ``w`` white of sd ``sigma``,
``a = exp(-dt / tau)`` (a causal first-order low-pass of time constant ``tau`` at sample time
``dt``; ``a = 0``: white noise, ``e = w``). It is the stationary AR(1) process of variance
``V = sigma^2 (1 - a) / (1 + a)`` and autocovariance ``V a^|k|`` (eq. N1).

Stop 55's reader of the corner from the channel's fourth differences at steps of 1-10 samples (``--noise-model
lowpass``) was retired at stop 57: it read the ship's own yaw acceleration and sway jerk as noise (r at 1.07-1.44
and v_dot at 1.3-3.1 of their sd on the podded truth), where the spectral reader reads every channel at least as
well (docs/detect-accuracy.md, stops 55-57). Prior files that record it still load, with the noise levels they hold.
"""

from __future__ import annotations

import math

import numpy as np

from primitives.iir import lfilter  # scipy.signal's, without its import

#: ``a`` beyond which the reading is not trusted (a corner 100 samples long: the noise then lies too far below the
#: corner's frequency for the ship's own motion not to compete); the end of noisespec's grid, the longest corner a prior holds
A_MAX = 0.99
#: ``a`` below which the noise reads white (tau = 0): noisespec's grid step, the resolution it has
A_MIN = A_MAX / 99


def robust_sigma(e: np.ndarray) -> float:
    """1.4826 median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(e - np.median(e))))


def white_noise_sd(x: np.ndarray) -> float:
    """Standard deviation of the white measurement noise on a signal that is smooth at its sample
    rate: robust sigma of the second difference / sqrt(6) (white noise's second difference has the variance
    ``(1 + 4 + 1) sigma^2``; the signal's own curvature is far below the noise at 10 Hz)."""
    return robust_sigma(np.diff(np.asarray(x, float), 2)) / np.sqrt(6.0)


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
