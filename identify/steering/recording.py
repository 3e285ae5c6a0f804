"""Steering records from recording files (the recording format of docs/commands/diagnose.md; MARIN .dat through
:func:`diagnose.recording.load_recording`).

A CSV is read with its time stamps as they are: irregular stamps stay irregular and an empty cell
is a missing reading, because the steering fit samples its model exactly on any grid (the diagnosis
reader would resample the stamps onto a uniform grid and cut the record at a gap of more than two
samples). Columns (SI units, radians): ``t`` [s] increasing; ``delta`` [rad] rudder angle in the sign
of the profile's ``[helm] starboard_sign``; ``psi`` [rad] heading, clockwise positive; optional ``r``
[rad/s] yaw rate, ``v`` [m/s] sway (for the state-space model) and ``u`` [m/s] forward speed. A record
without heading is refused: the initial heading would stay a parameter no measurement determines and
the rudder offset and the rate gyro's bias could not be told apart.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from diagnose.recording import RecordingError, load_recording, split_metadata
from identify.steering.estimate import SteeringData
from primitives.io import read_record_lines
from primitives.unit_ranges import YAW_RATE_MAX_RAD_S

COLUMNS = ("t", "delta", "psi", "r", "v", "u")
MAX_RUDDER_RAD = 0.7  # 40 deg: no rudder goes further; larger values are degrees
MIN_READINGS = 20
MAX_HEADING_RAD = 2 * np.pi + 0.5  # a gyro reads within [0, 2 pi) or [-pi, pi); beyond (with margin): degrees
MAX_RATE_RAD_S = YAW_RATE_MAX_RAD_S  # beyond any ship's yaw rate: deg/s (primitives.unit_ranges)
MAX_STEP_S = 100.0  # a steering record samples a turn of tens of seconds (L/V is 40 s for KVLCC2): longer steps are ms


def read_records(path: str | Path) -> tuple[list[SteeringData], float | None, list[str]]:
    """The record(s) of one file, its mean forward speed (None when the file has no ``u``) and notes."""
    p = Path(path)
    if p.suffix.lower() == ".dat":
        out, speeds, notes = [], [], []
        for rec in load_recording(p):
            y = np.column_stack([rec.y[:, 1], rec.y[:, 2], rec.psi])
            out.append(SteeringData(rec.t, rec.channels["delta"], y, ("v", "r", "psi"), rec.source))
            speeds.append(float(np.mean(rec.y[:, 0])))
            notes += rec.notes
        return out, float(np.mean(speeds)), notes
    if p.suffix.lower() not in (".csv", ".txt"):
        raise RecordingError(
            f"{p}: unknown recording format {p.suffix!r}; give a .csv (docs/commands/steering.md: 'Records') or MARIN .dat file"
        )
    cols, notes = _read_csv(p)
    data = _checked(p, cols, notes)
    u = cols.get("u")
    return [data], (float(np.nanmean(u)) if u is not None and np.isfinite(u).any() else None), notes


def _read_csv(p: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    lines, cut = read_record_lines(p, RecordingError, "a steering recording (.csv saved as UTF-8, or MARIN .dat)", "utf-8-sig")
    _, body = split_metadata(lines)
    if not body:
        raise RecordingError(f"{p}: no header row; the first non-comment line must name the columns (t,delta,psi,r,...)")
    rows = list(csv.reader(body))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in ("t", "delta", "psi") if c not in header]
    if missing:
        raise RecordingError(
            f"{p}: missing column(s) {', '.join(missing)}; a steering record needs t [s], delta [rad] and psi [rad], "
            f"r [rad/s] optional (the header read is {body[0].strip()[:80]!r})"
        )
    cols = {}
    for j, name in enumerate(header):
        if name not in COLUMNS:
            continue
        vals = np.full(len(rows) - 1, np.nan)
        for i, row in enumerate(rows[1:]):
            s = row[j].strip() if j < len(row) else ""
            if s and s.lower() != "nan":
                try:
                    vals[i] = float(s)
                except ValueError:
                    raise RecordingError(f"{p}: row {i + 2}, column '{name}': {s!r} is not a number") from None
        cols[name] = vals
    return cols, [cut] if cut else []


def _checked(p: Path, cols: dict[str, np.ndarray], notes: list[str]) -> SteeringData:
    t = cols["t"]
    if not np.all(np.isfinite(t)):
        i = int(np.argmax(~np.isfinite(t)))
        raise RecordingError(f"{p}: column 't' is empty at row {i + 2}; every row needs a time in seconds")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        i = int(bad[0])
        raise RecordingError(
            f"{p}: column 't' does not increase at row {i + 3} ({t[i]:g} -> {t[i + 1]:g} s); sort the rows, drop repeats"
        )
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if step > MAX_STEP_S:
        raise RecordingError(
            f"{p}: column 't' steps {step:g} (median): t in milliseconds? give t in seconds (a steering record is "
            f"sampled well under {MAX_STEP_S:g} s apart)"
        )
    _check_swap(p, cols)
    d = cols["delta"]
    big = np.nanmax(np.abs(d)) if np.isfinite(d).any() else 0.0
    if big > MAX_RUDDER_RAD:
        raise RecordingError(
            f"{p}: column 'delta' reaches {big:.3g}, more than any rudder turns in radians: a rudder angle in degrees? "
            f"give radians ({big:.3g} deg = {np.radians(big):.3g} rad)"
        )
    _check_angle_units(p, cols)
    keep = np.isfinite(d)
    if not keep.all():
        notes.append(
            f"{int((~keep).sum())} row(s) without a rudder reading left out (the rudder is held from the reading before)"
        )
    channels = tuple(c for c in ("v", "r", "psi") if c in cols and np.isfinite(cols[c][keep]).sum() >= 2)
    if "psi" not in channels:
        raise RecordingError(f"{p}: column 'psi' has fewer than 2 readings; a steering fit needs the heading [rad]")
    y = np.column_stack([cols[c][keep] for c in channels])
    if "psi" in channels:
        psi = y[:, channels.index("psi")]
        ok = np.isfinite(psi)
        psi[ok] = np.unwrap(psi[ok])
    if np.isfinite(y).sum() < MIN_READINGS or keep.sum() < MIN_READINGS:
        raise RecordingError(
            f"{p}: only {int(keep.sum())} rows with a rudder reading; a steering fit needs at least {MIN_READINGS}"
        )
    return SteeringData(t[keep], d[keep], y, channels, str(p))


# delta's unit-gain misfit to d psi/dt below SWAP_FIT and below SWAP_RATIO x r's: the two columns are swapped. Measured
# (docs/bad-input-sweep.md, Stop 61): 529 correct records give delta's misfit >= 1.68e3 (a rudder angle is no rate) and
# r's 0.001-9.6 (steer_swap.log); a rudder held at 0 gives exactly 1, so the bound 0.8 never calls a record without rudder swapped
SWAP_FIT, SWAP_RATIO = 0.8, 0.01


def _swap_misfits(t: np.ndarray, delta: np.ndarray, psi: np.ndarray, r: np.ndarray) -> tuple[float, float]:
    """The unit-gain misfits of the columns ``delta`` and ``r`` to the heading's rate: |d psi/dt - x|^2 / |d psi/dt|^2
    over the intervals with both ends read (x at the interval's midpoint). ``r`` = d psi/dt fits (0 but for noise
    and sampling); a rudder angle in rad as a rate in rad/s does not (it leads the rate by the ship's time
    constants and differs from it in size by K' U/L): swapped columns fit the other way round."""
    ok = np.isfinite(t) & np.isfinite(delta) & np.isfinite(psi) & np.isfinite(r)
    rate = _heading_rate(t, psi, ok)
    if rate is None:
        return np.inf, np.inf
    den = float(rate @ rate)
    if not den > 0:
        return np.inf, np.inf

    def misfit(x: np.ndarray) -> float:
        e = rate - _midpoints(x, ok)
        return float(e @ e) / den

    return misfit(delta), misfit(r)


def _heading_rate(t: np.ndarray, psi: np.ndarray, ok: np.ndarray) -> np.ndarray | None:
    """d psi/dt over the intervals between consecutive readings ``ok`` (the heading unwrapped first), or None with
    fewer than 10 readings: the rate both the swap check and the unit check compare a column with."""
    if ok.sum() < 10:
        return None
    return np.diff(np.unwrap(psi[ok])) / np.diff(t[ok])


def _midpoints(x: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """``x`` at the midpoints of the intervals of :func:`_heading_rate` (the mean of each interval's two ends)."""
    return 0.5 * (x[ok][1:] + x[ok][:-1])


def _looks_swapped(a: float, b: float) -> bool:
    """Whether the misfits ``a`` (column delta) and ``b`` (column r) of :func:`_swap_misfits` say swapped columns."""
    return a < SWAP_FIT and a < SWAP_RATIO * b


def _check_swap(p: Path, cols: dict[str, np.ndarray]) -> None:
    """Refuse a record whose ``delta`` column is the heading's rate and ``r`` is not: the columns are swapped (before
    the unit checks, which would call the rudder in ``r`` a rate in deg/s)."""
    if "r" not in cols:
        return
    a, b = _swap_misfits(cols["t"], cols["delta"], cols["psi"], cols["r"])
    if _looks_swapped(a, b):
        raise RecordingError(
            f"{p}: columns delta and r look swapped: 'delta' follows the heading's rate (misfit {a:.2f}) and 'r' does not "
            f"({b:.2g}); swap the two column names in the header row (delta is the rudder angle [rad], r the yaw rate [rad/s])"
        )


def _check_angle_units(p: Path, cols: dict[str, np.ndarray]) -> None:
    """Heading and yaw rate in radians: a raw heading beyond 2 pi (with margin) or a rate beyond any ship's is
    in degrees; with both columns, the rate of the heading against r (deg vs rad is a factor 57.3)."""
    for name, limit, unit in (("psi", MAX_HEADING_RAD, "rad"), ("r", MAX_RATE_RAD_S, "rad/s")):
        x = cols.get(name)
        big = float(np.nanmax(np.abs(x))) if x is not None and np.isfinite(x).any() else 0.0
        if big > limit:
            fix = "give radians wrapped to [-pi, pi) or [0, 2 pi)" if name == "psi" else "give rad/s"
            raise RecordingError(
                f"{p}: column '{name}' reaches {big:.3g}, more than {limit:.3g} {unit}: in degrees? {fix} "
                f"({big:.3g} deg = {np.radians(big):.3g} rad)"
            )
    if "r" not in cols:
        return
    t, psi, r = cols["t"], cols["psi"], cols["r"]
    ok = np.isfinite(psi) & np.isfinite(r)
    dpsi = _heading_rate(t, psi, ok)
    if dpsi is None:
        return
    rm = _midpoints(r, ok)
    den = float(rm @ rm)
    if den <= 0 or float(dpsi @ dpsi) <= 0:
        return
    k = float(dpsi @ rm) / den
    if k > 0 and abs(np.log(k * 180 / np.pi)) < 0.35:
        raise RecordingError(f"{p}: column 'r' is about 57 times the rate of 'psi': r in deg/s? give rad/s")
    if k > 0 and abs(np.log(k * np.pi / 180)) < 0.35:
        raise RecordingError(f"{p}: column 'psi' changes about 57 times faster than 'r': psi in degrees? give radians")
    if k < 0 and abs(np.log(-k)) < 0.35:  # d psi/dt = -r: one of the two in the other sign convention
        raise RecordingError(
            f"{p}: column 'r' turns against the heading (d psi/dt = {k:.2f} r): r looks negated; give r and psi "
            "clockwise (to starboard) positive"
        )
    if k > 0 and abs(np.log(k * 1000)) < 0.35:
        raise RecordingError(f"{p}: column 'psi' changes about 1000 times slower than 'r': t in milliseconds? give seconds")
