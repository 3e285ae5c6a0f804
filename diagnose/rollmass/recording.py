"""Roll recordings as CSV (BRIEF section 7 style) for the mass / CoG estimator.

Columns (SI, radians): ``t`` [s, uniform], ``delta`` [rad, measured rudder], ``p`` [rad/s, roll-rate
gyro, (6a)], ``a_s`` [m/s^2, IMU lateral (tangential) accelerometer, (6b) and (7)], ``r`` [rad/s,
yaw-rate gyro in ship sign, i.e. minus (6c)]; optional ``phi`` [rad] (not used). Optional metadata
lines ``# key: value`` before the header: ``ship``, ``load_kg``, ``load_height_m`` (body frame,
z down), ``sample_time``.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from diagnose.recording import RecordingError, split_metadata
from diagnose.rollmass.simulate import RollRecording
from primitives.io import atomic_write_text, read_input_text

REQUIRED = ("t", "delta", "p", "a_s", "r")
WHAT = {"p": "roll-rate gyro", "a_s": "lateral accelerometer", "r": "yaw-rate gyro", "delta": "rudder angle", "t": "time"}


def write_roll_csv(rec: RollRecording, path: str | Path, meta: dict[str, str] | None = None) -> Path:
    """Write one dataset atomically; ``phi`` is written when present."""
    buf = io.StringIO()
    for k, v in {"ship": "our_lass_ii", "sample_time": f"{rec.T:g}", **(meta or {})}.items():
        buf.write(f"# {k}: {v}\n")
    cols = list(REQUIRED) + (["phi"] if rec.phi is not None else [])
    data = [np.arange(rec.n) * rec.T, rec.delta, rec.p, rec.a_s, rec.r] + ([rec.phi] if rec.phi is not None else [])
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
        c = missing[0]
        hint = " (a recording without roll cannot give the mass)" if c in ("p", "a_s") else ""
        raise RecordingError(f"{path}: missing column '{c}' ({WHAT[c]}){hint}; columns must include {','.join(REQUIRED)}")
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
    rec = RollRecording(name=path.name, T=T, delta=col["delta"], p=col["p"], a_s=col["a_s"], r=col["r"], phi=col.get("phi"))
    return rec, meta
