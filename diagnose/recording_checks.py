"""Checks and conversions that make a recording fit a ship profile, each saying what it did.

- :func:`check_values`: physically possible magnitudes and a ship that moves (refuses an
  all-zeros file, u = 1e308, a time axis that would need billions of samples);
- :func:`check_frame`: u, v against the derivatives of x, y and psi: body frame, not earth
  frame, and m/s, not knots or km/h (BRIEF section 2 kinematics);
- :func:`check_inputs`: inputs within a plausible multiple of the profile's input limits;
- :func:`froude_scale`: a model-scale recording to full scale (Froude similarity);
- :func:`check_sample_time`: refuse, or resample and say so, a sample time other than the profile's.

All are pure functions on :class:`diagnose.recording.Recording` (no I/O) and raise
:class:`RecordingError` with one line naming the file, the column and the fix.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from primitives.errors import UserError

# Largest magnitudes a real run can show (a fast craft does 40 m/s; 5 rad/s is a spinning model).
MAX_ABS = {"u": 100.0, "v": 100.0, "r": 10.0, "p": 10.0, "phi": 3.2, "x": 1e8, "y": 1e8, "psi": 1e5,
           "wind_speed": 150.0}
MAX_GRID_SAMPLES = 5_000_000  # a uniform grid beyond this is a unit mistake, not a trial
INPUT_LIMIT_FACTOR = 50.0  # inputs beyond this multiple of the profile's limits are in other units
# Froude scaling exponents of lambda per signal kind (length ~ lambda, time ~ sqrt(lambda)).
FROUDE_POWER = {"x": 1.0, "y": 1.0, "u": 0.5, "v": 0.5, "r": -0.5, "p": -0.5, "n": -0.5, "n1": -0.5, "n2": -0.5,
                "wind_speed": 0.5, "tau_x": 3.0, "tau_y": 3.0, "tau_n": 4.0}


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
            raise _error()(f"{src}: column {k!r} row {int(np.argmax(bad)) + 2}: infinite value; give finite numbers or leave the cell empty")
        lim = MAX_ABS.get(k)
        if lim is not None and np.nanmax(np.abs(v), initial=0.0) > lim:
            i = int(np.nanargmax(np.abs(v)))
            raise _error()(
                f"{src}: column {k!r} row {i + 2}: {v[i]:.3g} is beyond any ship (|{k}| <= {lim:g} in SI units); check its units"
            )
    moving = [k for k in ("x", "y", "psi", "u", "v", "r") if k in cols and np.nanmax(cols[k], initial=0) - np.nanmin(cols[k], initial=0) > 0]
    speed = max((np.nanmax(np.abs(cols[k]), initial=0.0) for k in ("u", "v") if k in cols), default=0.0)
    if not moving and speed == 0:
        raise _error()(f"{src}: the ship does not move (x, y, psi and u, v, r are constant); nothing to diagnose: check the file")


def _track_velocity(t: np.ndarray, pos: np.ndarray, psi: np.ndarray, smooth_s: float = 2.0) -> tuple[np.ndarray, ...]:
    """Earth-frame (xd, yd) and body-frame (ub, vb) velocity from the track, smoothed over ~smooth_s
    so position noise does not swamp the comparison."""
    ts = float(np.median(np.diff(t)))
    k = max(1, int(round(smooth_s / ts / 2)))
    if len(t) <= 2 * k + 2:
        k = 1
    dt = t[2 * k:] - t[:-2 * k]
    xd = (pos[2 * k:, 0] - pos[:-2 * k, 0]) / dt
    yd = (pos[2 * k:, 1] - pos[:-2 * k, 1]) / dt
    c, s = np.cos(psi[k:-k]), np.sin(psi[k:-k])
    return xd, yd, c * xd + s * yd, -s * xd + c * yd, slice(k, len(t) - k)


def check_frame(src: str, t: np.ndarray, pos: np.ndarray, psi: np.ndarray, u: np.ndarray, v: np.ndarray) -> None:
    """u, v must be body-frame velocities over ground in m/s: compare them with the differentiated track.

    Earth frame (u = dx/dt, v = dy/dt) is told from body frame by which rotation fits the track
    better; it can only be told when the heading is away from north, so a run heading north
    passes. Wrong units show as a constant ratio between |(u, v)| and the track's speed.
    """
    if len(t) < 10:
        return
    xd, yd, ub, vb, sl = _track_velocity(t, pos, psi)
    um, vm = u[sl], v[sl]
    sog = np.hypot(xd, yd)
    moving = sog > max(0.05, 0.1 * np.nanmax(sog, initial=0.0))
    if moving.sum() < 10:
        return
    ratio = np.nanmedian(np.hypot(um, vm)[moving]) / np.nanmedian(sog[moving])
    if not (0.5 < ratio < 2.0) and ratio > 0:
        units = {1.94: "knots", 3.6: "km/h", 100.0: "cm/s"}
        guess = min(units, key=lambda r: abs(math.log(ratio / r)))
        hint = f" (looks like {units[guess]})" if abs(math.log(ratio / guess)) < 0.2 else ""
        raise _error()(
            f"{src}: columns 'u', 'v' are {ratio:.3g} x the speed of the track x, y{hint}; give u, v in m/s"
        )
    err_body = np.nanmean(((um - ub) ** 2 + (vm - vb) ** 2)[moving])
    err_earth = np.nanmean(((um - xd) ** 2 + (vm - yd) ** 2)[moving])
    if err_earth < 0.25 * err_body and err_body > 0.05 * np.nanmean(sog[moving] ** 2):
        raise _error()(
            f"{src}: columns 'u', 'v' look like earth-frame velocities (north, east = dx/dt, dy/dt): "
            "give body-frame surge and sway (u = xd cos psi + yd sin psi, v = -xd sin psi + yd cos psi)"
        )


def check_inputs(rec, profile) -> None:
    """Refuse inputs far beyond the ship's limits: a column in other units (N vs kN, rpm vs rev/s, 1e6 x)."""
    for name in profile.inputs:
        lo, hi = profile.input_limits.get(name, (-math.inf, math.inf))
        x = rec.channels.get(name)
        if x is None or not np.isfinite([lo, hi]).all():
            continue
        span = max(abs(lo), abs(hi))
        peak = float(np.nanmax(np.abs(x), initial=0.0))
        if span > 0 and peak > INPUT_LIMIT_FACTOR * span:
            raise _error()(
                f"{rec.source}: column {name!r} reaches {peak:.3g}, {peak / span:.3g} x the limit {span:g} of ship {profile.name!r}: "
                "check its units (SI: N, N m, rad, rev/s) or choose the matching --ship"
            )


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
        raise _error()(f"{rec.source}: Froude scaling needs a scale factor > 0 ('# scale_factor: 45.7' in the header), got {lam!r}")
    s = math.sqrt(lam)
    y = rec.y * np.array([s, s, 1 / s])
    chans = {k: v * lam ** FROUDE_POWER[k] if k in FROUDE_POWER else v.copy() for k, v in rec.channels.items()}
    note = (f"Froude-scaled from model to full scale with lambda = {lam:g}: lengths x {lam:g}, times and speeds x {s:.4g}, "
            f"rates and revolutions / {s:.4g}, forces x lambda^3, moments x lambda^4")
    meta = {**rec.meta, "scale": "full", "scale_factor": "1", "froude_scaled_from": f"model, lambda = {lam:g}"}
    out = replace(rec, t=rec.t * s, y=y, pos=rec.pos * lam, psi=rec.psi.copy(), channels=chans, meta=meta,
                  notes=[*rec.notes, note])
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
    return replace(rec, t=grid, y=interp(rec.y), psi=interp(rec.psi), pos=interp(rec.pos),
                   channels={k: interp(v) for k, v in rec.channels.items()}, segments=seg, notes=[*rec.notes, note])


def conform(recs: list, profile, *, resample: bool = False, full_scale: bool = True) -> list:
    """Every recording checked and brought to the profile: Froude-scaled to full scale when its
    header says ``# scale: model`` (a header giving a scale factor means the profile is the
    full-scale ship; pass ``full_scale=False`` to keep model scale), on the profile's sample time,
    inputs in range. The notes on each recording say what was done (the report prints them)."""
    out = []
    for rec in recs:
        rec.inputs_for(profile.inputs)  # a missing input column says the --ship is wrong: say that first
        if full_scale and rec.scale == "model":
            rec, _ = froude_scale(rec)
        rec = check_sample_time(rec, profile, resample)
        check_inputs(rec, profile)
        out.append(rec)
    return out
