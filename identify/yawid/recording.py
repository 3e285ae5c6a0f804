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
from primitives.io import atomic_write_text, read_input_text
from primitives.ship import ShipProfile

COLUMNS = ("t", "r", "v_dot", "u", "v", "phi", "tau_r")
POD_COLUMNS = ("n1", "delta1", "n2", "delta2")


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
    sig = {k: cols[k] for k in need[1:]}
    sig["tau_r"] = _pod_moment(path, cols, profile)
    return YawData(t, sig, source=str(path))


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
