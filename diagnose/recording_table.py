"""From a column table to uniformly sampled pieces: the steps of :func:`diagnose.recording.build_recording`.

Pure functions on numpy columns (no I/O): required columns and the time axis, latitude/longitude
to metres, repeated stamps averaged, unit checks, which rows are complete (the states and the
inputs the ship uses), gaps bridged or split, one piece resampled on a uniform grid. Each raises
:class:`diagnose.recording.RecordingError` naming the file, the column and the fix.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from diagnose.recording_checks import check_grid, check_values
from diagnose.recording_kinematics import check_frame, check_rate
from primitives.errors import UserError
from primitives.orderstats import median  # numpy's numbers without its import of numpy.ma (stop 52)

MAX_BRIDGE_S = 5.0  # longest gap bridged by linear interpolation; longer gaps split the run
INPUTS = ("tau_x", "tau_y", "tau_n", "delta", "n", "n1", "alpha1", "n2", "alpha2")  # never bridged over a long gap


def _error() -> type[UserError]:
    from diagnose.recording import RecordingError

    return RecordingError


def missing_columns(names: Collection[str], inputs: Collection[str] = ()) -> list[str]:
    """Every required column (t, psi, x and y or lat and lon) and ship input missing from ``names``,
    each with its unit, so that one message names them all."""
    out = [f"'{k}' ({what})" for k, what in (("t", "time, s"), ("psi", "heading, rad")) if k not in names]
    if not ({"x", "y"} <= set(names) or {"lat", "lon"} <= set(names)):
        out.append("'x', 'y' (north, east, m) or 'lat', 'lon' (deg)")
    out += [f"'{k}'" for k in inputs if k not in names]
    return out


def check_table(src: str, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The required columns (t, psi, x and y or lat and lon) and a time axis that is complete and
    sorted; returns (t, the other columns) with lat/lon converted to north/east metres."""
    missing = missing_columns(cols)
    if missing:
        raise _error()(f"{src}: missing required column(s) {', '.join(missing)}")
    has_xy = "x" in cols and "y" in cols
    t = cols["t"]
    if np.any(~np.isfinite(t)):
        raise _error()(f"{src}: column 't' has empty or non-numeric values; every row needs a time")
    if np.any(np.diff(t) < 0):
        i = int(np.argmax(np.diff(t) < 0))
        raise _error()(f"{src}: column 't' decreases at row {i + 2} ({t[i]} -> {t[i + 1]}); sort the rows by time")
    cols = {k: v for k, v in cols.items() if k != "t"}
    if not has_xy:
        lat0, lon0 = np.nanmean(cols["lat"][:5]), np.nanmean(cols["lon"][:5])
        r_e = 6371008.8
        cols["x"] = np.radians(cols.pop("lat") - lat0) * r_e
        cols["y"] = np.radians(cols.pop("lon") - lon0) * r_e * math.cos(math.radians(lat0))
    return t, cols


def derive_velocities(t: np.ndarray, pos: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Body velocities over ground from positions and heading (Fossen 2021, eq. 2.40: x north, y east)."""
    xd = np.gradient(pos[:, 0], t)
    yd = np.gradient(pos[:, 1], t)
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([c * xd + s * yd, -s * xd + c * yd, np.gradient(psi, t)], axis=-1)


def check_units(src: str, cols: dict[str, np.ndarray], t: np.ndarray) -> None:
    psi = cols["psi"]
    dpsi = np.diff(psi)
    dt = np.diff(t)
    if "r" in cols:
        rate = np.abs(dpsi / dt)
        ok = (np.abs(dpsi) < 3.0) & (np.abs(cols["r"][:-1]) > 1e-3)
        if ok.sum() > 10:
            ratio = median(rate[ok]) / max(median(np.abs(cols["r"][:-1][ok])), 1e-12)
            if 20.0 < ratio < 150.0:
                raise _error()(
                    f"{src}: column 'psi' looks like degrees (its rate is {ratio:.0f} x column 'r'); convert heading to radians"
                )
    if np.nanmax(np.abs(psi)) > 2 * np.pi + 0.2 and np.any(np.abs(dpsi) > 300.0):
        raise _error()(f"{src}: column 'psi' looks like degrees (wraps at 360); convert heading to radians")
    if "r" not in cols and np.nanmax(psi) - np.nanmin(psi) > 7.0 and np.nanmedian(np.abs(dpsi / dt)) > 1.0:
        raise _error()(f"{src}: column 'psi' looks like degrees (turns faster than 1 rad/s); convert to radians")
    if "x" in cols and "y" in cols:
        x, y = cols["x"], cols["y"]
        looks_geo = (
            np.nanmax(np.abs(x)) <= 90
            and np.nanmax(np.abs(y)) <= 180
            and np.nanmean(np.abs(x)) > 1.0
            and np.ptp(x) < 0.2
            and np.ptp(y) < 0.2
        )
        if looks_geo and ("u" not in cols or np.nanmax(np.abs(cols["u"])) > 0.05):
            raise _error()(
                f"{src}: columns 'x', 'y' look like latitude/longitude in degrees; "
                "name them 'lat', 'lon' or give north/east metres"
            )


def group_repeated(t: np.ndarray, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
    """Average rows that share a time stamp (values printed with few digits repeat the stamp)."""
    uniq, inv, counts = np.unique(t, return_inverse=True, return_counts=True)
    if len(uniq) == len(t):
        return t, cols, 0
    out = {}
    for k, v in cols.items():
        s = np.zeros(len(uniq))
        c = np.zeros(len(uniq))
        ok = np.isfinite(v)
        np.add.at(s, inv[ok], v[ok])
        np.add.at(c, inv[ok], 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[k] = np.where(c > 0, s / np.maximum(c, 1), np.nan)
    return uniq, out, int(np.sum(counts > 1))


def check_step(src: str, dt_med: float, ts: float, declared: bool) -> None:
    """Time stamps whose step is several sample times cannot be a run sampled at ``ts``: the time
    column is in other units (ms) or the declared sample time is wrong."""
    if declared and dt_med > 3 * ts:
        ratio = dt_med / ts
        hint = next(
            (
                f" (t in {u}?)"
                for f, u in ((1000.0, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds"))
                if abs(math.log(ratio / f)) < 0.15
            ),
            "",
        )
        raise _error()(
            f"{src}: column 't' steps by {dt_med:g} (median) but the sample time is {ts:g} s{hint}; "
            "give t in seconds and a matching '# sample_time:'"
        )


def bridged_notes(cols: dict[str, np.ndarray], i0: int, i1: int, t: np.ndarray, valid: np.ndarray) -> list[str]:
    """What linear interpolation bridged in rows i0..i1 of one piece: rows missing a state or an
    input, and cells missing in other columns (wind, roll), each said."""
    out = []
    bad = ~valid[i0 : i1 + 1]
    if bad.any():
        which = [k for k, v in cols.items() if np.any(bad & ~np.isfinite(v[i0 : i1 + 1]))]
        j = i0 + int(np.argmax(bad))
        out.append(
            f"{int(bad.sum())} row(s) missing {', '.join(which)} (first at t = {t[j]:g} s) bridged by linear "
            f"interpolation (gaps <= {MAX_BRIDGE_S:g} s)"
        )
    for k, v in cols.items():
        seg = v[i0 : i1 + 1]
        miss = ~np.isfinite(seg) & valid[i0 : i1 + 1]  # only cells of otherwise valid rows: not counted twice
        if miss.any() and np.isfinite(seg).sum() >= 2:
            j = i0 + int(np.argmax(miss))
            out.append(
                f"column {k!r}: {int(miss.sum())} missing value(s) (first at t = {t[j]:g} s) bridged by linear interpolation"
            )
    return out


def check_kinematics(src: str, grid: np.ndarray, pos: np.ndarray, res: dict[str, np.ndarray]) -> None:
    """u, v against the track, r against dpsi/dt, p against dphi/dt (recording_checks)."""
    if "u" in res and "v" in res:
        check_frame(src, grid, pos, res["psi"], res["u"], res["v"])
    if "r" in res:
        check_rate(src, grid, res["r"], res["psi"], "r", "psi", "yaw rate", "heading")
    if "p" in res and "phi" in res:
        check_rate(src, grid, res["p"], res["phi"], "p", "phi", "roll rate", "roll angle")


def complete_rows(
    src: str, cols: dict[str, np.ndarray], inputs: tuple[str, ...] | list[str] | None
) -> tuple[np.ndarray, list[str]]:
    """Rows holding the state (x, y, psi and u, v, r when given) and the inputs the ship uses
    (``inputs``; None: every input column present), and those column names. A column with fewer
    than two values does not count (nothing to interpolate); a column the ship does not use never
    splits the run (it is bridged, and said, like wind or roll)."""
    used = INPUTS if inputs is None else tuple(inputs)
    req = ["x", "y", "psi"] + [k for k in ("u", "v", "r", *used) if k in cols and np.isfinite(cols[k]).sum() >= 2]
    valid = np.all([np.isfinite(cols[k]) for k in req], axis=0)
    if not valid.any():
        raise _error()(f"{src}: no row has all of {req}; check the columns")
    return valid, req


def split_gaps(t: np.ndarray, valid: np.ndarray, ts: float) -> tuple[list[np.ndarray], str | None]:
    """Indices of the complete rows cut where no row is complete for longer than MAX_BRIDGE_S (and
    than 2 samples), and the note saying so (None when the run is one piece)."""
    idx = np.flatnonzero(valid)
    longest = max(MAX_BRIDGE_S, 2 * ts)
    gaps = np.flatnonzero(np.diff(t[idx]) - ts > longest + 1e-9 * ts)
    bounds = np.split(idx, gaps + 1)
    if len(bounds) == 1:
        return bounds, None
    where = ", ".join(f"t = {t[idx[g]]:g}-{t[idx[g + 1]]:g} s" for g in gaps[:3]) + (", ..." if len(gaps) > 3 else "")
    return bounds, (
        f"{len(gaps)} gap(s) of missing rows longer than {longest:g} s ({where}) split the run into "
        f"{len(bounds)} pieces: never interpolated over"
    )


def resample_piece(
    cols: dict[str, np.ndarray], t: np.ndarray, rows: np.ndarray, ts: float
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """One piece's columns on a uniform grid of ``ts`` from its first to its last complete row
    (linear interpolation; a column with fewer than two values in the piece is left out)."""
    tp = t[rows]
    grid = np.arange(tp[0], tp[-1] + 1e-9 * ts, ts)
    res = {}
    for k, v in cols.items():
        ok = np.isfinite(v[rows])
        if ok.sum() >= 2:
            res[k] = np.interp(grid, tp[ok], v[rows][ok])
    return grid, res


def piece_segments(segments: list[str] | None, t: np.ndarray, grid: np.ndarray) -> list | None:
    """Segment labels of the nearest rows on the grid (None without labels or when they do not match the rows)."""
    if segments is None or len(segments) != len(t):
        return None
    nearest = np.searchsorted(t, grid).clip(0, len(t) - 1)
    return list(np.asarray(segments, dtype=object)[nearest])


def piece_velocities(grid: np.ndarray, pos: np.ndarray, res: dict[str, np.ndarray]) -> tuple[np.ndarray, str | None]:
    """(u, v, r) of a piece: the columns, derived from the track where missing (and a note saying so)."""
    if all(k in res for k in ("u", "v", "r")):
        return np.stack([res["u"], res["v"], res["r"]], axis=-1), None
    y = derive_velocities(grid, pos, res["psi"])
    for i, k in enumerate(("u", "v", "r")):
        if k in res:
            y[:, i] = res[k]
    return y, "u, v, r derived from x, y, psi where missing (central differences)"


def uniform_axis(
    src: str, t: np.ndarray, cols: dict[str, np.ndarray], sample_time: float | None, min_samples: int
) -> tuple[np.ndarray, dict[str, np.ndarray], float, list[str], str | None]:
    """Repeated stamps averaged, values and units checked, the sample time (declared, else the
    median step) checked against the stamps, heading unwrapped: (t, columns, sample time, notes,
    the note that the stamps are irregular or None)."""
    notes: list[str] = []
    t, cols, n_rep = group_repeated(t, cols)
    if n_rep:
        notes.append(f"{n_rep} repeated time stamps: rows sharing a stamp were averaged")
    if len(t) < 3:
        raise _error()(f"{src}: only {len(t)} distinct time stamps; a recording needs at least {min_samples}")
    check_values(src, cols)
    check_units(src, cols, t)
    dt_med = float(median(np.diff(t)))
    ts = float(sample_time or dt_med)
    if not (math.isfinite(ts) and ts > 0):
        raise _error()(f"{src}: sample time {ts} is not a positive number of seconds; fix '# sample_time:'")
    check_step(src, dt_med, ts, sample_time is not None)
    check_grid(src, t, ts)
    psi = cols["psi"].copy()  # unwrapped before interpolation
    fin = np.isfinite(psi)
    psi[fin] = np.unwrap(psi[fin])
    cols["psi"] = psi
    irregular = None
    if abs(dt_med - ts) > 0.01 * ts or np.ptp(np.diff(t)) > 0.01 * ts:
        irregular = f"time stamps irregular (median step {dt_med:.3g} s): resampled on a uniform {ts:g} s grid"
    return t, cols, ts, notes, irregular
