"""Checks and conversions that make a recording fit a ship profile, each saying what it did.

- :func:`check_values`: physically possible magnitudes and a ship that moves (refuses an
  all-zeros file, u = 1e308, a time axis that would need billions of samples);
- (:mod:`diagnose.recording_kinematics`: u, v against the track, r and p against psi and phi);
- :func:`check_inputs`: inputs within the profile's input limits, or the unit they are likely in;
- :func:`apply_rudder_sign`: a rudder angle in the other sign convention (header ``# rudder_sign:``)
  converted to the profile's;
- :func:`check_rudder_sign`: the yaw rate's response to the rudder against the profile's sign;
- :func:`check_yaw_moment_sign`: the same for a generalized yaw moment tau_n;
- :func:`check_speed`: speeds within the profile's speed range (another ship, a model scale run
  without its header);
- :func:`froude_scale`: a model-scale recording to full scale (Froude similarity);
- :func:`check_sample_time`: refuse, or resample and say so, a sample time other than the profile's.

All are pure functions on :class:`diagnose.recording.Recording` (no I/O) and raise
:class:`RecordingError` with one line naming the file, the column and the fix.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from primitives.errors import UserError
from primitives.goodness import coefficient_t

if TYPE_CHECKING:
    from diagnose.recording import Recording
    from primitives.ship import ShipProfile

# Largest magnitudes a real run can show (a fast craft does 40 m/s; 5 rad/s is a spinning model).
MAX_ABS = {"u": 100.0, "v": 100.0, "r": 10.0, "p": 10.0, "phi": 3.2, "x": 1e8, "y": 1e8, "psi": 1e5, "wind_speed": 150.0}
MAX_GRID_SAMPLES = 5_000_000  # a uniform grid beyond this is a unit mistake, not a trial
# Froude scaling exponents of lambda per signal kind (length ~ lambda, time ~ sqrt(lambda)).
FROUDE_POWER = {
    "x": 1.0,
    "y": 1.0,
    "u": 0.5,
    "v": 0.5,
    "r": -0.5,
    "p": -0.5,
    "n": -0.5,
    "n1": -0.5,
    "n2": -0.5,
    "wind_speed": 0.5,
    "tau_x": 3.0,
    "tau_y": 3.0,
    "tau_n": 4.0,
}


def _error() -> type[UserError]:
    from diagnose.recording import RecordingError

    return RecordingError


def check_grid(src: str, t: np.ndarray, ts: float) -> None:
    """Refuse a time axis whose uniform grid would need more than MAX_GRID_SAMPLES samples."""
    n = (float(t[-1]) - float(t[0])) / ts
    if not math.isfinite(n) or n > MAX_GRID_SAMPLES:
        raise _error()(
            f"{src}: column 't' spans {t[-1] - t[0]:.3g} s, {n:.3g} samples of {ts:g} s (limit {MAX_GRID_SAMPLES:,}); "
            "give time in seconds and a matching '# sample_time:'"
        )


def check_values(src: str, cols: dict[str, np.ndarray]) -> None:
    """Finite, physically possible values, and a ship that moves (an all-zeros file has nothing to fit)."""
    for k, v in cols.items():
        bad = np.isinf(v)
        if bad.any():
            raise _error()(
                f"{src}: column {k!r} row {int(np.argmax(bad)) + 2}: infinite value; give finite numbers or leave the cell empty"
            )
        lim = MAX_ABS.get(k)
        if lim is not None and np.nanmax(np.abs(v), initial=0.0) > lim:
            i = int(np.nanargmax(np.abs(v)))
            raise _error()(
                f"{src}: column {k!r} row {i + 2}: {v[i]:.3g} is beyond any ship (|{k}| <= {lim:g} in SI units); check its units"
            )
    moving = [
        k
        for k in ("x", "y", "psi", "u", "v", "r")
        if k in cols and np.nanmax(cols[k], initial=0) - np.nanmin(cols[k], initial=0) > 0
    ]
    speed = max((np.nanmax(np.abs(cols[k]), initial=0.0) for k in ("u", "v") if k in cols), default=0.0)
    if not moving and speed == 0:
        raise _error()(f"{src}: the ship does not move (x, y, psi and u, v, r are constant); nothing to diagnose: check the file")


# Input units a column is most likely in when it exceeds the profile's limits: (factor to SI, unit, SI unit).
INPUT_UNITS = {"delta": (180 / math.pi, "deg", "rad"), "alpha": (180 / math.pi, "deg", "rad"), "n": (60.0, "rpm", "rev/s")}
# An actuator cannot go far beyond its limit: a peak beyond this multiple of it is another unit
# (or another ship); a little above it is a profile limit set conservatively, or noise.
INPUT_LIMIT_TOL = 1.25
# A unit is hinted only when the column read in it peaks within this band of the limit (a run uses
# a good part of its actuator's range): 2.6 rev/s is not 2.6 rpm, 0.8 rad is not 0.8 deg.
UNIT_BAND = (0.2, INPUT_LIMIT_TOL)


def _input_unit(name: str) -> tuple[float, str, str] | None:
    base = name.rstrip("0123456789")
    return INPUT_UNITS.get(base)


def check_inputs(rec, profile) -> None:
    """Refuse inputs beyond the ship's limits, naming the unit they are most likely in (a rudder
    angle in degrees, a shaft speed in rpm = 60 x rev/s, forces x 1e6 ...)."""
    for name in profile.inputs:
        lo, hi = profile.input_limits.get(name, (-math.inf, math.inf))
        x = rec.channels.get(name)
        if x is None or not np.isfinite([lo, hi]).all():
            continue
        span = max(abs(lo), abs(hi))
        peak = float(np.nanmax(np.abs(x), initial=0.0))
        if not (span > 0 and peak > INPUT_LIMIT_TOL * span):
            continue
        unit = _input_unit(name)
        lim = f"{span:g}"
        if unit is not None:
            f, u_name, si = unit
            lim = f"{span:g} {si}" + (f" ({span * f:.3g} {u_name})" if u_name == "deg" else "")
            if UNIT_BAND[0] * span <= peak / f <= UNIT_BAND[1] * span:  # in that unit a plausible order
                raise _error()(
                    f"{rec.source}: column {name!r} reaches {peak:.3g}, {peak / span:.3g} x the {lim} limit of ship "
                    f"{profile.name!r}: {u_name}? give {si} ({name} in {u_name} / {f:.4g})"
                )
        raise _error()(
            f"{rec.source}: column {name!r} reaches {peak:.3g}, which exceeds the {lim} limit of ship {profile.name!r} "
            f"({peak / span:.3g} x): check its units (SI: N, N m, rad, rev/s) and the recording's scale, the profile's "
            "[input_limits], or choose the matching --ship"
        )


# A recording's top speed within this factor of the speed the profile expects: beyond it, it is
# another ship or a model-scale run taken for full scale (a factor sqrt(10): a basin model at 1:10
# or smaller sails sqrt(lambda) >= 3.2 x slower than its ship).
SPEED_FACTOR = math.sqrt(10.0)
# A run sampled this many times faster than its profile is on a model's time scale (lambda >= 9).
MODEL_TS_FACTOR = 3.0


def _profile_speeds(rec, profile) -> tuple[float | None, float, str]:
    """(expected speed, top speed, what the expectation is) from the profile's speed range: the
    straight-course speed its model holds at the run's own shaft speed going ahead (rudder/propeller
    ships with ``n`` > 0 within its limits), else the profile's service speed when the run is
    sampled far faster than the profile (a model's time scale), else None: a slow run (a manoeuvre
    at low speed, station keeping, astern, engine stopped) is no evidence of another scale. Top:
    at the engine's highest rps."""
    cruise = float(profile.cruise_speed_mps)
    expect, what, top = None, "", cruise
    if rec.sample_time < profile.sample_time / MODEL_TS_FACTOR:
        expect = cruise
        what = (
            f"the profile's {cruise:g} m/s service speed, sampled every {rec.sample_time:.3g} s "
            f"(the profile: {profile.sample_time:g} s)"
        )
    n = rec.channels.get("n")
    lim = profile.input_limits.get("n")
    if "n" not in profile.inputs or lim is None or not np.isfinite(lim).all():
        return expect, top, what
    from primitives.helm import steady_speed

    try:
        top = max(cruise, steady_speed(profile, float(lim[1])))
        if n is not None:
            n_run = float(np.nanpercentile(n, 90))
            if 0 < n_run <= INPUT_LIMIT_TOL * max(abs(lim[0]), abs(lim[1])):
                u_n = steady_speed(profile, n_run)
                if u_n > 0:
                    expect, what = u_n, f"the {u_n:.3g} m/s ship {profile.name!r} sails at this run's {n_run:.3g} rev/s"
    except (ValueError, FloatingPointError, ArithmeticError):  # a profile whose surge balance has no root
        pass
    return expect, top, what


def ship_header_note(rec, profile) -> str | None:
    """A note when the recording's ``# ship:`` header names another ship than the profile diagnosed against.

    Not a refusal, as ``shiptrial mass`` warns (``identify.rollmass.api.check_ship``) when a profile the user chose
    meets another header: ``--ship`` is always the user's choice here, and a recording of a truly different ship is
    refused by its content first (its input columns, speed range, Froude scale or sample time: a KVLCC2 run against
    the model ship lacks tau_x); what passes is most likely a header written with a wrong or stale name. The header
    must name the profile or the vessel it models (its ``vessel`` field: kvlcc2-linear is a model of the kvlcc2),
    equal but for case and punctuation (:func:`primitives.profile_tables.names_ship`, mass's rule too; stop 62: a
    prefix let 'model' pass for 'model-ship')."""
    from primitives.profile_tables import names_ship

    said = str(rec.meta.get("ship", "")).strip()
    if not said or names_ship(said, profile.name, profile.vessel):
        return None
    return (
        f"{rec.source}: header '# ship: {said}' but --ship is {profile.name!r}: diagnosed against "
        f"{profile.name}'s model; if the run is of {said}, give its profile with --ship, else correct the header "
        f"(a profile that models {said} says so with vessel = {said!r})"
    )


def ship_notes(rec) -> list[str]:
    """The ``# ship:`` header notes :func:`rudder_in_profile_sign` attached to ``rec`` (the CLI prints them)."""
    return [n for n in rec.notes if n.startswith(f"{rec.source}: header '# ship: ")]


def check_speed(rec, profile) -> None:
    """Refuse a recording whose speeds are far from the ship's (another ship, or a model-scale run
    without its '# scale: model' header): its top speed (90th percentile) against the profile's
    speed range (:func:`_profile_speeds`), within SPEED_FACTOR. Too slow is judged only against
    evidence the run should be faster (its own shaft speed ahead, or a model's sample time)."""
    top = float(np.nanpercentile(np.hypot(rec.y[:, 0], rec.y[:, 1]), 90))
    expect, fastest, what = _profile_speeds(rec, profile)
    if expect is not None and top * SPEED_FACTOR < expect:
        lam = (expect / max(top, 1e-9)) ** 2
        raise _error()(
            f"{rec.source}: speeds ({top:.3g} m/s at the top) are {top / expect:.2g} x {what}: a model-scale recording "
            f"without a '# scale: model' header (Froude scale ~{lam:.0f})? or another ship: add '# scale: model' and "
            "'# scale_factor: LAMBDA' to the header, or choose the matching --ship"
        )
    if top > SPEED_FACTOR * fastest:
        raise _error()(
            f"{rec.source}: speeds ({top:.3g} m/s at the top) are {top / fastest:.2g} x the {fastest:.3g} m/s ship "
            f"{profile.name!r} can sail: another ship, or u, v in other units? give m/s or choose the matching --ship"
        )


# |t| of the data's rudder coefficient above which its sign is a verdict (3 standard errors). On
# the MARIN runs and every MMG battery run (calm, diagnose, validate; full and model scale) the
# t value has the profile's sign and |t| >= 4.2; flipped, the opposite sign with |t| >= 4.2.
# The ordinary least-squares t (coefficient_t, lags=0) is right here, unlike yawid's smoothed dr/dt: the one-step
# fit holds r(k) as a regressor, which takes the correlation the differencing puts in the residuals. Measured (stop
# 60, docs/bad-input-sweep.md "Stop 60", 500 draws, white and AR(1) noise at 1-50 x): with r pure noise the t's
# spread stays 0.97-1.15, not growing with the noise, and a 3-sigma refusal fires on 0-4 of 500 (Newey-West lags
# 1-5: the same).
RUDDER_T = 3.0


# The rudder's sign is judged only when it moves: peak-to-peak (over the samples going ahead) at
# least this fraction of the profile's rudder limit (3.5 deg of 35) and never under 2 deg.
MIN_RUDDER_PTP = 0.1
# Samples going ahead: u above this fraction of the run's top speed (astern the flow reverses the
# rudder's effect; near zero speed it has none).
AHEAD_FRACTION = 0.2


def _ahead(rec) -> np.ndarray:
    """Steps k (0..N-1) that start going ahead (u(k) > AHEAD_FRACTION x the run's top |u|)."""
    u = rec.y[:-1, 0]
    top = float(np.nanmax(np.abs(rec.y[:, 0]), initial=0.0))
    return np.isfinite(u) & (u > AHEAD_FRACTION * top) & (top > 0)


def rudder_response_t(rec) -> float:
    """t value of the rudder's coefficient in a one-step least-squares fit, over the steps going
    ahead (:func:`_ahead`), of the yaw-rate increment r(k+1) - r(k) on r(k), v(k), delta(k) U(k)^2,
    U(k)^2 and a constant (the form of a linear yaw equation, Ljungberg (2022) (3.60)): its sign is the sign
    of the ship's rudder yaw derivative, whatever the model. The U^2 column takes what a change of
    speed does, so a rudder held constant carries no information (a large standard error)."""
    y, d = rec.y, rec.channels["delta"]
    ahead = _ahead(rec)
    dr = np.diff(y[:, 2])[ahead]
    u2 = (y[:-1, 0] ** 2 + y[:-1, 1] ** 2)[ahead]
    X = np.column_stack([y[:-1, 2][ahead], y[:-1, 1][ahead], d[:-1][ahead] * u2, u2, np.ones(len(dr))])
    if len(dr) <= X.shape[1] + 5:
        return 0.0
    others = np.delete(X, 2, axis=1)
    own = X[:, 2] - others @ np.linalg.lstsq(others, X[:, 2], rcond=None)[0]
    if not np.linalg.norm(own) > 1e-6 * np.linalg.norm(X[:, 2]):
        return 0.0  # delta U^2 is a combination of the other columns (a constant rudder): no information
    return coefficient_t(X, dr, 2)


def _profile_rudder_sign(profile, rec) -> float:
    """Sign of d r(k+1) / d delta(k) of the profile's model on a straight course ahead at the
    run's median speed going ahead."""
    return _profile_input_sign(profile, rec, "delta", 0.01)


def _profile_input_sign(profile, rec, name: str, step: float) -> float:
    """Sign of d r(k+1) / d ``name``(k) of the profile's model on a straight course ahead at the run's median speed
    going ahead, the other inputs at their medians (``step``: the input's change either side of zero)."""
    from primitives.simulate import model_signals

    ahead = _ahead(rec)
    u = float(np.median(np.hypot(rec.y[:-1, 0], rec.y[:-1, 1])[ahead]))
    inputs = {k: np.array(float(np.median(rec.channels[k][:-1][ahead]))) for k in profile.inputs if k in rec.channels}
    out = []
    for dd in (-step, step):
        sig = model_signals(profile, np.array([u, 0.0, 0.0]), np.array(0.0), inputs | {name: np.array(dd)})
        out.append(float(profile.model.increments(sig, profile.params())[2]))
    return float(np.sign(out[1] - out[0]))


def apply_rudder_sign(rec: Recording, profile: ShipProfile) -> Recording:
    """The recording with its rudder angle in the profile's sign convention, and a note when it
    was converted. The header ``# rudder_sign: port-positive|starboard-positive`` says which side a
    positive delta turns the ship to (MMG's convention, Yasukawa & Yoshimura 2015, is
    starboard-positive; the MARIN / ``kvlcc2`` profile's is port-positive); a recording without it
    is taken in the profile's convention (and :func:`check_rudder_sign` judges that)."""
    said = rec.meta.get("rudder_sign")
    if said is None:
        return rec
    if "delta" not in profile.inputs or "delta" not in rec.channels:
        note = f"rudder_sign {said} not used: ship {profile.name!r} or the file has no rudder angle 'delta'"
        return rec if note in rec.notes else replace(rec, notes=[*rec.notes, note])
    theirs = 1.0 if said == "starboard-positive" else -1.0
    ours = float(np.sign(profile.helm.starboard_sign))
    if theirs == ours:
        return rec
    mine = "starboard-positive" if ours > 0 else "port-positive"
    note = f"rudder angle converted from the file's {said} convention to ship {profile.name!r}'s {mine} (delta x -1)"
    meta = {**rec.meta, "rudder_sign": mine, "rudder_sign_converted_from": said}
    return replace(rec, channels={**rec.channels, "delta": -rec.channels["delta"]}, meta=meta, notes=[*rec.notes, note])


def check_rudder_sign(rec, profile) -> None:
    """Refuse a rudder angle of the opposite sign to the profile's: the yaw rate's response to it
    (:func:`rudder_response_t`) has the opposite sign of the profile's rudder yaw derivative. Judged
    on the steps going ahead, when the rudder moves there (MIN_RUDDER_PTP of its limit)."""
    if "delta" not in profile.inputs or "delta" not in rec.channels or rec.n_samples < 20:
        return
    ahead = _ahead(rec)
    if ahead.sum() < 20:
        return
    lo, hi = profile.input_limits.get("delta", (-math.radians(35.0), math.radians(35.0)))
    span = max(abs(lo), abs(hi)) if np.isfinite([lo, hi]).all() else math.radians(35.0)
    if np.ptp(rec.channels["delta"][:-1][ahead]) < max(MIN_RUDDER_PTP * span, math.radians(2.0)):
        return  # the rudder does not move: no response to judge
    sign = _profile_rudder_sign(profile, rec)
    tval = rudder_response_t(rec)
    if sign != 0 and tval * sign < -RUDDER_T:
        side = "port" if sign < 0 else "starboard"
        raise _error()(
            f"{rec.source}: column 'delta' turns the ship the other way from ship {profile.name!r}: the yaw rate "
            f"responds to it with the opposite sign of the profile's rudder yaw derivative (t = {tval:+.1f} in a "
            f"one-step fit going ahead); flip the sign of delta, or say the file's convention in its header "
            f"('# rudder_sign: {'starboard' if side == 'port' else 'port'}-positive', converted on reading; "
            f"in this profile a positive delta turns to {side})" + _said_wrong(rec)
        )


def check_yaw_moment_sign(rec, profile) -> None:
    """Refuse a generalized yaw moment ``tau_n`` of the opposite sign to the profile's: the t value of its
    coefficient in a one-step fit going ahead of r(k+1) - r(k) on r(k), v(k), tau_n(k) and a constant (the linear
    yaw row of Ljungberg (2022) (9.1)) against the sign of the profile's own d r(k+1) / d tau_n(k). Measured on the
    52 model-ship battery recordings (control, each single effect and the combined ones; seeds 1, 2; diagnose and
    validate): t = +15.2 (actuator delay) .. +73.9; the same negated, the opposite sign."""
    if "tau_n" not in profile.inputs or "tau_n" not in rec.channels or rec.n_samples < 20:
        return
    ahead = _ahead(rec)
    n = rec.channels["tau_n"][:-1][ahead]
    if ahead.sum() < 20 or not np.ptp(n) > 0:
        return
    y = rec.y
    dr = np.diff(y[:, 2])[ahead]
    X = np.column_stack([y[:-1, 2][ahead], y[:-1, 1][ahead], n, np.ones(len(dr))])
    tval = coefficient_t(X, dr, 2)
    sign = _profile_input_sign(profile, rec, "tau_n", 0.01 * float(np.max(np.abs(n))))
    if sign != 0 and tval * sign < -RUDDER_T:
        raise _error()(
            f"{rec.source}: column 'tau_n' turns the ship the other way from ship {profile.name!r}: the yaw rate "
            f"responds to it with the opposite sign of the profile's yaw moment derivative (t = {tval:+.1f} in a one-step "
            "fit going ahead); flip the sign of tau_n (clockwise, to starboard, positive)"
        )


def _said_wrong(rec) -> str:
    """Who named the wrong rudder convention: the --rudder-sign option or the file's header."""
    if rec.meta.get("rudder_sign_from") == "option":
        return " - the rudder_sign given as an option (--rudder-sign) is wrong"
    return " - the header's rudder_sign is wrong" if "rudder_sign" in rec.meta else ""


def with_conventions(recs: list, environment: str | None = None, rudder_sign: str | None = None) -> list:
    """The recordings with ``environment`` and ``rudder_sign`` standing for their header lines
    (``# environment:``, ``# rudder_sign:``; the CLI's --environment and --rudder-sign). An unknown
    value is refused. A recording whose rudder was converted already keeps its convention."""
    from diagnose.recording import ENVIRONMENTS, RUDDER_SIGNS

    for name, value, allowed in (("environment", environment, ENVIRONMENTS), ("rudder_sign", rudder_sign, RUDDER_SIGNS)):
        if value is not None and value not in allowed:
            raise _error()(f"{name} {value!r} is not one of {', '.join(allowed)}")
    out = []
    for rec in recs:
        meta = dict(rec.meta)
        if environment is not None:
            meta["environment"] = environment
        if rudder_sign is not None and "rudder_sign_converted_from" not in meta:
            meta |= {"rudder_sign": rudder_sign, "rudder_sign_from": "option"}
        out.append(replace(rec, meta=meta))
    return out


def rudder_in_profile_sign(recs: list, profile) -> list:
    """Every recording's rudder in the profile's convention (:func:`apply_rudder_sign`), or refused
    when it or its yaw moment turns the ship the other way (:func:`check_rudder_sign`,
    :func:`check_yaw_moment_sign`), with its ``# ship:`` header note (:func:`ship_header_note`) attached once:
    :func:`conform` and ``diagnose.api.run`` both come here. Idempotent: a converted recording says the
    profile's convention."""
    out = []
    for rec in recs:
        rec = apply_rudder_sign(rec, profile)
        check_rudder_sign(rec, profile)
        check_yaw_moment_sign(rec, profile)
        note = ship_header_note(rec, profile)  # the one place it is attached: conform and api.run both come here
        out.append(replace(rec, notes=[*rec.notes, note]) if note and note not in rec.notes else rec)
    return out


def froude_scale(rec, factor: float | None = None):
    """A model-scale recording at full scale by Froude similarity, and a note saying so.

    With scale factor lambda: lengths x lambda, times and speeds x sqrt(lambda), rates and
    propeller revolutions / sqrt(lambda), forces x lambda^3 and moments x lambda^4 (same water
    density), angles unchanged. ``factor`` defaults to the header's ``# scale_factor:``. A
    recording already at full scale is returned unchanged with an empty note.
    """
    lam = factor if factor is not None else rec.scale_factor
    if rec.scale == "full" and factor is None:
        return rec, ""
    if lam is None or not (math.isfinite(lam) and lam > 0):
        raise _error()(
            f"{rec.source}: Froude scaling needs a scale factor > 0 ('# scale_factor: 45.7' in the header), got {lam!r}"
        )
    s = math.sqrt(lam)
    y = rec.y * np.array([s, s, 1 / s])
    chans = {k: v * lam ** FROUDE_POWER[k] if k in FROUDE_POWER else v.copy() for k, v in rec.channels.items()}
    note = (
        f"Froude-scaled from model to full scale with lambda = {lam:g}: lengths x {lam:g}, times and speeds x {s:.4g}, "
        f"rates and revolutions / {s:.4g}, forces x lambda^3, moments x lambda^4"
    )
    meta = {**rec.meta, "scale": "full", "scale_factor": "1", "froude_scaled_from": f"model, lambda = {lam:g}"}
    out = replace(
        rec, t=rec.t * s, y=y, pos=rec.pos * lam, psi=rec.psi.copy(), channels=chans, meta=meta, notes=[*rec.notes, note]
    )
    return out, note


def check_sample_time(rec, profile, resample: bool = False):
    """The recording on the profile's sample time: as is when they agree (0.1 %), resampled with a
    note when ``resample``, else a RecordingError naming both times and the fix."""
    ts, want = rec.sample_time, profile.sample_time
    if abs(ts - want) <= 1e-3 * want:
        return rec
    if not resample:
        raise _error()(
            f"{rec.source}: sampled every {ts:g} s but ship {profile.name!r} is modelled at {want:g} s; "
            "resample the file, or pass --resample to let the tool interpolate it (and say so)"
        )
    grid = np.arange(rec.t[0], rec.t[-1] + 1e-9 * want, want)
    if len(grid) < 3:
        raise _error()(f"{rec.source}: only {len(grid)} samples at the ship's {want:g} s; record longer")

    def interp(a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, float)
        if a.ndim == 1:
            return np.interp(grid, rec.t, a)
        return np.stack([np.interp(grid, rec.t, a[:, j]) for j in range(a.shape[1])], axis=-1)

    seg = None
    if rec.segments is not None:
        idx = np.clip(np.searchsorted(rec.t, grid), 0, len(rec.t) - 1)
        seg = [rec.segments[i] for i in idx]
    note = f"resampled from {ts:g} s to the ship's {want:g} s by linear interpolation (--resample)"
    return replace(
        rec,
        t=grid,
        y=interp(rec.y),
        psi=interp(rec.psi),
        pos=interp(rec.pos),
        channels={k: interp(v) for k, v in rec.channels.items()},
        segments=seg,
        notes=[*rec.notes, note],
    )


def conform(recs: list, profile, *, resample: bool = False, full_scale: bool = True) -> list:
    """Every recording checked and brought to the profile: Froude-scaled to full scale when its
    header says ``# scale: model`` (a header giving a scale factor means the profile is the
    full-scale ship; pass ``full_scale=False`` to keep model scale), on the profile's sample time,
    inputs in range. The notes on each recording say what was done (the report prints them), and a ``# ship:``
    header naming another ship (:func:`ship_header_note`)."""
    out = []
    for rec in recs:
        rec.inputs_for(profile.inputs)  # a missing input column says the --ship is wrong: say that first
        if full_scale and rec.scale == "model":
            rec, _ = froude_scale(rec)
        check_speed(rec, profile)  # before the sample time: a model-scale run says why its time step differs
        rec = check_sample_time(rec, profile, resample)
        rec = apply_rudder_sign(rec, profile)  # before the limits: a converted rudder is judged as the ship's
        check_inputs(rec, profile)
        out.append(rec)
    # the signs (a header naming the wrong convention is still caught) and the '# ship:' note, as api.run has them
    return rudder_in_profile_sign(out, profile)
