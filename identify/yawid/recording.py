"""Yaw-identification recordings as CSV: what the chapter-4 estimation needs, checked on reading.

Columns (SI, radians; one row per sample, uniform sample time): ``t, r, u, v`` always; ``v_dot``
(measured sway acceleration) and ``phi`` (roll angle) for the full model (2.17) -- the simplified
model (2.18) needs neither (L873-875); the pods' yaw moment ``tau_r`` [N m] as measured, or the pod
inputs ``n1, delta1, n2, delta2`` (rev/s, rad) from which the ship profile's pod model (2.9)-(2.12)
computes it (with the roll rate ``p`` when present). ``# key: value`` lines above the header are
kept as metadata. A missing column is one line naming it and the fix (RecordingError).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from diagnose.recording import RecordingError, split_metadata
from identify.yawid.experiment import YawData, pod_yaw_moment
from identify.yawid.model import YawModel
from primitives.goodness import coefficient_t
from primitives.io import atomic_write_text, read_record_lines
from primitives.ship import ShipProfile
from primitives.unit_ranges import YAW_RATE_MAX_RAD_S

COLUMNS = ("t", "r", "v_dot", "u", "v", "phi", "tau_r")
POD_COLUMNS = ("n1", "delta1", "n2", "delta2")
MAX_RATE_RAD_S = YAW_RATE_MAX_RAD_S  # beyond any ship's yaw rate: deg/s (primitives.unit_ranges)
MAX_ROLL_RAD = 0.7  # 40 deg: no trial rolls further (the naval vessel's reach 0.23); larger: degrees
# u: the naval vessel's top speed (n = 80 rev/s, its input limit) is 9.79 m/s, its cruise speed 9.7; the fastest run
# (the turn pulse at full revs) has a median u of 9.58 m/s, 0.82 x this bound. In knots the identification runs'
# medians are 13.4..16.5, 1.15..1.42 x the bound; a run slower than 6.0 m/s (median) in knots is not caught.
MAX_SPEED_X = 1.2
KNOT_MPS = 1852 / 3600
VDOT_WINDOW_S = 5  # vdot_slope's moving means: sway turns over tens of seconds, noise averages out
# measured (yaw_vdot.py, 40 identification runs; docs/bad-input-sweep.md, Stop 61): the slope is 0.980..1.017 in m/s
# and 1.905..1.977 in knots at Table 4.1's noise, 0.802..1.011 and 1.559..1.964 (t >= 4.6) at 5 x; noise in v_dot only
# lowers it (0.04..0.77 at 20 x in m/s): refused above 1.4 with a t of (slope - 1) over 3
VDOT_KNOTS_SLOPE, VDOT_KNOTS_T = 1.4, 3.0
MAX_STEP_S = 10.0  # a yaw fit needs the response within a turn (tens of seconds): steps this long are milliseconds
# the sign check's bounds on z (response_z, Newey-West standard error; yaw_sign_hac.py in the stop 60 leftovers):
# z = +16.7..+16.9 on six yawid-sim runs, >= +14.6 on 40 identification runs at Table 4.1's noise, >= +7.9 at 5 x,
# and +7.4 (median) on the turn pulse; negated, the same values with the sign flipped. A run with no evidence (the
# turn pulse at 10, 20, 50 x noise, 500 draws each) spreads with std 0.85..1.04 and never went below -2.9. So: below
# -4 refused (clear: 4 of its own standard errors), between -4 and -2 a note (noise, or a sign to check).
SIGN_Z = -4.0
SIGN_NOTE_Z = -2.0
HAC_LAG_S = 3  # the sign check's autocorrelation window (response_z), in seconds


def write_yaw_csv(data: YawData, path: str | Path, meta: dict[str, str] | None = None, run: int = 0) -> Path:
    """One run of ``data`` (run ``run`` of a batch) as a recording CSV, with the columns it has."""
    names = [k for k in COLUMNS[1:] if k in data.signals]
    sig = [np.atleast_2d(data.signals[k])[run] for k in names]
    lines = [f"# {k}: {v}" for k, v in (meta or {}).items()] + [",".join(["t", *names])]
    lines += [",".join(f"{x:.9g}" for x in row) for row in zip(data.t, *sig)]
    return atomic_write_text(path, "\n".join(lines) + "\n")


def _columns(path: Path) -> tuple[dict[str, str], dict[str, np.ndarray], str | None]:
    lines, cut = read_record_lines(path, RecordingError, "a yaw recording CSV (t, r, u, v, ...)", "utf-8-sig")
    meta, body = split_metadata(lines)
    if len(body) < 2:
        raise RecordingError(f"{path}: needs a header row (t,r,u,v,...) and data rows")
    reader = csv.reader(body)
    header = [h.strip() for h in next(reader)]
    rows = list(reader)
    cols = {}
    for j, name in enumerate(header):
        vals = np.empty(len(rows))
        for i, row in enumerate(rows):
            try:
                vals[i] = float(row[j])
            except (IndexError, ValueError):
                raise RecordingError(
                    f"{path}: row {i + 2}, column '{name}': {row[j] if j < len(row) else ''!r} is not a number"
                ) from None
        if not np.all(np.isfinite(vals)):
            raise RecordingError(f"{path}: column '{name}' holds NaN or inf; the yaw fit needs gap-free signals")
        cols[name] = vals
    return meta, cols, cut


def read_yaw_csv(path: str | Path, model: YawModel, profile: ShipProfile | None = None) -> YawData:
    """A recording with every signal ``model`` needs, or a one-line RecordingError saying which is missing."""
    path = Path(path)
    meta, cols, cut = _columns(path)
    need = ("t", "r") + model.signals
    for name in need:
        if name not in cols:
            why = {
                "phi": "the roll angle phi [rad] (the full model (2.17) needs roll; --model simplified does not)",
                "v_dot": "the measured sway acceleration v_dot [m/s2] (the full model needs it; --model simplified does not)",
            }
            raise RecordingError(f"{path}: no column '{name}': add {why.get(name, f'{name} in SI units')}")
    t = cols["t"]
    if t.size < 50:
        raise RecordingError(f"{path}: {t.size} samples; the yaw fit needs at least 50 (the thesis uses 6000)")
    dt = np.diff(t)
    if not np.all(dt > 0) or np.ptp(dt) > 1e-6 * max(1.0, dt.mean()) + 1e-9:
        raise RecordingError(f"{path}: column 't' must be uniformly sampled and increasing (resample the recording)")
    _check_step(path, dt, meta)
    _check_units(path, t, {k: cols[k] for k in need})  # a column the model does not read is not judged
    _check_speed(path, cols["u"], profile)
    if "v_dot" in need:  # the full model's measured sway acceleration: the speed log's unit
        _check_sway_units(path, t, cols["v"], cols["v_dot"])
    sig = {k: cols[k] for k in need[1:]}
    sig["tau_r"] = _pod_moment(path, cols, profile)
    weak = _check_response(path, t, sig["r"], sig["tau_r"], "tau_r" in cols)
    return YawData(t, sig, source=str(path), notes=tuple(n for n in (cut, weak) if n))


def _check_step(path: Path, dt: np.ndarray, meta: dict[str, str]) -> None:
    """The time step in seconds, and the header's ``# sample_time:`` agreeing with it (within 1 %)."""
    step = float(np.median(dt))
    if step > MAX_STEP_S:
        raise RecordingError(
            f"{path}: column 't' steps {step:g} (median): t in milliseconds? give t in seconds (the yaw fit needs "
            f"samples well under {MAX_STEP_S:g} s apart)"
        )
    declared = meta.get("sample_time")
    if declared is None:
        return
    try:
        ts = float(declared)
    except ValueError:
        raise RecordingError(f"{path}: '# sample_time: {declared}' is not a number of seconds; correct the header") from None
    if not abs(step - ts) <= 0.01 * step:
        raise RecordingError(
            f"{path}: column 't' steps {step:g} s but '# sample_time:' says {declared} s; correct the header or the times"
        )


def _check_units(path: Path, t: np.ndarray, cols: dict[str, np.ndarray]) -> None:
    """r in rad/s and phi in rad: beyond any ship's yaw rate or roll, they are degrees, or, when only the noise
    takes single samples there (:func:`unit_slip`), a sensor far noisier than a ship's; refused either way."""
    for name, limit, unit in (("r", MAX_RATE_RAD_S, "rad/s"), ("phi", MAX_ROLL_RAD, "rad")):
        if name not in cols:
            continue
        big = float(np.max(np.abs(cols[name])))
        if big <= limit:
            continue
        slip, mean, sd = unit_slip(t, cols[name], limit)
        if slip:
            raise RecordingError(
                f"{path}: column '{name}' reaches {big:.3g}, more than {limit:g} {unit}: in degrees? give {unit} "
                f"({big:.3g} deg = {np.radians(big):.3g} rad)"
            )
        raise RecordingError(
            f"{path}: column '{name}' reaches {big:.3g}, more than {limit:g} {unit}, in single samples only: its 1 s "
            f"means stay within {mean:.3g}, and its noise (std {sd:.3g} {unit} from successive samples) takes it there; "
            "the yaw fit needs a quieter sensor (check it and its filter)"
        )


def unit_slip(t: np.ndarray, x: np.ndarray, limit: float) -> tuple[bool, float, float]:
    """Whether a column over ``limit`` is so because of its unit, not its noise: its 1 s moving means (the signal)
    exceed ``limit`` by more than 5 of their noise's standard deviations. Returns (slip, the means' largest
    magnitude, the noise's std sigma). sigma is read from successive samples (median |x[k+1] - x[k]| /
    (0.6745 sqrt 2), white noise), the means' noise is sigma / sqrt(n). Degrees scale signal and noise alike, so a
    run in degrees stays far over (r: 1 s means 3.1 deg/s for a bound of 0.43); noise alone does not (r at 50 x
    Table 4.1's noise: samples to 0.54 rad/s, 1 s means to 0.19, bound 0.40)."""
    n = _per_second(t)
    means = np.convolve(x, np.ones(n) / n, mode="valid") if len(x) >= n else np.asarray(x, float)
    sd = float(np.median(np.abs(np.diff(x)))) / (0.6745 * np.sqrt(2.0)) if len(x) > 1 else 0.0
    mean = float(np.max(np.abs(means)))
    return mean > limit + 5.0 * sd / np.sqrt(n), mean, sd


def vdot_slope(t: np.ndarray, v: np.ndarray, v_dot: np.ndarray) -> tuple[float, float]:
    """The slope of d v/dt on the measured sway acceleration ``v_dot`` (both as VDOT_WINDOW_S moving means, least
    squares through 0), and the t of (slope - 1) with Newey and West's error (the moving means correlate the
    residuals): the slope is 1 when v is in m/s, 1/0.5144 = 1.944 when the speed log gives v in knots (v_dot, an
    accelerometer's, stays in m/s^2). (nan, 0) on a run shorter than three windows or without sway acceleration."""
    n = VDOT_WINDOW_S * _per_second(t)
    if len(t) < 3 * n:
        return float("nan"), 0.0
    w = np.ones(n) / n
    vm, am = np.convolve(v, w, mode="valid"), np.convolve(v_dot, w, mode="valid")
    g = np.gradient(vm, float(np.median(np.diff(t))))
    den = float(am @ am)
    if not den > 0:
        return float("nan"), 0.0
    return float(g @ am) / den, coefficient_t(am[:, None], g - am, 0, lags=2 * n)


def _check_sway_units(path: Path, t: np.ndarray, v: np.ndarray, v_dot: np.ndarray) -> None:
    """v in m/s: d v/dt against the measured v_dot (:func:`vdot_slope`) says knots at any speed, where u's bound
    against the cruise speed (:func:`_check_speed`) catches only runs above 6 m/s. A speed log in knots gives u and v
    in knots; u alone in knots (v in m/s) leaves no trace in a yaw recording (docs/bad-input-sweep.md, Stop 61)."""
    k, tk = vdot_slope(t, v, v_dot)
    if k > VDOT_KNOTS_SLOPE and tk > VDOT_KNOTS_T:
        raise RecordingError(
            f"{path}: column 'v' changes {k:.2f} x as fast as the measured 'v_dot' says (in m/s: 1; in knots: 1.94): "
            "the speed log in knots? give u and v in m/s (knots x 0.5144)"
        )


def _per_second(t: np.ndarray) -> int:
    """Samples in one second (at least 1): the window of the checks' 1 s moving means."""
    return max(1, int(round(1.0 / float(np.median(np.diff(t))))))


def _check_speed(path: Path, u: np.ndarray, profile: ShipProfile | None) -> None:
    """u in m/s: a run whose median speed is beyond MAX_SPEED_X the profile's cruise speed is in knots (or km/h)."""
    if profile is None or not profile.cruise_speed_mps > 0:
        return
    median, limit = float(np.median(u)), MAX_SPEED_X * profile.cruise_speed_mps
    if median > limit:
        raise RecordingError(
            f"{path}: column 'u' runs at {median:.3g} (median), over {MAX_SPEED_X:g} x the cruise speed of "
            f"{profile.name} ({profile.cruise_speed_mps:g} m/s): in knots? give m/s ({median:.3g} kn = "
            f"{median * KNOT_MPS:.3g} m/s)"
        )


def _check_response(path: Path, t: np.ndarray, r: np.ndarray, tau_r: np.ndarray, measured: bool) -> str | None:
    """The ship turns with its pods' moment: (I_z - N_rdot) dr/dt = tau_r + hull moments (2.17), so dr/dt regressed
    on tau_r (:func:`response_z`) has a positive slope. A recording without any change of r or tau_r has nothing to
    fit; a slope below SIGN_Z of its standard errors is a sign error of r or tau_r, refused; one between SIGN_Z and
    SIGN_NOTE_Z is the note returned (a very noisy run can land there with the signs right)."""
    source = "column 'tau_r'" if measured else "the pod yaw moment computed from n1, delta1, n2, delta2"
    for label, x in (("column 'r'", r), (source, tau_r)):
        if np.ptp(x) == 0:
            raise RecordingError(f"{path}: {label} is constant: the recording has no turn to fit; give a manoeuvring run")
    z = response_z(t, r, tau_r)
    if np.isnan(z):  # r or tau_r changes only within the first or last second, outside the window of its means
        raise RecordingError(
            f"{path}: column 'r' or {source} changes only in the first or last second: the recording has no turn "
            "to fit; give a manoeuvring run"
        )
    which = "'r' or 'tau_r'" if measured else "'r' or a pod input's sign (delta1, delta2)"
    if z < SIGN_Z:
        raise RecordingError(
            f"{path}: the yaw rate turns against {source} (slope of dr/dt on it {z:+.1f} standard errors): "
            f"{which} looks negated; give r and the moment clockwise (to starboard) positive"
        )
    if z < SIGN_NOTE_Z:
        return (
            f"the yaw rate follows {source} weakly or against it (slope of dr/dt on it {z:+.1f} standard errors, "
            f"refused below {SIGN_Z:+g}): noise, or {which} negated; check the fit and the signs"
        )
    return None


def response_z(t: np.ndarray, r: np.ndarray, tau_r: np.ndarray) -> float:
    """The slope of dr/dt on tau_r in standard errors (the yaw row of (2.17): (I_z - N_rdot) dr/dt = tau_r + hull
    moments; regressors tau_r, r and a constant, r and tau_r over 1 s moving means; 0 for a run under 2 s, NaN when
    either changes only within its first or last second).

    The standard error is Newey and West's (1987) heteroskedasticity and autocorrelation consistent one
    (:func:`primitives.goodness.coefficient_t` with Bartlett weights, lags up to 3 s): the moving means and the
    differentiation correlate the residuals over n + 1 samples, and the ordinary least-squares error, which ignores
    that, made the statistic's spread on a noise-only run grow with the noise (1.07 at 20 x Table 4.1's noise, 1.32
    at 50 x: a 3-sigma refusal then fired on 6 of 500)."""
    dt = float(np.median(np.diff(t)))
    n = _per_second(t)
    if len(t) <= 2 * n + 3:
        return 0.0
    box = np.ones(n) / n
    rs, ts = np.convolve(r, box, mode="same"), np.convolve(tau_r, box, mode="same")
    cut = slice(n, -n)
    if not (np.std(rs[cut]) > 0 and np.std(ts[cut]) > 0):  # a change only in the first or last second: no scale
        return float("nan")
    # columns scaled to unit spread: tau_r in N m and r in rad/s differ by 1e8 (z does not depend on the scale)
    x = np.column_stack([ts[cut] / np.std(ts[cut]), rs[cut] / np.std(rs[cut]), np.ones(len(rs[cut]))])
    y = np.gradient(rs, dt)[cut] / np.std(rs[cut])
    return coefficient_t(x, y, 0, lags=HAC_LAG_S * n)


def _pod_moment(path: Path, cols: dict[str, np.ndarray], profile: ShipProfile | None) -> np.ndarray:
    """Measured tau_r, or the pod model's yaw moment from the logged pod inputs."""
    if "tau_r" in cols:
        return cols["tau_r"]
    missing = [c for c in POD_COLUMNS if c not in cols]
    if missing:
        raise RecordingError(
            f"{path}: no pod yaw moment: add column 'tau_r' [N m] (measured pod forces) or the pod inputs "
            f"{', '.join(POD_COLUMNS)} (missing: {', '.join(missing)})"
        )
    if profile is None or not profile.pods:
        raise RecordingError(f"{path}: pod inputs without 'tau_r' need a ship profile with [[pods]] (e.g. --ship naval-vessel)")
    inputs = {name: cols[name] for name in profile.inputs if name in cols}
    if len(inputs) != len(profile.inputs):
        raise RecordingError(f"{path}: ship {profile.name!r} has inputs {list(profile.inputs)}; the recording lacks some")
    return pod_yaw_moment(profile, inputs, cols["u"], cols["v"], cols["r"], cols.get("p"))
