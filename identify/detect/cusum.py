"""Dead-zone CUSUM of seed 000 eq. (5.1), calibrated from the prior model's own residual noise.

    g(t) = max(0, g(t-1) + s(t)),  s(t) = |eps(t)| - d  if |eps(t)| >= d  else  -l;  alarm at g > h

Table 5.1 prints d, l with negative signs, which contradicts (5.1); they are magnitudes here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from primitives import jitloop
from primitives.orderstats import quantile  # numpy's numbers without its import of numpy.ma (stop 52)


@dataclass(frozen=True)
class DeadZoneCusum:
    """Tuning ``d`` (dead zone), ``l`` (leak per sample below the dead zone), ``h`` (alarm threshold)."""

    d: float
    l: float
    h: float

    def statistic(self, eps: np.ndarray) -> np.ndarray:
        """``g(t)`` of (5.1a) over the residual ``eps`` (time on axis 0; extra axes are runs)."""
        return cusum_path(self._increments(eps))

    def _increments(self, eps: np.ndarray) -> np.ndarray:
        """(5.1)'s ``s(t)``: ``|eps| - d`` at or above the dead zone, ``-l`` below it (a NaN residual: below)."""
        a = np.abs(np.asarray(eps, float))
        return np.where(a >= self.d, a - self.d, -self.l)

    def peaks(self, eps: np.ndarray) -> np.ndarray:
        """The largest ``g(t)`` per run: ``statistic(eps).max(axis=0)``, the same numbers. For many runs in numpy
        (the no-change records, :func:`calibrate_dead_zone`) the recursion steps as :func:`cusum_path` does and
        keeps only its running peak, the increments made a block of samples at a time: not the (n, runs) paths
        and three (n, runs) temporaries of fresh pages (16 MB each for 400 records of a 500 s recording)."""
        eps = np.asarray(eps, float)
        if eps.ndim != 2 or eps.shape[1] <= CLOSED_MAX or not eps.size or jitloop.use(eps.size):
            return self.statistic(eps).max(axis=0)
        acc, s = np.zeros(eps.shape[1]), np.empty(eps.shape[1])
        peak = np.full(eps.shape[1], -np.inf)
        for i in range(0, len(eps), BLOCK):
            for row in self._increments(eps[i : i + BLOCK]):
                np.maximum(0.0, np.add(acc, row, out=s), out=acc)  # as _stepped: max(0, g + s)
                np.maximum(peak, acc, out=peak)
        return peak

    def first_alarm(self, eps: np.ndarray) -> int | None:
        """Index of the first sample with ``g > h``, or None."""
        hit = np.flatnonzero(self.statistic(eps) > self.h)
        return int(hit[0]) if hit.size else None


#: samples of one block of :func:`cusum_path`'s closed form: its sums' rounding grows with the block, not the record
BLOCK = 256
#: columns up to which the numpy form is the closed form; wider arrays step the recursion, 3 array calls a sample
#: (numpy's running sums along axis 0 cost more than that there: 5,000 x 400 24 ms against 15 ms stepped, 5,000 x 1
#: 0.4 ms against 18 ms; the crossover lies near 150 columns)
CLOSED_MAX = 64


def cusum_path(inc: np.ndarray) -> np.ndarray:
    """``g_t = max(0, g_{t-1} + inc_t)``, ``g_{-1} = 0``, along axis 0, vectorised over the other axes; compiled
    for a large float array (:func:`_path`, a NaN carried on as numpy's maximum does). In numpy, stepped sample by
    sample for many columns (the no-change records': the compiled loop's bits), and for up to :data:`CLOSED_MAX`
    (a recording's own statistics) in the recursion's closed form (Lindley's; stop 51), by blocks of :data:`BLOCK`
    samples: with ``S_t`` the sum of the block's increments up to t and ``g0`` the value before the block,

        g_t = S_t - min(-g0, min_{s <= t} S_s)

    a cumulative sum and a running minimum, not 15,000 array calls for 5,000 samples. The same recursion in
    another order of rounding: within 1e-12 of the statistic's scale (tests/test_detect_cusum.py), a NaN carried
    on the same way."""
    if inc.dtype == np.float64 and inc.size and jitloop.use(inc.size):
        flat = np.ascontiguousarray(inc).reshape(inc.shape[0], -1)
        return _path(flat, np.empty_like(flat)).reshape(inc.shape)
    # a -inf increment resets the recursion to 0 but makes the closed form's S_t - min S_s NaN
    if inc.size > CLOSED_MAX * max(inc.shape[0], 1) or np.isneginf(inc).any():
        return _stepped(inc)
    g = np.empty(inc.shape)  # doubles, as the recursion's running sum
    low = np.zeros(inc.shape[1:])  # -g0: g before the first block is 0
    for i in range(0, inc.shape[0], BLOCK):
        blk = g[i : i + BLOCK]
        np.cumsum(inc[i : i + BLOCK], axis=0, out=blk)  # the block's own sums: rounding of their scale only
        run = np.minimum.accumulate(np.minimum(blk, low), axis=0)
        np.subtract(blk, run, out=blk)
        np.negative(blk[-1], out=low)
    return g if g.dtype == inc.dtype else g.astype(inc.dtype)


def _stepped(inc: np.ndarray) -> np.ndarray:
    """:func:`cusum_path` one sample at a time over all columns at once."""
    g = np.empty_like(inc)
    acc = np.zeros(inc.shape[1:])
    for i in range(inc.shape[0]):
        acc = np.maximum(0.0, acc + inc[i])
        g[i] = acc
    return g


@jitloop.compiled
def _path(inc, out):  # pragma: no cover - compiled
    n, m = inc.shape
    acc = np.zeros(m)
    for i in range(n):
        for j in range(m):
            s = acc[j] + inc[i, j]
            acc[j] = 0.0 if s <= 0.0 else s  # NaN stays NaN, as np.maximum(0, NaN)
            out[i, j] = acc[j]
    return out


def normal_pdf(z: float) -> float:
    """The standard normal density exp(-z^2 / 2) / sqrt(2 pi) (scipy.stats.norm.pdf)."""
    return math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def normal_sf(z: float) -> float:
    """The standard normal upper tail P(Z > z) = erfc(z / sqrt 2) / 2 (scipy.stats.norm.sf)."""
    return 0.5 * math.erfc(z / math.sqrt(2.0))


def first_alarms(stat: np.ndarray, h: float) -> np.ndarray:
    """First index along axis 0 where ``stat > h`` per run (axis 1), -1 where none."""
    over = stat > h
    return np.where(over.any(axis=0), over.argmax(axis=0), -1)


def calibrate_dead_zone(sigma: float, null: np.ndarray, false_alarm: float = 0.02, d_sigma: float = 2.0) -> DeadZoneCusum:
    """Choose d, l, h from the prior's own residual noise (never from evaluation runs).

    ``d = d_sigma * sigma`` (``sigma`` the robust sigma of the prior's fit residual); ``l`` makes
    the expected increment under white Gaussian noise equal to minus the mean excess above d (so
    the statistic drifts down); ``h`` is the (1 - false_alarm) quantile of the statistic's maximum
    over ``null``, no-change residual records (n, runs) simulated from the prior (nullsim.null_records).
    """
    d = d_sigma * sigma
    # closed forms for |N(0, sigma^2)|: E[(|e| - d)+] and P(|e| < d), with the standard normal's
    # density and upper tail (math, not scipy.stats: its import is about 2 s of CPU)
    z = d_sigma
    excess = 2 * sigma * (normal_pdf(z) - z * normal_sf(z))
    p_in = 1 - 2 * normal_sf(z)
    l = 2.0 * excess / p_in  # expected increment = excess - l p_in = -excess
    det = DeadZoneCusum(d, l, np.inf)
    h = float(quantile(det.peaks(null), 1 - false_alarm))
    return DeadZoneCusum(d, l, h)
