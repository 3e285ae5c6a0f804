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

from identify.rollmass.model import Known, Load
from identify.rollmass.simulate import RollRecording
from primitives.iir import butter, filtfilt, lfilter  # scipy.signal's, without its import (2 s of CPU)

PHI_SCALE = 5.0  # phi / integrated p amplitude above which phi is in another unit (degrees: 57)
MIN_RHO = 0.4  # |correlation| below which a relation is not judged (weak excitation, noise)
HEEL_RATIO = 3.0  # heel_ratio outside 1/3 .. 3 is a unit error, not a ship (measured 0.975-1.136)
RUDDER_SCALE = 10.0  # rudder_scale_message's factor: a unit error, not a ship (measured 0.41-1.19)
# the scale checks judge recordings of at least a period of the roll band's lower edge (0.1 Hz): on 2-3 s
# cut from the bundled example the rudder's ratio read 36-427 with delta in radians (review of stop 50); 6 s
# and more read as the whole file
MIN_SCALE_S = 10.0
# the low-band a_s / r slope over the profile's steady a_s / r gain, below which r is in deg/s, not a ship: 0.148-2.02
# on 560 basin-truth recordings (7 variants x 20 runs x 4 datasets, stop 52); r in deg/s divides it by 57 (<= 0.035)
YAW_SCALE_MIN = 0.05
G = 9.81  # m/s^2 (the profile's g is 9.81 too; the check's bound is a factor 3)
SHIP_SIGN = "ship sign: roll positive starboard down, yaw positive to starboard, a_s as eq. (7)"


def _band(x: np.ndarray, T: float, lo: float | None, hi: float) -> np.ndarray:
    """``x`` band-passed (low-passed without ``lo``), zero phase, mean removed: for the checks' verdicts
    only, so through the modal form where scipy's loop would run sample by sample (the 0.1-0.45 Hz band at
    50 Hz: 6 times faster, nearer the exact filter; :mod:`primitives.iir`, stop 53)."""
    fs = 1 / T
    b, a = butter(2, [lo, hi] if lo else hi, btype="bandpass" if lo else "lowpass", fs=fs)
    y = filtfilt(b, a, x - x.mean(), modal=True)
    return y - y.mean()


def _trimmed(rec: RollRecording) -> slice:
    """The samples the relations are judged on: without 20 s at each end (the filters' edges) when the
    recording is over four times that long, else all of it."""
    cut = 20 * max(int(1 / rec.T), 1)
    return slice(cut, -cut) if rec.n > 4 * cut else slice(None)


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
    s = _trimmed(rec)
    r1 = _rho(_band(rec.a_s, T, 0.1, 0.45)[s], _band(phi, T, 0.1, 0.45)[s])
    r2 = _rho(_band(rec.a_s, T, None, 0.15)[s], _band(rec.r, T, None, 0.15)[s])
    r3 = _rho(_band(rec.r, T, None, 0.3)[s], _band(_lagged_rudder(rec), T, None, 0.3)[s])
    return r1, r2, r3


def steady_gains(values: dict[str, float], kn: Known, z_f: float, load: Load) -> np.ndarray:
    """Steady outputs ``[p, a_s, r]`` per unit rudder of the profile's sway-roll-yaw model."""
    from identify.rollmass.output_error import model_matrices

    A, B, C, D = model_matrices(values, kn, z_f, load)
    return D[:, 0] - C @ np.linalg.solve(A, B[:, 0])


def expected_signs(values: dict[str, float], kn: Known, z_f: float, load: Load) -> tuple[float, float]:
    """Signs of the steady ``a_s / r`` and ``r / delta`` gains of the profile's sway-roll-yaw model."""
    return gain_signs(steady_gains(values, kn, z_f, load))


def gain_signs(dc: np.ndarray) -> tuple[float, float]:
    """The signs :func:`expected_signs` checks, from the steady gains ``dc`` (:func:`steady_gains`)."""
    return float(np.sign(dc[1] * dc[2])), float(np.sign(dc[2]))


def _lagged_rudder(rec: RollRecording) -> np.ndarray:
    """The rudder through a 1 s first-order lag (the turn's answer to it), mean removed."""
    a = float(np.exp(-rec.T / 1.0))
    return lfilter([1 - a], [1, -a], rec.delta - rec.delta.mean())


def rudder_scale_message(rec: RollRecording, gain: float) -> str | None:
    """``None`` or a one-line message when the yaw rate answers the rudder RUDDER_SCALE times more
    weakly (or strongly) than the profile's steady turning gain ``gain`` (rad/s per rad) says: a rudder
    angle in degrees. The regression slope of r on the lagged rudder below 0.3 Hz over ``gain`` measured
    0.65-0.72 on the own simulator's case-1 runs and 0.41-1.19 on 189 basin-truth recordings (7 variants
    x 3 runs x 3 cases, stop 50); ``delta`` in degrees gives 0.012."""
    T = rec.T
    if rec.n * T < MIN_SCALE_S:
        return None
    s = _trimmed(rec)
    r, d = _band(rec.r, T, None, 0.3)[s], _band(_lagged_rudder(rec), T, None, 0.3)[s]
    if not (np.dot(d, d) > 0 and gain != 0 and abs(_rho(r, d)) >= MIN_RHO):
        return None
    k = float(np.dot(r, d) / np.dot(d, d)) / gain
    if 1 / RUDDER_SCALE <= abs(k) <= RUDDER_SCALE:
        return None
    return (
        f"{rec.name}: column 'delta' is {abs(k):.3g} times the rudder angle the profile's ship turns with as recorded "
        f"(0.4-1.2 on ships like it; degrees give about 0.012): give delta in radians"
    )


def yaw_scale_message(rec: RollRecording, dc: np.ndarray) -> str | None:
    """``None`` or a one-line message when the accelerometer's turn answers ``r`` under YAW_SCALE_MIN times as
    strongly as the profile's steady gains ``dc`` (:func:`steady_gains`) say: a yaw rate in deg/s. Asked
    where the rudder's scale check fails, which cannot tell an ``r`` in deg/s from a ``delta`` in degrees
    (stop 52's sweep: ``r`` in deg/s was refused as "column 'delta' is 41 times ...")."""
    T = rec.T
    s = _trimmed(rec)
    a, r = _band(rec.a_s, T, None, 0.15)[s], _band(rec.r, T, None, 0.15)[s]
    if not (np.dot(r, r) > 0 and dc[2] != 0 and dc[1] != 0):
        return None
    k = float(np.dot(a, r) / np.dot(r, r)) / float(dc[1] / dc[2])
    if abs(k) >= YAW_SCALE_MIN:
        return None
    return (
        f"{rec.name}: column 'r' is {1 / abs(k):.3g} times the yaw rate the accelerometer's turns say (0.5-7 on ships "
        "like it; deg/s give about 57 more): give r in rad/s"
    )


def heel_ratio(rec: RollRecording) -> float:
    """The accelerometer's heel against the integrated roll rate's, in the roll band (0.1-0.45 Hz):
    std(a_s) / (g std(int p)), about 1 by (7) (``a_s ~ g phi``, the ``z_s p'`` term adds a few per
    cent). Measured 1.10 on the own simulator's case-1 runs and 0.975-1.136 on 189 recordings of the
    basin truth family (7 variants x 3 runs x 3 cases, stop 50); ``p`` in deg/s gives 0.019."""
    T = rec.T
    if rec.n * T < MIN_SCALE_S:
        return float("nan")
    s = _trimmed(rec)
    a, phi = _band(rec.a_s, T, 0.1, 0.45)[s], _band(_roll_angle(rec), T, 0.1, 0.45)[s]
    return float(a.std() / (G * phi.std())) if phi.std() > 0 else float("nan")


def scale_message(rec: RollRecording) -> str | None:
    """``None`` or a one-line message when ``p`` and ``a_s`` disagree in scale by more than HEEL_RATIO
    (a roll rate in deg/s, an accelerometer in g)."""
    k = heel_ratio(rec)
    if not np.isfinite(k) or 1 / HEEL_RATIO <= k <= HEEL_RATIO:
        return None
    return (
        f"{rec.name}: columns 'p' and 'a_s' disagree in scale: in the roll band the accelerometer's heel is {k:.3g} "
        "times g times the integrated roll rate (about 1 by eq. (7); p in deg/s gives about 0.019, a_s in g 0.10): give p in "
        "rad/s and a_s in m/s^2"
    )


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
        return scale_message(rec) if clear[0] else None
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
