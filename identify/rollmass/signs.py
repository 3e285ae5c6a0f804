"""Sign checks of a roll recording's ``p``, ``a_s``, ``r`` and ``delta`` (Linder et al. 2015, (6)-(8)).

Three relations any rolling, turning ship obeys give three votes:

* ``a_s`` against the integrated roll rate, in the roll band (0.1-0.45 Hz): ``a_s ~ g phi`` (7), so the
  two move together whatever the ship;
* ``a_s`` against ``r`` at low frequency (below 0.15 Hz, the turns): the steady heel and the
  centripetal term of (7)-(8), whose sign the profile's model gives (its steady-state gains);
* ``r`` against the rudder (lagged 1 s): the sign of the profile's steady turning gain.

A vote counts only when the correlation is clear (``|rho| >= MIN_RHO``). From the votes the flipped
column is named: ``p`` (first fails, second holds), ``a_s`` (first and second fail), ``r`` (first
holds, second fails), ``delta`` (first two hold, third fails). With all three holding, a ``phi`` column
(which carries the wall-sided restoring) is checked against the integrated roll rate in the roll band: its
sign, and its scale (degrees give 57 times the amplitude).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, filtfilt, lfilter

from identify.rollmass.model import Known, Load
from identify.rollmass.simulate import RollRecording

PHI_SCALE = 5.0  # phi / integrated p amplitude above which phi is in another unit (degrees: 57)
MIN_RHO = 0.4  # |correlation| below which a relation is not judged (weak excitation, noise)
SHIP_SIGN = "ship sign: roll positive starboard down, yaw positive to starboard, a_s as eq. (7)"


def _band(x: np.ndarray, T: float, lo: float | None, hi: float) -> np.ndarray:
    fs = 1 / T
    b, a = butter(2, [lo, hi] if lo else hi, btype="bandpass" if lo else "lowpass", fs=fs)
    y = filtfilt(b, a, x - x.mean())
    return y - y.mean()


def _rho(a: np.ndarray, b: np.ndarray) -> float:
    sa, sb = a.std(), b.std()
    return float(np.mean(a * b) / (sa * sb)) if sa > 0 and sb > 0 else 0.0


def _roll_angle(rec: RollRecording) -> np.ndarray:
    """The roll rate integrated (its mean, mostly gyro bias, removed first)."""
    return np.cumsum(rec.p - rec.p.mean()) * rec.T


def relations(rec: RollRecording) -> tuple[float, float, float]:
    """Correlations ``(a_s ~ int p, a_s ~ r, r ~ lagged delta)`` of one recording."""
    T = rec.T
    phi = _roll_angle(rec)
    cut = 20 * max(int(1 / T), 1)  # the filters' edges
    s = slice(cut, -cut) if rec.n > 4 * cut else slice(None)
    r1 = _rho(_band(rec.a_s, T, 0.1, 0.45)[s], _band(phi, T, 0.1, 0.45)[s])
    r2 = _rho(_band(rec.a_s, T, None, 0.15)[s], _band(rec.r, T, None, 0.15)[s])
    a = float(np.exp(-T / 1.0))
    lag = lfilter([1 - a], [1, -a], rec.delta - rec.delta.mean())
    r3 = _rho(_band(rec.r, T, None, 0.3)[s], _band(lag, T, None, 0.3)[s])
    return r1, r2, r3


def expected_signs(values: dict[str, float], kn: Known, z_f: float, load: Load) -> tuple[float, float]:
    """Signs of the steady ``a_s / r`` and ``r / delta`` gains of the profile's sway-roll-yaw model."""
    from identify.rollmass.output_error import model_matrices

    A, B, C, D = model_matrices(values, kn, z_f, load)
    dc = D[:, 0] - C @ np.linalg.solve(A, B[:, 0])  # steady outputs [p, a_s, r] per unit rudder
    return float(np.sign(dc[1] * dc[2])), float(np.sign(dc[2]))


def check_signs(rec: RollRecording, expect: tuple[float, float]) -> str | None:
    """``None`` or a one-line message naming the column whose sign is flipped and the fix."""
    r1, r2, r3 = relations(rec)
    s_ar, s_rd = expect
    clear = [abs(x) >= MIN_RHO for x in (r1, r2, r3)]
    ok1, ok2, ok3 = r1 > 0, r2 * s_ar > 0, r3 * s_rd > 0
    col = None
    if clear[0] and clear[1]:
        col = "p" if (not ok1 and ok2) else "a_s" if (not ok1 and not ok2) else "r" if not ok2 else None
        if col is None and clear[2] and not ok3:
            col = "delta"
    elif clear[0] and not ok1:
        col = "p or a_s"
    if col is None and rec.phi is not None:
        phi_b, int_p = _band(rec.phi, rec.T, 0.1, 0.45), _band(_roll_angle(rec), rec.T, 0.1, 0.45)
        if _rho(phi_b, int_p) < -MIN_RHO:
            col = "phi"
        elif int_p.std() > 0 and phi_b.std() > PHI_SCALE * int_p.std():
            # a roll angle in degrees whose peak stays under the reader's 1 rad bound (under 57 deg of heel)
            ratio = phi_b.std() / int_p.std()
            return (
                f"{rec.name}: column 'phi' is {ratio:.0f} times the integrated roll rate in the roll band "
                f"(57 for degrees): give the roll angle in radians"
            )
    if col is None:
        return None
    what = {
        "phi": "the roll angle is opposite to the integrated roll rate",
        "p": "the roll rate integrates to a roll angle opposite to the accelerometer's heel",
        "a_s": "the accelerometer's heel is opposite to both the roll rate and the turn",
        "r": "the yaw rate turns the ship against its heel",
        "delta": "the yaw rate answers the rudder the other way round from the profile's ship",
        "p or a_s": "the roll rate and the accelerometer disagree on the heel",
    }[col]
    return (
        f"{rec.name}: column '{col}' looks negated ({what}; correlations {r1:+.2f}, {r2:+.2f}, {r3:+.2f}); "
        f"negate it ({SHIP_SIGN})"
    )
