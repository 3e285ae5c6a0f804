"""A candidate for the speed a slowing ship's oe model follows, from its surge equation (stop 62, not in the product:
``benchmarks/diag_rollmass_speed_terms.py --switches surge`` puts it in place of
:func:`identify.rollmass.speed.followed_speed`'s low-passed speed where a recording's speed is followed).

The surge equation of a ship turning at small drift (Fossen 2011, eq. 6.103 linearised in the speed about the
straight-running ``U0``; the rudder's drag and the sway-yaw coupling ``(m + X_vr) v r`` kept as forces)

    (m - X_udot) u' = X_u (u - U0) + X_dd delta^2 + X_vr v r                                         (S1)

makes the speed a first-order lag (time constant ``tau = (m - X_udot) / |X_u|``, a few seconds) of the drag. In a
quasi-steady turn the sway velocity is linear in the rudder and the yaw rate, ``v = a delta + b r``, so
``v r = a delta r + b r^2``, and

    u / mean(u) = c0 + L_tau[c1 delta^2 + c2 delta r + c3 r^2 + c4 r + c5 delta] + c6 exp(-t / tau)   (S2)

with ``L_tau`` the causal first-order lag ``tau y' + y = x`` (each regressor filtered from its first value, as a
ship in steady running), ``c4 r`` and ``c5 delta`` absorbing the yaw gyro's bias and the rudder's zero in the
squares (``(r - b)^2 = r^2 - 2 b r + b^2``), and ``exp(-t / tau)`` the speed's own transient from the state the
recording starts in. ``c0..c6`` are least squares on the measured ``u / mean(u)`` (unbiased under a positioning error
independent of the turns), ``tau`` the best of a grid (:data:`TAU_GRID`). The speed followed is (S2) plus the
:data:`~identify.rollmass.speed.SPEED_LP_HZ` low-pass of what (S2) leaves (what the quasi-steady sway misses, and the
positioning's slow error, which no model of the ship can tell from the speed): :func:`followed`.

Why a candidate: the zero-phase low-pass alone (stop 43) keeps the positioning's error out of the rudder input, but it
also rounds the speed's kink at every rudder step (the drag steps, the speed's slope with it) over about a second on
each side, before the turn as well as after it, where the roll's transient carries the load's information. On the
basin truth's quiet ``speed_loss`` runs 0-1 (30-run family) the low-pass's error is 0.53-0.80 % sd of the speed, (S2)'s
0.14-0.20 %; what that does to the load: docs/mass-accuracy.md, stop 62.
"""

from __future__ import annotations

import numpy as np

from identify.rollmass import speed
from identify.rollmass.simulate import RollRecording
from primitives.iir import filtfilt, lfilter
from primitives.zerophase import lowpass

# time constants [s] tried for (S2): the model ship's (m - X_udot)/|X_u| is about 5 s; a real ship's can be
# tens of seconds, a basin model's a second or two
TAU_GRID = np.geomspace(1.0, 40.0, 24)


def _lagged(x: np.ndarray, tau: float, T: float) -> np.ndarray:
    """``L_tau[x]`` of (S2) along axis 0: the causal first-order lag, its state started at ``x[0]`` (a ship in steady
    running)."""
    a = float(np.exp(-T / tau))
    return lfilter(np.array([1.0 - a]), np.array([1.0, -a]), x - x[0], axis=0) + x[0]


def _design(delta: np.ndarray, r: np.ndarray, tau: float, T: float) -> np.ndarray:
    """The columns of (S2) at time constant ``tau``."""
    t = np.arange(len(delta)) * T
    drag = np.column_stack([delta * delta, delta * r, r * r, r, delta])
    return np.column_stack([np.ones_like(delta), _lagged(drag, tau, T), np.exp(-t / tau)])


def surge_fit(s: np.ndarray, delta: np.ndarray, r: np.ndarray, T: float) -> tuple[np.ndarray, float]:
    """(S2) fitted to the speed's variation ``s = u / mean(u)`` driven by the measured ``delta`` and ``r`` at sample
    time ``T``: the fitted variation and its time constant ``tau`` (the grid's best, least squares)."""
    best = (np.inf, s * 0.0 + np.mean(s), float(TAU_GRID[0]))
    for tau in TAU_GRID:
        X = _design(delta, r, float(tau), T)
        scale = np.maximum(np.abs(X).max(axis=0), 1e-300)  # columns of unlike size (r^2 ~ 1e-3, 1)
        coef = np.linalg.lstsq(X / scale, s, rcond=None)[0]
        fit = (X / scale) @ coef
        sse = float(np.sum((s - fit) ** 2))
        if sse < best[0]:
            best = (sse, fit, float(tau))
    return best[1], best[2]


_FOLLOWED: dict[int, tuple] = {}  # followed()'s last answers by recording (the oe fit asks on every residual evaluation)


def followed(rec: RollRecording) -> np.ndarray | None:
    """:func:`identify.rollmass.speed.followed_speed`'s decision (None: the speed held), and where it follows the speed
    (S2) fitted to ``u / mean(u)`` plus the low-pass of its remainder in place of the low-pass alone; cached by the
    recording's arrays (a grid of least squares)."""
    if _ORIGINAL(rec) is None:
        return None
    hit = _FOLLOWED.get(id(rec.u))
    if hit is not None and hit[0] is rec.u and hit[1] is rec.delta and hit[2] is rec.r:
        return hit[3]
    s = rec.u / np.mean(rec.u)
    fit, _ = surge_fit(s, rec.delta, rec.r, rec.T)
    out = fit + filtfilt(*lowpass(2, speed.SPEED_LP_HZ, 1.0 / rec.T), s - fit, padtype="even")
    if len(_FOLLOWED) > 64:
        _FOLLOWED.clear()
    _FOLLOWED[id(rec.u)] = (rec.u, rec.delta, rec.r, out)
    return out


_ORIGINAL = speed.followed_speed
