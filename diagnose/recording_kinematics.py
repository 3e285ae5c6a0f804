"""Kinematic checks of a recording as loaded: u, v against the track x, y and heading psi, and
each rate (r, p) against its angle (psi, phi) (Fossen 2021, eq. 2.40: x north, y east). They run on the
recording's own time axis, before any Froude scaling, so each compares like with like: speeds with
speeds, an angle's change with its rate integrated over the same window. Each raises
:class:`diagnose.recording.RecordingError` in one line naming the file, the column and the fix.
"""

from __future__ import annotations

import math

import numpy as np

from primitives.errors import UserError
from primitives.orderstats import median  # numpy's numbers without its import of numpy.ma (stop 52)


def _error() -> type[UserError]:
    from diagnose.recording import RecordingError

    return RecordingError


def _track_velocity(t: np.ndarray, pos: np.ndarray, psi: np.ndarray, smooth_s: float = 2.0) -> tuple[np.ndarray, ...]:
    """Earth-frame (xd, yd) and body-frame (ub, vb) velocity from the track, smoothed over ~smooth_s
    so position noise does not swamp the comparison."""
    k = _half_window(t, smooth_s)
    dt = t[2 * k :] - t[: -2 * k]
    xd = (pos[2 * k :, 0] - pos[: -2 * k, 0]) / dt
    yd = (pos[2 * k :, 1] - pos[: -2 * k, 1]) / dt
    c, s = np.cos(psi[k:-k]), np.sin(psi[k:-k])
    return xd, yd, c * xd + s * yd, -s * xd + c * yd, slice(k, len(t) - k)


def _half_window(t: np.ndarray, smooth_s: float) -> int:
    ts = float(median(np.diff(t)))
    k = max(1, int(round(smooth_s / ts / 2)))
    return 1 if len(t) <= 2 * k + 2 else k


# A measured signal is within this factor of what the track says, or in other units: the
# geometric middle between m/s and knots (1.944), the closest unit mistake for a speed.
RATIO_TOL = math.sqrt(1.9438)
SPEED_UNITS = (
    (1.9438, "u, v in knots?"),
    (3.6, "u, v in km/h?"),
    (100.0, "u, v in cm/s?"),
    (1000.0, "t in milliseconds (or u, v in mm/s)?"),
    (1 / 60.0, "t in minutes?"),
)
# |correlation| (uncentred) between a rate and the differentiated angle above which the run turns
# (or rolls) well enough above the noise for their ratio and sign to be judged; below it, no verdict.
MIN_RATE_CORR = 0.8
# Mean square mismatch of (u, v) and the track's body-frame velocity, relative to the speed squared,
# beyond which the track, heading and velocities do not describe the same motion (x, y swapped, psi
# from another reference). Legitimate runs (MARIN, every MMG battery run): at most 0.057.
TRACK_MISMATCH = 0.5


def _unit_hint(ratio: float, units: tuple[tuple[float, str], ...]) -> str:
    """The unit mistake whose factor is within 15 % of ``ratio``, as ' (hint)', else ''."""
    for f, text in units:
        if abs(math.log(ratio / f)) < 0.15:
            return f" ({text})"
    return ""


def _track_noise_var(t: np.ndarray, pos: np.ndarray, k: int) -> float:
    """Variance per component of the track's velocity noise over a 2k-sample central difference,
    from the position noise: the second difference of white noise of variance s^2 has variance
    6 s^2 (robust: the median of its square, 0.455 x the variance); a smooth track's own
    acceleration adds (a ts^2)^2, negligible at sample rates that resolve a manoeuvre."""
    if len(pos) < 5:
        return 0.0
    d2 = pos[2:] - 2.0 * pos[1:-1] + pos[:-2]
    d2 = d2[np.all(np.isfinite(d2), axis=1)]
    if len(d2) == 0:
        return 0.0
    s2 = float(median(d2**2)) / (0.455 * 6.0)
    span = float(t[2 * k] - t[0]) if len(t) > 2 * k else float(t[-1] - t[0])
    return 2.0 * s2 / max(span, 1e-12) ** 2


# The track's speed is judged only when its mean square exceeds this multiple of the noise it
# carries (GPS noise differentiated): below it the run holds station (DP) and there is no verdict.
NOISE_MARGIN = 3.0
FRAME_WINDOWS_S = (2.0, 8.0, 30.0)  # track differencing windows tried in turn, shortest first


def check_frame(src: str, t: np.ndarray, pos: np.ndarray, psi: np.ndarray, u: np.ndarray, v: np.ndarray) -> None:
    """u, v must be body-frame velocities over ground in m/s: compare them with the differentiated track.

    Earth frame (u = dx/dt, v = dy/dt) is told from body frame by which rotation fits the track
    better; it can only be told when the heading is away from north, so a run heading north
    passes. Wrong units show as a constant ratio between |(u, v)| and the track's speed (rms,
    the track's mean square less its noise variance, so a noisy track does not read faster), a
    wrong sign as u or v matching the track's body-frame component better negated . A run whose motion is within the track's noise (station keeping) passes.
    """
    if len(t) < 10:
        return
    for smooth_s in FRAME_WINDOWS_S:  # the shortest window whose track speed stands above its noise
        xd, yd, ub, vb, sl = _track_velocity(t, pos, psi, smooth_s)
        um, vm = u[sl], v[sl]
        noise = 2.0 * _track_noise_var(t, pos, sl.start)  # both components: the bias of |track velocity|^2
        sog, spd = np.hypot(xd, yd), np.hypot(um, vm)
        sog_floor = max(0.05, 0.1 * np.nanmax(sog, initial=0.0), 3.0 * math.sqrt(noise))
        moving = (sog > sog_floor) | (spd > max(0.05, 0.1 * np.nanmax(spd, initial=0.0)))
        if moving.sum() < 10:
            return
        speed2 = float(np.nanmean(sog[moving] ** 2)) - noise
        if speed2 > 0 and speed2 >= NOISE_MARGIN * noise:  # > 0: a track standing still, noise-free, has no speed to compare
            break
    else:
        return  # the motion is within the track's noise at every window (station keeping): no verdict
    ratio = math.sqrt(float(np.nanmean(spd[moving] ** 2)) / speed2)
    if not (1 / RATIO_TOL < ratio < RATIO_TOL):
        raise _error()(
            f"{src}: columns 'u', 'v' are {ratio:.3g} x the speed of the track x, y{_unit_hint(ratio, SPEED_UNITS)}; "
            "give u, v in m/s, x, y in m and t in s"
        )
    err_body = np.nanmean(((um - ub) ** 2 + (vm - vb) ** 2)[moving])
    err_earth = np.nanmean(((um - xd) ** 2 + (vm - yd) ** 2)[moving])
    if err_earth < 0.25 * err_body and err_body - noise > 0.05 * speed2:
        raise _error()(
            f"{src}: columns 'u', 'v' look like earth-frame velocities (north, east = dx/dt, dy/dt): "
            "give body-frame surge and sway (u = xd cos psi + yd sin psi, v = -xd sin psi + yd cos psi)"
        )
    _check_signs(src, um, vm, ub, vb, moving)
    if err_body - noise > TRACK_MISMATCH * speed2:
        sxd, syd, sub, svb, _ = _track_velocity(t, pos[:, ::-1], psi)
        swapped = np.nanmean(((um - sub) ** 2 + (vm - svb) ** 2)[moving]) < 0.25 * err_body
        raise _error()(
            f"{src}: columns 'u', 'v' do not follow the track x, y with heading psi (rms mismatch {math.sqrt(err_body):.3g} m/s "
            f"at {math.sqrt(speed2):.3g} m/s)"
            + (
                "; x and y look swapped: x is north, y east"
                if swapped
                else "; give x north, y east in m and psi clockwise from north in rad"
            )
        )


def _check_signs(src: str, um: np.ndarray, vm: np.ndarray, ub: np.ndarray, vb: np.ndarray, moving: np.ndarray) -> None:
    """u or v of the opposite sign to the track's body-frame component: the negated column fits
    the track 4 x better than the column."""
    for name, meas, track, what in (
        ("u", um, ub, "surge xd cos psi + yd sin psi: positive ahead"),
        ("v", vm, vb, "sway -xd sin psi + yd cos psi: positive to starboard"),
    ):
        same = np.nanmean(((meas - track) ** 2)[moving])
        flipped = np.nanmean(((meas + track) ** 2)[moving])
        if flipped < 0.25 * same:
            raise _error()(
                f"{src}: column {name!r} has the opposite sign of the track's body-frame {what} "
                f"(rms mismatch {math.sqrt(same):.3g} m/s, negated {math.sqrt(flipped):.3g}); flip its sign"
            )


def check_rate(
    src: str, t: np.ndarray, rate: np.ndarray, angle: np.ndarray, rate_name: str, angle_name: str, rate_what: str, angle_what: str
) -> None:
    """A rate column (r, p) against its angle (psi, phi): the angle's change over a ~2 s window
    against the rate integrated over the same window (trapezoid), the same sign and, within
    RATIO_TOL, the same size; a ratio of 57.3 says one of them is in degrees. Integrating rather
    than differentiating keeps fast motion (a model's roll period of 1.5 s) at a gain of ~1 at
    any window. Judged only when the run turns (rolls) clearly above the noise (uncentred
    correlation >= MIN_RATE_CORR)."""
    ok = np.isfinite(rate) & np.isfinite(angle)
    if ok.sum() < 10:
        return
    tt, a, m = t[ok], angle[ok], rate[ok]
    k = _half_window(tt, 2.0)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (m[1:] + m[:-1]) * np.diff(tt))])
    ref = a[2 * k :] - a[: -2 * k]
    m = cum[2 * k :] - cum[: -2 * k]
    norm = math.sqrt(float(np.mean(m**2)) * float(np.mean(ref**2)))
    if norm == 0:
        return
    corr = float(np.mean(m * ref)) / norm
    if abs(corr) < MIN_RATE_CORR:
        return
    gain = math.copysign(math.sqrt(float(np.mean(m**2)) / float(np.mean(ref**2))), corr)
    if gain < 0:
        raise _error()(
            f"{src}: column {rate_name!r} has the opposite sign of d{angle_name}/dt (correlation {corr:.2f}): "
            f"the {rate_what} must be the rate of the {angle_what} ({rate_name} > 0 turns {angle_name} positive); flip its sign"
            + (", or say the log's convention: '# yaw_rate_sign: port-positive' (or --yaw-rate-sign)" if rate_name == "r" else "")
        )
    if not (1 / RATIO_TOL < gain < RATIO_TOL):
        units = ((180 / math.pi, f"{rate_name} in deg/s? give rad/s"), (math.pi / 180, f"{angle_name} in degrees? give radians"))
        raise _error()(
            f"{src}: column {rate_name!r} is {gain:.3g} x d{angle_name}/dt{_unit_hint(gain, units)}; "
            f"give {angle_name} in rad and {rate_name} in rad/s"
        )
