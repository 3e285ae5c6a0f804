"""A recorded channel's measurement noise read from its spectrum beside the ship's own motion (stop 56): still
white noise of sd ``sigma`` behind a first-order low-pass of time constant ``tau`` (eq. N1 of
:mod:`identify.detect.noiseread`), but fitted with the ship's motion as a term of its own.

Stop 55's fourth differences at steps of up to 10 samples see 0.2-0.5 Hz, where a ship's yaw acceleration and
sway jerk are as large as the noise (on the podded truth their spectrum is 0.07-0.7 of the noise's at 0.5 Hz and
6-26 times it at 0.2 Hz), so r and v_dot read 1.1-3 times too high. Here:

- the channel's spectrum ``P(f)`` is Welch's average (eq. S1): Hann-windowed segments of :data:`SEG_S` seconds, half
  overlapping, each with its own straight line taken out, ``P = 2 dt mean |FFT(w x)|^2 / sum w^2``;
- the noise's spectrum is the discrete AR(1)'s (eq. S2): ``N(f) = 2 dt sigma^2 (1 - a)^2 / |1 - a e^(-i 2 pi f dt)|^2``,
  ``a = exp(-dt / tau)``: flat below the corner, falling as f^-2 above it, flattening again towards Nyquist;
- the band ``[f_lo, f_N)`` starts at :data:`F_LADDER`'s 0.25 Hz (in Hz, whatever the sample rate), and in it
  ``P = N(f) + c (f / f_lo)^-k`` (eq. S3): the ship's motion, whose spectrum falls much faster than the noise's
  (``k`` in :data:`K_GRID`, 4-12), is fitted beside the noise from the data, not cut by a bandwidth set beforehand;
  ``sigma^2`` and ``c`` (both >= 0: a two-variable non-negative least squares) by linear least squares in the relative misfit at each ``a`` and ``k``
  (weighted by the fit, which a weight by the data would bias low), ``a`` on a grid then by golden section;
- a corner at the grid's end (nothing resolved) is tried once more on the band from 0.35 Hz, then, as
  white noise (``a`` within the grid's first step of 0), it reads :func:`identify.detect.noiseread.white_noise_sd`
  with tau = 0, as stop 55's reader does; so does a fit with no noise level (``sigma^2 = 0``: a pure tone, a
  noise-free channel, whose band the motion term covers alone).

Not handled: a channel held between samples (a 1 Hz sensor logged at 10 Hz) has a held noise's spectrum, not
eq. S2's, and reads a corner of a few tenths of a second at several times its sd (stop 55's reader reads it 0;
neither is right). The band and segment are set in Hz and seconds: tested at 10 Hz on the podded truth and at
10, 20 and 50 Hz on synthetic channels (tests/test_detect_noisespec.py). At 1 Hz or slower the reading is white: a band
with fewer than :data:`MIN_BINS` bins above 0.25 Hz resolves no corner (none at all at 2 s sampling). Between 1 and
2 Hz the band is short and white noise can read a corner (one white record of 2000 samples: 0.34 s at 1.4 Hz, 0.19 s
at 2 Hz; the stop 56 re-read mend).

On the podded truth (docs/detect-accuracy.md, stop 56) it reads r at 0.93-0.99 and v_dot at 0.79-1.22 of their
sd (means per variant over one recording on each of 4 ships; per record r 0.82-1.04), u, v, phi and p at 0.88-1.06.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from identify.detect.noiseread import A_MAX, A_MIN, white_noise_sd

#: Welch segment (s): 256 samples at 10 Hz, a 0.04 Hz bin, 38 half-overlapping segments in a 500 s record
SEG_S = 25.6
#: the band's low end (Hz): above a slow roll's peak (strong-roll's 0.1 Hz) and below the corners a ship's sensors
#: have (0.2-0.5 s: 0.3-0.8 Hz); the next rung if no corner is read. In Hz, not as a fraction of Nyquist, so that
#: a 50 Hz log reads the same band as a 10 Hz one (the review of stop 56 measured 0.48-5.4 of the sd at 50 Hz)
F_LADDER = (0.25, 0.35)
#: the ship's motion's fall-off exponents tried (eq. S3): its spectrum falls much faster than the noise's f^-2
K_GRID = (4, 5, 6, 7, 8, 10, 12)
#: fewest bins in the band for a fit: at 1 Hz sampling the band 0.25-0.5 Hz holds about 6 (white noise read a 0.46 s
#: corner at 1.24 of its sd, the review of stop 56), at 2 s sampling none (the fit failed on an empty band)
MIN_BINS = 8


def segment(dt: float) -> int:
    """Welch's segment in samples at the sample time ``dt``: :data:`SEG_S` seconds (256 at 10 Hz)."""
    return max(8, int(round(SEG_S / dt)))


def welch_psd(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, int]:
    """``(f, P, K)``: Welch's one-sided density (eq. S1) at ``f`` (0 < f < Nyquist) and the number K of segments
    averaged (the density's relative scatter is about ``1 / sqrt(K)`` per bin, a little more for the overlap), in
    segments of :func:`segment`'s length. Not :func:`primitives.spectrum.welch` (scipy's defaults): that one has a
    periodic window, takes out each segment's mean only and steps by ``N - N // 2``, each of which moves the fit."""
    x = np.asarray(x, float)
    nseg = min(segment(dt), len(x))
    starts = np.arange(0, len(x) - nseg + 1, nseg // 2)
    seg = np.stack([x[s : s + nseg] for s in starts])
    t = np.arange(nseg) - (nseg - 1) / 2
    # each segment's own straight line out: the ship's slow motion must not leak through the window's sidelobes
    slope = seg @ t / (t @ t)
    seg = seg - seg.mean(axis=1, keepdims=True) - slope[:, None] * t
    w = np.hanning(nseg)
    p = 2 * dt * np.mean(np.abs(np.fft.rfft(seg * w, axis=1)) ** 2, axis=0) / np.sum(w * w)
    f = np.fft.rfftfreq(nseg, dt)
    keep = (f > 0) & (f < 0.5 / dt)
    return f[keep], p[keep], len(starts)


def _shape(a: float, f: np.ndarray, dt: float) -> np.ndarray:
    """Eq. S2 per unit ``sigma^2``: ``2 dt (1 - a)^2 / |1 - a e^(-i w)|^2``, ``w = 2 pi f dt``."""
    return 2 * dt * (1 - a) ** 2 / (1 + a * a - 2 * a * np.cos(2 * np.pi * f * dt))


def _nnls2(basis: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``argmin |basis x - y|`` over ``x >= 0`` for two columns: the free solution if it is non-negative, else the
    better of the two one-column fits (each clamped at 0), which is where a 2-variable NNLS's optimum lies."""
    x = np.linalg.lstsq(basis, y, rcond=None)[0]
    if np.all(x >= 0):
        return x
    best, cost = np.zeros(2), float(y @ y)
    for j in range(2):
        col = basis[:, j]
        xj = max(float(col @ y) / float(col @ col), 0.0)
        c = float(np.sum((y - xj * col) ** 2))
        if c < cost:
            best, cost = np.where(np.arange(2) == j, xj, 0.0), c
    return best


def _solve(a: float, motion: np.ndarray, f: np.ndarray, p: np.ndarray, dt: float) -> tuple[float, np.ndarray]:
    """Eq. S3's levels ``(sigma^2, c) >= 0`` at fixed ``a`` and the motion term's column ``motion`` (:func:`_motion`) by
    least squares in the relative misfit, weighted once by the data then once by the fit (a weight of the data alone
    biases the levels low), and the misfit."""
    basis = np.stack([_shape(a, f, dt), motion], axis=1)
    w = 1 / p
    for _ in range(2):
        # both levels >= 0: a tone's band can be covered by the motion term with sigma^2 < 0 otherwise (review 1)
        x = _nnls2(basis * w[:, None], p * w)
        model = basis @ x
        if not np.all(model > 0):
            return math.inf, x
        w = 1 / model
    return float(np.sum(((p - model) * w) ** 2)), x


def _motion(f: np.ndarray, k: int) -> np.ndarray:
    """Eq. S3's motion term per unit ``c``: ``(f / f_lo)^-k``; depends on ``k`` only, so built once per fit and ``k``."""
    return (f / f[0]) ** -float(k)


def fit_band(f: np.ndarray, p: np.ndarray, dt: float) -> tuple[float, float]:
    """``(sigma^2, a)`` of eq. S3 fitted to the density ``p`` at ``f``: ``a`` on a grid of 100 in [0, A_MAX] for each
    fall-off ``k`` of :data:`K_GRID`, then by golden section at the best ``k``."""
    grid = np.linspace(0.0, A_MAX, 100)
    motions = [_motion(f, k) for k in K_GRID]
    res = np.array([[_solve(a, m, f, p, dt)[0] for a in grid] for m in motions])
    ik, ia = np.unravel_index(int(np.argmin(res)), res.shape)
    m = motions[ik]
    a = _golden_refine(lambda a: _solve(a, m, f, p, dt)[0], grid, int(ia), 30)
    return float(_solve(a, m, f, p, dt)[1][0]), a


def _golden_refine(fun: Callable[[float], float], grid: np.ndarray, i: int, iters: int) -> float:
    """The minimum of the smooth ``fun`` between the neighbours of its best grid point ``grid[i]``: ``iters`` steps of
    golden-section search (Kiefer 1953), the bracket's midpoint (stop 55's reader, retired at stop 57, shared it)."""
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(iters):
        c, d = hi - g * (hi - lo), lo + g * (hi - lo)
        lo, hi = (lo, d) if fun(c) < fun(d) else (c, hi)
    return 0.5 * (lo + hi)


def spectral_noise(x: np.ndarray, dt: float) -> tuple[float, float]:
    """``(sigma, tau)``: the white noise's sd and its low-pass's time constant (s; 0: white), read from the
    channel's spectrum above the ship's own motion (eq. S1-S3). The noise the channel carries has the sd
    ``sigma sqrt((1 - a) / (1 + a))``."""
    x = np.asarray(x, float)
    if len(x) < 2 * segment(dt) or not np.all(np.isfinite(x)) or np.ptp(x) == 0:
        # too short for a spectrum, non-finite or constant: the white reading (a NaN stays NaN)
        return white_noise_sd(x), 0.0
    f, p, _ = welch_psd(x, dt)
    s2, a = 0.0, A_MAX
    for r in F_LADDER:
        band = f >= r
        if np.count_nonzero(band) < MIN_BINS:  # too few bins above the motion (2 s sampling has none): white
            break
        s2, a = fit_band(f[band], p[band], dt)
        if a < 0.999 * A_MAX:
            break
    if a >= 0.999 * A_MAX or a < A_MIN or not s2 > 0:
        # no corner resolved (the ship's own motion fills the band), white noise, or no noise level at all (a pure
        # tone or a noise-free channel, which the motion term covers alone): main's white reading
        return white_noise_sd(x), 0.0
    return math.sqrt(s2), -dt / math.log(a)
