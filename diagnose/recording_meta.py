"""A recording's header lines (``# key: value``) that say where and how it was recorded: the
environment (a basin or towing tank has no current and no wind), the rudder's sign convention,
the wind's reference (true or relative, converted to the true wind on reading), the sample time
and scale. The readers in :mod:`diagnose.recording` call these on every file."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from diagnose.recording import Recording

# header values that say where and how a run was recorded (the README's recording format)
ENVIRONMENTS = ("sea", "basin", "towing-tank")  # a basin or towing tank has no current and no wind
RUDDER_SIGNS = ("port-positive", "starboard-positive")  # the sign of delta that turns the ship to that side
# the side a positive yaw rate turns the bow to: the house convention (r = dpsi/dt, heading clockwise
# from north) is starboard-positive; a log in the other (mathematical, counter-clockwise) one is converted
YAW_RATE_SIGNS = ("starboard-positive", "port-positive")
WIND_REFERENCES = ("true", "relative")  # wind over ground, or as felt on board (from the bow, clockwise)
# a true wind above this (median over the run) is a storm (Beaufort 10) no trial is run in: the
# speed is taken to be in knots (1 kn = 0.5144 m/s), not m/s
MAX_TRIAL_WIND_MPS = 25.0


def check_meta(path: Path, meta: dict[str, str]) -> None:
    """Header values the loader uses: sample time (s), scale (model|full) and scale factor,
    and the environment, rudder sign and wind reference named among their allowed values."""
    from diagnose.recording import RecordingError

    for key in ("sample_time", "scale_factor"):
        if key in meta:
            try:
                v = float(meta[key])
            except ValueError:
                v = float("nan")
            if not (math.isfinite(v) and v > 0):
                raise RecordingError(f"{path}: header '# {key}: {meta[key]}' must be a positive number")
    for key, allowed in (
        ("environment", ENVIRONMENTS),
        ("rudder_sign", RUDDER_SIGNS),
        ("yaw_rate_sign", YAW_RATE_SIGNS),
        ("wind_reference", WIND_REFERENCES),
    ):
        if key in meta and meta[key] not in allowed:
            raise RecordingError(f"{path}: header '# {key}: {meta[key]}' must be one of {', '.join(allowed)}")
    if "scale" in meta and meta["scale"] not in ("model", "full"):
        raise RecordingError(f"{path}: header '# scale: {meta['scale']}' must be 'model' or 'full'")
    if meta.get("scale") == "model" and "scale_factor" not in meta:
        raise RecordingError(f"{path}: header '# scale: model' needs '# scale_factor: LAMBDA' (full-scale length / model length)")


def true_wind(path: Path, rec: Recording) -> Recording:
    """The recording's wind as the true wind (over ground, the direction it comes from, clockwise
    from north), converted from a relative one, and checked for knots.

    A relative (apparent) wind of speed V_a from the angle g_a off the bow (clockwise) is the air's
    velocity relative to the ship, -V_a (cos g_a, sin g_a) in body axes; the true air velocity is
    that plus the ship's velocity over ground (u, v) (Fossen 2021, (10.8)-(10.9): u_rw = u - u_w)."""
    from diagnose.recording import RecordingError

    has = [k for k in ("wind_speed", "wind_dir") if k in rec.channels]
    if not has:
        return rec
    if len(has) == 1:
        raise RecordingError(f"{path}: column {has[0]!r} without its partner; a wind needs both wind_speed and wind_dir")
    ref = rec.meta.get("wind_reference")
    if ref is None:
        raise RecordingError(
            f"{path}: columns wind_speed, wind_dir without their reference; add '# wind_reference: true' "
            "(over ground, direction from north) or '# wind_reference: relative' (as felt on board, direction from the bow)"
        )
    chans = dict(rec.channels)
    notes = list(rec.notes)
    if not np.isfinite(chans["wind_speed"]).any():
        raise RecordingError(f"{path}: column 'wind_speed' holds no value; fill it in m/s or drop the wind columns")
    top = float(np.nanmax(np.abs(chans["wind_dir"])))
    if top > 2 * np.pi + 1e-9:
        raise RecordingError(
            f"{path}: column 'wind_dir' reaches {top:.1f}, more than 2 pi: is it in degrees? give radians (degrees x pi / 180)"
        )
    if ref == "relative":
        va, ga = chans["wind_speed"], chans["wind_dir"]
        ub, vb = rec.y[:, 0] - va * np.cos(ga), rec.y[:, 1] - va * np.sin(ga)  # true air velocity (toward), body axes
        c, s = np.cos(rec.psi), np.sin(rec.psi)
        wn, we = c * ub - s * vb, s * ub + c * vb
        relative_in_knots(
            path,
            np.column_stack([wn, we]),
            np.column_stack([c * rec.y[:, 0] - s * rec.y[:, 1], s * rec.y[:, 0] + c * rec.y[:, 1]]),
        )
        chans["wind_speed"], chans["wind_dir"] = np.hypot(wn, we), np.arctan2(-we, -wn) % (2 * np.pi)
        notes.append("relative wind (as felt on board) converted to the true wind with the recorded u, v and heading")
    med = float(np.nanmedian(chans["wind_speed"]))
    if med > MAX_TRIAL_WIND_MPS:
        raise RecordingError(
            f"{path}: column 'wind_speed': the true wind's median is {med:.1f} m/s, a storm no trial is run in; "
            f"is it in knots? give m/s (knots x 0.5144: {0.5144 * med:.1f} m/s)"
        )
    return replace(rec, channels=chans, notes=notes, meta={**rec.meta, "wind_reference": "true"})


# the unit factor a relative wind's speed is refused at: knots read as m/s give 1.944
KNOTS_FACTOR_SEEN = 1.5
# judged only when the ship's velocity over ground varies (std) by half its speed (about half a
# turning circle): over a zig-zag the anemometer's flow distortion, which changes with the
# relative wind angle, moves the factor as much as knots do (0.8-1.6 in m/s on the MMG battery's
# zig-zags, 1.18 in m/s and 2.28 in knots on its turning circle)
MIN_TURN_SPREAD = 0.5


def relative_in_knots(path: Path, wind_ne: np.ndarray, ship_ne: np.ndarray) -> None:
    """Refuse a relative wind whose speed is in knots, judged against the ship's own speed.

    The true wind is the relative wind plus the ship's velocity over ground (Fossen 2021,
    (10.8)-(10.9)); with the relative speed read f times too large the derived true wind is
    f w - (f - 1) U, which follows the ship's velocity U as it turns. Regressing the derived
    true wind ``wind_ne`` (N, 2) on the ship's velocity ``ship_ne`` (N, 2) gives 1 - f (gusts do
    not follow the ship's velocity, so they do not bias it; a flow distortion of the anemometer
    does, a little); judged only when the ship turns (its velocity's std at least
    MIN_TURN_SPREAD of its speed)."""
    from diagnose.recording import RecordingError

    ok = np.all(np.isfinite(wind_ne), axis=1) & np.all(np.isfinite(ship_ne), axis=1)
    w, u = wind_ne[ok] - wind_ne[ok].mean(axis=0), ship_ne[ok] - ship_ne[ok].mean(axis=0)
    var = float(np.sum(u * u))
    speed = float(np.mean(np.hypot(ship_ne[ok, 0], ship_ne[ok, 1]))) if ok.any() else 0.0
    if not ok.sum() or var < (MIN_TURN_SPREAD * speed) ** 2 * ok.sum() or speed <= 0:
        return
    factor = 1.0 - float(np.sum(w * u)) / var
    if factor > KNOTS_FACTOR_SEEN:
        raise RecordingError(
            f"{path}: column 'wind_speed' (relative): the true wind derived from it follows the ship's own velocity "
            f"as it turns, as if the speed were {factor:.2f} times too large; is it in knots? give m/s (knots x 0.5144)"
        )


def yaw_rate_as_said(cols: dict[str, np.ndarray], meta: dict[str, str], option: str | None = None) -> str | None:
    """A recorded yaw rate ``cols["r"]`` turned into the house convention (starboard-positive,
    r = dpsi/dt, heading clockwise) in place, when the header ``# yaw_rate_sign:`` (or ``option``,
    the CLI's --yaw-rate-sign, which overrides it) says it is port-positive; the note that says
    what was done (None when nothing was said). Done before the reader compares r with the
    heading's rate, which refuses an r of the other sign."""
    said = option or meta.get("yaw_rate_sign")
    if said is None:
        return None
    if said not in YAW_RATE_SIGNS:
        from diagnose.recording import RecordingError

        raise RecordingError(f"yaw_rate_sign {said!r} is not one of {', '.join(YAW_RATE_SIGNS)}")
    if "r" not in cols:
        return f"yaw_rate_sign {said} not used: no column 'r' (the yaw rate is derived from the heading)"
    if said == YAW_RATE_SIGNS[0]:
        return None
    cols["r"] = -cols["r"]
    meta["yaw_rate_sign"], meta["yaw_rate_sign_converted_from"] = YAW_RATE_SIGNS[0], said
    return f"yaw rate r converted from {said} to starboard-positive (r = dpsi/dt, heading clockwise)"
