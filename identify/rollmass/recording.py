"""Roll recordings as CSV for the mass / CoG estimator (Linder et al. 2015, eqs. (6)-(8)).

Columns (SI, radians): ``t`` [s, uniform], ``delta`` [rad, measured rudder], ``p`` [rad/s, roll-rate
gyro, (6a)], ``a_s`` [m/s^2, IMU lateral (tangential) accelerometer, (6b) and (7)], ``r`` [rad/s,
yaw-rate gyro in ship sign, i.e. minus (6c)]; optional ``u`` [m/s, surge speed, positive ahead:
checked against ``speed_m_s``, not followed] and ``phi`` [rad, roll angle, positive starboard down: an AHRS's
roll output; with the hull's BM it gives the wall-sided restoring, :mod:`identify.rollmass.restoring`]. Optional metadata
lines ``# key: value`` before the header (:data:`META_KEYS`): ``role`` (nominal, calibration,
loaded), ``speed_m_s``, ``imu_z_m``, ``imu_x_m`` (forward of midship), ``load_kg``, ``load_z_m`` (z: body frame, metres, positive
down from the waterline; a ``load_height_m`` is refused as ambiguous), ``ship``, ``dataset``,
``sample_time``.
"""

from __future__ import annotations

import csv
import difflib
import io
from pathlib import Path

import numpy as np

from diagnose.recording import RecordingError, split_metadata
from identify.rollmass.simulate import RollRecording
from primitives.io import atomic_write_text, read_input_text

REQUIRED = ("t", "delta", "p", "a_s", "r")
OPTIONAL = ("u", "phi")
WHAT = {
    "p": "roll-rate gyro, rad/s",
    "a_s": "IMU lateral accelerometer, m/s^2",
    "r": "yaw-rate gyro, rad/s",
    "delta": "rudder angle, rad",
    "t": "time, s",
    "u": "surge speed, m/s, positive ahead",
    "phi": "roll angle, rad, positive starboard down",
}
# names other loggers use for our columns; a file with one of them is told which to rename
ALIASES = {
    "a_s": ("ay", "a_y", "acc_y", "accy", "acc_lat", "fy", "f_y"),
    "p": ("roll_rate", "gyro_x", "wx", "phidot", "phi_dot"),
    "r": ("yaw_rate", "gyro_z", "wz", "psidot", "psi_dot"),
    "delta": ("rudder", "rudder_angle"),
    "t": ("time",),
    "u": ("speed", "surge", "surge_speed", "u_m_s", "stw", "sog", "speed_m_s"),
}
MAX_PHI = 1.0  # rad: a roll angle column beyond it is in degrees (or the ship capsized)
META_KEYS = ("role", "speed_m_s", "imu_z_m", "imu_x_m", "load_kg", "load_z_m", "ship", "dataset", "sample_time")


def _closest(name: str) -> str | None:
    """The known column an unknown one most likely means (alias table, then spelling)."""
    low = name.lower()
    for col, names in ALIASES.items():
        if low in names:
            return col
    hit = difflib.get_close_matches(name, REQUIRED + OPTIONAL, n=1, cutoff=0.6)
    return hit[0] if hit else None


def _missing_message(path: Path, header: list[str], missing: list[str]) -> str:
    parts = []
    for c in missing:
        cand = [h for h in header if h not in REQUIRED + OPTIONAL and _closest(h) == c]
        hint = f" (the file has '{cand[0]}': if that is it, rename it '{c}' and check its sign)" if cand else ""
        parts.append(f"'{c}' ({WHAT[c]}){hint}")
    return (
        f"{path}: missing column{'s' if len(missing) > 1 else ''} "
        + ", ".join(parts)
        + f"; columns must include {','.join(REQUIRED)}"
    )


def write_roll_csv(rec: RollRecording, path: str | Path, meta: dict[str, str] | None = None) -> Path:
    """Write one dataset atomically; ``u`` and ``phi`` are written when present."""
    buf = io.StringIO()
    for k, v in {"ship": "our_lass_ii", "sample_time": f"{rec.T:g}", **(meta or {})}.items():
        buf.write(f"# {k}: {v}\n")
    extra = {k: x for k, x in (("u", rec.u), ("phi", rec.phi)) if x is not None}
    cols = list(REQUIRED) + list(extra)
    data = [np.arange(rec.n) * rec.T, rec.delta, rec.p, rec.a_s, rec.r, *extra.values()]
    buf.write(",".join(cols) + "\n")
    for row in np.column_stack(data):
        buf.write(",".join(f"{x:.9g}" for x in row) + "\n")
    return atomic_write_text(path, buf.getvalue())


def read_roll_csv(path: str | Path) -> tuple[RollRecording, dict[str, str]]:
    """Read and check one dataset; any problem is a one-line :class:`RecordingError`."""
    path = Path(path)
    meta, body = split_metadata(read_input_text(path, RecordingError, "a roll recording CSV (t, delta, p, a_s, r)").splitlines())
    if not body:
        raise RecordingError(f"{path}: no header row; expected columns {','.join(REQUIRED)}")
    rows = list(csv.reader(body))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise RecordingError(_missing_message(path, header, missing))
    notes = []
    for h in header:
        if h not in REQUIRED + OPTIONAL:
            near = _closest(h)
            notes.append(
                f"{path.name}: column '{h}' is not read"
                + (f" (did you mean '{near}'?)" if near else f" (known columns: {','.join(REQUIRED + OPTIONAL)})")
            )
    try:
        arr = np.array([[float(x) for x in r] for r in rows[1:]], dtype=float)
    except ValueError as exc:
        raise RecordingError(f"{path}: non-numeric value ({exc})") from exc
    if arr.ndim != 2 or arr.shape[0] < 100 or arr.shape[1] != len(header):
        raise RecordingError(f"{path}: need at least 100 complete rows of {len(header)} values")
    col = {h: arr[:, i] for i, h in enumerate(header)}
    for c in REQUIRED:
        if not np.all(np.isfinite(col[c])):
            raise RecordingError(f"{path}: column '{c}' has empty or non-finite values; fill or cut them")
    dt = np.diff(col["t"])
    T = float(np.median(dt))
    if T <= 0 or np.max(np.abs(dt - T)) > 1e-3 * T:
        raise RecordingError(f"{path}: column 't' is not uniformly sampled (steps {dt.min():g}..{dt.max():g} s); resample it")
    if np.std(col["p"]) < 1e-6:
        raise RecordingError(f"{path}: column 'p' is constant: the recording has no roll motion")
    phi = col.get("phi")
    if phi is not None and not (np.all(np.isfinite(phi)) and np.max(np.abs(phi)) < MAX_PHI):
        raise RecordingError(
            f"{path}: column 'phi' (roll angle, rad) must be finite and under {MAX_PHI:g} rad; it reaches "
            f"{np.nanmax(np.abs(phi)):g}: give it in radians, fill gaps, or drop the column"
        )
    u = col.get("u")
    if u is not None and not (np.all(np.isfinite(u)) and np.min(u) > 0):
        raise RecordingError(
            f"{path}: column 'u' (surge speed, m/s) must be finite and positive (the ship going ahead); "
            f"it has {np.nanmin(u):g}..{np.nanmax(u):g}: fill gaps, check its sign, or drop the column"
        )
    rec = RollRecording(
        name=path.name, T=T, delta=col["delta"], p=col["p"], a_s=col["a_s"], r=col["r"], phi=phi, notes=notes, u=u
    )
    return rec, meta
