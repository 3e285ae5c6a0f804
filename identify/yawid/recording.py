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
from primitives.io import atomic_write_text, read_input_text
from primitives.ship import ShipProfile
from primitives.unit_ranges import YAW_RATE_MAX_RAD_S

COLUMNS = ("t", "r", "v_dot", "u", "v", "phi", "tau_r")
POD_COLUMNS = ("n1", "delta1", "n2", "delta2")
MAX_RATE_RAD_S = YAW_RATE_MAX_RAD_S  # beyond any ship's yaw rate: deg/s (primitives.unit_ranges)
MAX_ROLL_RAD = 0.7  # 40 deg: no trial rolls further (the naval vessel's reach 0.23); larger: degrees
MAX_STEP_S = 10.0  # a yaw fit needs the response within a turn (tens of seconds): steps this long are milliseconds
# the sign check's z bound: the regression of dr/dt on tau_r measured z = +54..+56 on six yawid-sim runs, +16.7 (turn
# pulse) and +10.8..+56.5 (identification runs, Table 4.1 noise x1 and x5); a negated r or tau_r gives the same with
# the sign flipped. -3 refuses a clear flip and leaves a weak one (the turn pulse at 5 x noise: +3.5) to the fit.
SIGN_Z = -3.0


def write_yaw_csv(data: YawData, path: str | Path, meta: dict[str, str] | None = None, run: int = 0) -> Path:
    """One run of ``data`` (run ``run`` of a batch) as a recording CSV, with the columns it has."""
    names = [k for k in COLUMNS[1:] if k in data.signals]
    sig = [np.atleast_2d(data.signals[k])[run] for k in names]
    lines = [f"# {k}: {v}" for k, v in (meta or {}).items()] + [",".join(["t", *names])]
    lines += [",".join(f"{x:.9g}" for x in row) for row in zip(data.t, *sig)]
    return atomic_write_text(path, "\n".join(lines) + "\n")


def _columns(path: Path) -> tuple[dict[str, str], dict[str, np.ndarray]]:
    meta, body = split_metadata(
        read_input_text(path, RecordingError, "a yaw recording CSV (t, r, u, v, ...)", "utf-8-sig").splitlines()
    )
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
    return meta, cols


def read_yaw_csv(path: str | Path, model: YawModel, profile: ShipProfile | None = None) -> YawData:
    """A recording with every signal ``model`` needs, or a one-line RecordingError saying which is missing."""
    path = Path(path)
    meta, cols = _columns(path)
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
    _check_units(path, {k: cols[k] for k in need})  # a column the model does not read is not judged
    sig = {k: cols[k] for k in need[1:]}
    sig["tau_r"] = _pod_moment(path, cols, profile)
    _check_response(path, t, sig["r"], sig["tau_r"], "tau_r" in cols)
    return YawData(t, sig, source=str(path))


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


def _check_units(path: Path, cols: dict[str, np.ndarray]) -> None:
    """r in rad/s and phi in rad: beyond any ship's yaw rate or roll, they are degrees."""
    for name, limit, unit in (("r", MAX_RATE_RAD_S, "rad/s"), ("phi", MAX_ROLL_RAD, "rad")):
        if name not in cols:
            continue
        big = float(np.max(np.abs(cols[name])))
        if big > limit:
            raise RecordingError(
                f"{path}: column '{name}' reaches {big:.3g}, more than {limit:g} {unit}: in degrees? give {unit} "
                f"({big:.3g} deg = {np.radians(big):.3g} rad)"
            )


def _check_response(path: Path, t: np.ndarray, r: np.ndarray, tau_r: np.ndarray, measured: bool) -> None:
    """The ship turns with its pods' moment: (I_z - N_rdot) dr/dt = tau_r + hull moments (2.17), so dr/dt regressed
    on tau_r (and r, a constant; both over 1 s moving means) has a positive slope. A recording without any change of
    r or tau_r has nothing to fit; a slope negative beyond SIGN_Z standard errors is a sign error of r or tau_r."""
    source = "column 'tau_r'" if measured else "the pod yaw moment computed from n1, delta1, n2, delta2"
    for label, x in (("column 'r'", r), (source, tau_r)):
        if np.ptp(x) == 0:
            raise RecordingError(f"{path}: {label} is constant: the recording has no turn to fit; give a manoeuvring run")
    dt = float(np.median(np.diff(t)))
    n = max(1, int(round(1.0 / dt)))
    if len(t) <= 2 * n + 3:
        return
    box = np.ones(n) / n
    rs, ts = np.convolve(r, box, mode="same"), np.convolve(tau_r, box, mode="same")
    cut = slice(n, -n)
    for label, x in (("column 'r'", rs[cut]), (source, ts[cut])):
        if not np.std(x) > 0:  # its only change within the first or last second: no turn (and no scale below)
            raise RecordingError(
                f"{path}: {label} changes only in the first or last second: the recording has no turn to fit; "
                "give a manoeuvring run"
            )
    # columns scaled to unit spread: tau_r in N m and r in rad/s differ by 1e8 (z does not depend on the scale)
    x = np.column_stack([ts[cut] / np.std(ts[cut]), rs[cut] / np.std(rs[cut]), np.ones(len(rs[cut]))])
    y = np.gradient(rs, dt)[cut] / np.std(rs[cut])
    z = coefficient_t(x, y, 0)
    if z < SIGN_Z:
        which = "'r' or 'tau_r'" if measured else "'r' or a pod input's sign (delta1, delta2)"
        raise RecordingError(
            f"{path}: the yaw rate turns against {source} (slope of dr/dt on it {z:+.1f} standard errors): "
            f"{which} looks negated; give r and the moment clockwise (to starboard) positive"
        )


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
