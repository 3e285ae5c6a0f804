"""Recordings: the measured motion and inputs of one trial run (BRIEF section 7).

Two readers: the project CSV (``# key: value`` metadata lines, a header, one row per sample)
and the MARIN KVLCC2 ``.dat`` files as published (two title lines, tab-separated, 3
significant digits, repeated time stamps, trailing tab-only rows, degrees and rpm).

Whatever the source, a :class:`Recording` holds uniformly sampled signals in SI units and
radians: velocities (derived from positions and heading when missing), heading (unwrapped),
inputs, optional wind and roll. Repeated time stamps are averaged, irregular stamps are
resampled on a uniform grid, short NaN gaps are bridged (and reported) and long ones split
the recording: a long gap is never interpolated over.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from diagnose.recording_checks import check_frame, check_grid, check_rate, check_values
from primitives.errors import UserError
from primitives.io import read_input_text

MIN_SAMPLES = 50
MAX_BRIDGE_S = 5.0  # longest gap bridged by linear interpolation; longer gaps split the run
INPUTS = ("tau_x", "tau_y", "tau_n", "delta", "n", "n1", "alpha1", "n2", "alpha2")  # never bridged over a long gap
NUMERIC = ("t", "x", "y", "lat", "lon", "psi", "u", "v", "r", "tau_x", "tau_y", "tau_n", "delta", "n",
           "n1", "alpha1", "n2", "alpha2", "wind_speed", "wind_dir", "phi", "p",
           "v_dot")  # v_dot: measured sway acceleration, m/s^2 (optional; change detection uses it)


class RecordingError(UserError):
    """A recording cannot be used as given; the message names the file, the field and the fix."""


@dataclass
class Recording:
    """One uniformly sampled run. Arrays have N+1 samples; inputs at k act on the step k -> k+1."""

    source: str
    t: np.ndarray
    y: np.ndarray  # (N+1, 3) measured u, v, r over ground
    psi: np.ndarray  # (N+1,) unwrapped heading, rad
    pos: np.ndarray  # (N+1, 2) x north, y east, m
    channels: dict[str, np.ndarray]  # inputs and optional signals (wind_speed, wind_dir, phi, p, v_dot)
    segments: list[str] | None = None
    meta: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def scale(self) -> str | None:
        """``model`` or ``full`` from the header line ``# scale:``; None when the file does not say."""
        return self.meta.get("scale")

    @property
    def scale_factor(self) -> float | None:
        """Froude scale factor lambda from ``# scale_factor:`` (full-scale length / model length)."""
        v = self.meta.get("scale_factor")
        return None if v is None else float(v)

    @property
    def n_samples(self) -> int:
        return len(self.t)

    @property
    def sample_time(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0])

    def inputs_for(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Input array (N+1, m) for a profile's input names; error naming the missing column."""
        missing = [n for n in names if n not in self.channels]
        if missing:
            raise RecordingError(
                f"{self.source}: missing column(s) {missing} that the ship's inputs {list(names)} need; "
                "add them to the recording or choose the matching --ship"
            )
        return np.stack([self.channels[n] for n in names], axis=-1)

    @property
    def wind_ne(self) -> np.ndarray | None:
        """Measured wind as the air velocity (toward), north/east m/s, or None."""
        if "wind_speed" not in self.channels or "wind_dir" not in self.channels:
            return None
        s, d = self.channels["wind_speed"], self.channels["wind_dir"]  # direction it comes FROM
        return np.stack([-s * np.cos(d), -s * np.sin(d)], axis=-1)

    def window(self, i0: int, i1: int, label: str = "") -> Recording:
        """Samples i0..i1-1 as a new recording."""
        sl = slice(i0, i1)
        return replace(
            self,
            source=self.source + (f"[{label}]" if label else ""),
            t=self.t[sl], y=self.y[sl], psi=self.psi[sl], pos=self.pos[sl],
            channels={k: v[sl] for k, v in self.channels.items()},
            segments=None if self.segments is None else self.segments[sl],
            notes=list(self.notes),
        )


# -- generic column table -> Recording ------------------------------------------------------------


def _derive_velocities(t: np.ndarray, pos: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Body velocities over ground from positions and heading (BRIEF section 2 kinematics)."""
    xd = np.gradient(pos[:, 0], t)
    yd = np.gradient(pos[:, 1], t)
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([c * xd + s * yd, -s * xd + c * yd, np.gradient(psi, t)], axis=-1)


def _check_units(src: str, cols: dict[str, np.ndarray], t: np.ndarray) -> None:
    psi = cols["psi"]
    dpsi = np.diff(psi)
    dt = np.diff(t)
    if "r" in cols:
        rate = np.abs(dpsi / dt)
        ok = (np.abs(dpsi) < 3.0) & (np.abs(cols["r"][:-1]) > 1e-3)
        if ok.sum() > 10:
            ratio = np.median(rate[ok]) / max(np.median(np.abs(cols["r"][:-1][ok])), 1e-12)
            if 20.0 < ratio < 150.0:
                raise RecordingError(
                    f"{src}: column 'psi' looks like degrees (its rate is {ratio:.0f} x column 'r'); "
                    "convert heading to radians"
                )
    if np.nanmax(np.abs(psi)) > 2 * np.pi + 0.2 and np.any(np.abs(dpsi) > 300.0):
        raise RecordingError(f"{src}: column 'psi' looks like degrees (wraps at 360); convert heading to radians")
    if "r" not in cols and np.nanmax(psi) - np.nanmin(psi) > 7.0 and np.nanmedian(np.abs(dpsi / dt)) > 1.0:
        raise RecordingError(f"{src}: column 'psi' looks like degrees (turns faster than 1 rad/s); convert to radians")
    if "x" in cols and "y" in cols:
        x, y = cols["x"], cols["y"]
        looks_geo = (np.nanmax(np.abs(x)) <= 90 and np.nanmax(np.abs(y)) <= 180 and np.nanmean(np.abs(x)) > 1.0
                     and np.ptp(x) < 0.2 and np.ptp(y) < 0.2)
        if looks_geo and ("u" not in cols or np.nanmax(np.abs(cols["u"])) > 0.05):
            raise RecordingError(
                f"{src}: columns 'x', 'y' look like latitude/longitude in degrees; "
                "name them 'lat', 'lon' or give north/east metres"
            )


def _group_repeated(t: np.ndarray, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
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


def _check_step(src: str, dt_med: float, ts: float, declared: bool) -> None:
    """Time stamps whose step is several sample times cannot be a run sampled at ``ts``: the time
    column is in other units (ms) or the declared sample time is wrong."""
    if declared and dt_med > 3 * ts:
        ratio = dt_med / ts
        hint = next((f" (t in {u}?)" for f, u in ((1000.0, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds"))
                     if abs(math.log(ratio / f)) < 0.15), "")
        raise RecordingError(f"{src}: column 't' steps by {dt_med:g} (median) but the sample time is {ts:g} s{hint}; "
                             "give t in seconds and a matching '# sample_time:'")


def _bridged_notes(cols: dict[str, np.ndarray], i0: int, i1: int, t: np.ndarray, valid: np.ndarray) -> list[str]:
    """What linear interpolation bridged in rows i0..i1 of one piece: rows missing a state or an
    input, and cells missing in other columns (wind, roll), each said."""
    out = []
    bad = ~valid[i0: i1 + 1]
    if bad.any():
        which = [k for k, v in cols.items() if np.any(bad & ~np.isfinite(v[i0: i1 + 1]))]
        j = i0 + int(np.argmax(bad))
        out.append(f"{int(bad.sum())} row(s) missing {', '.join(which)} (first at t = {t[j]:g} s) bridged by linear "
                   f"interpolation (gaps <= {MAX_BRIDGE_S:g} s)")
    for k, v in cols.items():
        seg = v[i0: i1 + 1]
        miss = ~np.isfinite(seg) & valid[i0: i1 + 1]  # only cells of otherwise valid rows: not counted twice
        if miss.any() and np.isfinite(seg).sum() >= 2:
            j = i0 + int(np.argmax(miss))
            out.append(f"column {k!r}: {int(miss.sum())} missing value(s) (first at t = {t[j]:g} s) bridged by linear interpolation")
    return out


def _check_kinematics(src: str, grid: np.ndarray, pos: np.ndarray, res: dict[str, np.ndarray]) -> None:
    """u, v against the track, r against dpsi/dt, p against dphi/dt (recording_checks)."""
    if "u" in res and "v" in res:
        check_frame(src, grid, pos, res["psi"], res["u"], res["v"])
    if "r" in res:
        check_rate(src, grid, res["r"], res["psi"], "r", "psi", "yaw rate", "heading")
    if "p" in res and "phi" in res:
        check_rate(src, grid, res["p"], res["phi"], "p", "phi", "roll rate", "roll angle")


def build_recording(
    src: str,
    cols: dict[str, np.ndarray],
    *,
    meta: dict[str, str] | None = None,
    segments: list[str] | None = None,
    sample_time: float | None = None,
    min_samples: int = MIN_SAMPLES,
) -> list[Recording]:
    """Validate columns, average repeated stamps, resample uniformly, bridge or split gaps.

    Returns one recording per gap-free piece (most files give one).
    """
    meta = dict(meta or {})
    if "t" not in cols:
        raise RecordingError(f"{src}: missing required column 't' (time in seconds)")
    if "psi" not in cols:
        raise RecordingError(f"{src}: missing required column 'psi' (heading in radians)")
    has_xy = "x" in cols and "y" in cols
    if not has_xy and not ("lat" in cols and "lon" in cols):
        raise RecordingError(f"{src}: missing required columns 'x', 'y' (north, east in m) or 'lat', 'lon'")
    t = cols["t"]
    if np.any(~np.isfinite(t)):
        raise RecordingError(f"{src}: column 't' has empty or non-numeric values; every row needs a time")
    if np.any(np.diff(t) < 0):
        i = int(np.argmax(np.diff(t) < 0))
        raise RecordingError(f"{src}: column 't' decreases at row {i + 2} ({t[i]} -> {t[i + 1]}); sort the rows by time")
    cols = dict(cols)
    if not has_xy:
        lat0, lon0 = np.nanmean(cols["lat"][:5]), np.nanmean(cols["lon"][:5])
        r_e = 6371008.8
        cols["x"] = np.radians(cols.pop("lat") - lat0) * r_e
        cols["y"] = np.radians(cols.pop("lon") - lon0) * r_e * math.cos(math.radians(lat0))
    notes: list[str] = []
    t, cols, n_rep = _group_repeated(t, {k: v for k, v in cols.items() if k != "t"})
    if n_rep:
        notes.append(f"{n_rep} repeated time stamps: rows sharing a stamp were averaged")
    if len(t) < 3:
        raise RecordingError(f"{src}: only {len(t)} distinct time stamps; a recording needs at least {min_samples}")
    check_values(src, cols)
    _check_units(src, cols, t)
    dt_med = float(np.median(np.diff(t)))
    ts = float(sample_time or dt_med)
    if not (math.isfinite(ts) and ts > 0):
        raise RecordingError(f"{src}: sample time {ts} is not a positive number of seconds; fix '# sample_time:'")
    _check_step(src, dt_med, ts, sample_time is not None)
    check_grid(src, t, ts)
    # psi is unwrapped before interpolation
    psi = cols["psi"].copy()
    fin = np.isfinite(psi)
    psi[fin] = np.unwrap(psi[fin])
    cols["psi"] = psi
    # rows need the state and the inputs: a long gap in either splits the run, a short one is bridged
    req = ["x", "y", "psi"] + [k for k in ("u", "v", "r", *INPUTS) if k in cols and np.isfinite(cols[k]).sum() >= 2]
    valid = np.all([np.isfinite(cols[k]) for k in req], axis=0)
    idx = np.flatnonzero(valid)
    if len(idx) == 0:
        raise RecordingError(f"{src}: no row has all of {req}; check the columns")
    # a gap is the time with no valid row: longer than MAX_BRIDGE_S (and than 2 samples) splits
    longest = max(MAX_BRIDGE_S, 2 * ts)
    gaps = np.flatnonzero(np.diff(t[idx]) - ts > longest + 1e-9 * ts)
    bounds = np.split(idx, gaps + 1)
    if len(bounds) > 1:
        where = ", ".join(f"t = {t[idx[g]]:g}-{t[idx[g + 1]]:g} s" for g in gaps[:3]) + (", ..." if len(gaps) > 3 else "")
        notes.append(f"{len(gaps)} gap(s) of missing rows longer than {longest:g} s ({where}) split the run into "
                     f"{len(bounds)} pieces: never interpolated over")
    if abs(dt_med - ts) > 0.01 * ts or np.ptp(np.diff(t)) > 0.01 * ts:
        notes.append(f"time stamps irregular (median step {dt_med:.3g} s): resampled on a uniform {ts:g} s grid")
    out = []
    dropped = 0
    for piece_no, rows in enumerate(bounds):
        tp = t[rows]
        grid = np.arange(tp[0], tp[-1] + 1e-9 * ts, ts)
        if len(grid) < min_samples:
            dropped += 1
            continue
        res = {}
        for k, v in cols.items():
            ok = np.isfinite(v[rows])
            if ok.sum() < 2:
                continue
            res[k] = np.interp(grid, tp[ok], v[rows][ok])
        seg = None
        if segments is not None:
            seg_arr = np.asarray(segments, dtype=object)
            nearest = np.searchsorted(t, grid).clip(0, len(t) - 1)
            seg = list(seg_arr[nearest]) if len(seg_arr) == len(t) else None
        pos = np.stack([res["x"], res["y"]], axis=-1)
        pnotes = list(notes) + _bridged_notes(cols, rows[0], rows[-1], t, valid)
        if len(bounds) > 1:
            pnotes.append(f"piece {piece_no + 1} of {len(bounds)}: t = {tp[0]:g}-{tp[-1]:g} s")
        _check_kinematics(src, grid, pos, res)
        if all(k in res for k in ("u", "v", "r")):
            y = np.stack([res["u"], res["v"], res["r"]], axis=-1)
        else:
            y = _derive_velocities(grid, pos, res["psi"])
            for i, k in enumerate(("u", "v", "r")):
                if k in res:
                    y[:, i] = res[k]
            pnotes.append("u, v, r derived from x, y, psi where missing (central differences)")
        chans = {k: v for k, v in res.items() if k not in ("x", "y", "psi", "u", "v", "r")}
        label = f"piece {piece_no + 1}" if len(bounds) > 1 else ""
        out.append(Recording(src + (f"[{label}]" if label else ""), grid, y, res["psi"], pos, chans, seg, meta, pnotes))
    if dropped and out:
        out[0].notes.append(f"{dropped} piece(s) between gaps shorter than {min_samples} samples were left out")
    if not out:
        n_max = max(len(np.arange(t[b][0], t[b][-1] + 1e-9 * ts, ts)) for b in bounds)
        raise RecordingError(
            f"{src}: too short: {n_max} samples at {ts:g} s; a diagnosis needs at least {min_samples} (record longer)"
        )
    return out


# -- readers ---------------------------------------------------------------------------------------


def split_metadata(lines: list[str]) -> tuple[dict[str, str], list[str]]:
    """``# key: value`` metadata lines and the non-empty CSV lines of a recording (BRIEF section 7)."""
    meta: dict[str, str] = {}
    body = []
    for line in lines:
        if line.startswith("#"):
            if ":" in line:
                k, v = line[1:].split(":", 1)
                meta[k.strip()] = v.strip()
        elif line.strip():
            body.append(line)
    return meta, body


def read_csv(path: str | Path, *, sample_time: float | None = None) -> list[Recording]:
    """A recording CSV of BRIEF section 7 (one or more gap-free pieces)."""
    path = Path(path)
    meta, body = split_metadata(_read_text(path, "utf-8-sig").splitlines())
    if not body:
        raise RecordingError(f"{path}: no header row; the first non-comment line must name the columns (t,x,y,psi,...)")
    reader = csv.reader(body)
    header = [h.strip() for h in next(reader)]
    _check_header(path, header, body[0])
    rows = list(reader)
    if not rows:
        raise RecordingError(f"{path}: header but no data rows")
    for i, row in enumerate(rows):
        if len(row) > len(header) and any(c.strip() for c in row[len(header):]):
            raise RecordingError(f"{path}: row {i + 2} has {len(row)} fields but the header names {len(header)} columns; "
                                 "fix the row (a value too many, or a decimal comma?)")
    cols: dict[str, np.ndarray] = {}
    segments = None
    for j, name in enumerate(header):
        raw = [row[j].strip() if j < len(row) else "" for row in rows]
        if name == "segment":
            segments = raw
            continue
        if name not in NUMERIC:
            continue
        vals = np.full(len(raw), np.nan)
        for i, s in enumerate(raw):
            if s and s.lower() != "nan":
                try:
                    vals[i] = float(s)
                except ValueError:
                    raise RecordingError(f"{path}: row {i + 2}, column '{name}': {s!r} is not a number") from None
        cols[name] = vals
    _check_meta(path, meta)
    ts = sample_time or (float(meta["sample_time"]) if "sample_time" in meta else None)
    return build_recording(str(path), cols, meta=meta, segments=segments, sample_time=ts)


def _check_header(path: Path, header: list[str], line: str) -> None:
    """Column names as BRIEF section 7 gives them (lower case, no units, comma-separated, each once);
    the message quotes the header as read."""
    shown = line.strip()[:80]
    if len(header) == 1:
        sep = next((f"{name} ({c!r})" for c, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")) if c in line), "")
        raise RecordingError(f"{path}: the header {shown!r} has one column" + (f", separated by {sep}" if sep else "")
                             + "; separate the columns with commas (t,x,y,psi,...)")
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if name in seen:
            raise RecordingError(f"{path}: column {name!r} appears twice in the header (columns {seen[name] + 1} and {j + 1}); "
                                 "keep one")
        seen[name] = j
        base = re.split(r"[\s\[\(/]", name, maxsplit=1)[0].lower()
        if name not in NUMERIC and name != "segment" and (base in NUMERIC or base == "segment"):
            raise RecordingError(f"{path}: column {name!r} in the header {shown!r}: name it exactly {base!r} "
                                 "(lower case, no unit: values are read in SI units, angles in rad)")
    if "t" not in header:
        raise RecordingError(f"{path}: missing required column 't' (time in seconds); the header read is {shown!r}")


def _read_text(path: Path, encoding: str) -> str:
    return read_input_text(path, RecordingError, "a recording file (.csv saved as UTF-8, or MARIN .dat)", encoding)


def _check_meta(path: Path, meta: dict[str, str]) -> None:
    """Header values the loader uses: sample time (s), scale (model|full) and scale factor."""
    for key in ("sample_time", "scale_factor"):
        if key in meta:
            try:
                v = float(meta[key])
            except ValueError:
                v = float("nan")
            if not (math.isfinite(v) and v > 0):
                raise RecordingError(f"{path}: header '# {key}: {meta[key]}' must be a positive number")
    if "scale" in meta and meta["scale"] not in ("model", "full"):
        raise RecordingError(f"{path}: header '# scale: {meta['scale']}' must be 'model' or 'full'")
    if meta.get("scale") == "model" and "scale_factor" not in meta:
        raise RecordingError(f"{path}: header '# scale: model' needs '# scale_factor: LAMBDA' (full-scale length / model length)")


KVLCC2_COLUMNS = ("t", "x", "y", "phi", "psi", "u", "v", "p", "r", "delta", "n")


def read_marin_dat(path: str | Path, *, sample_time: float = 1.0) -> Recording:
    """A MARIN KVLCC2 free-running ``.dat`` file as published (SIMMAN 2008).

    Degrees -> radians (phi, psi, p, r, delta), rpm -> rev/s. The published u, v are the
    earth-frame velocity components (dx0/dt, dy0/dt: the check below compares them with the
    differentiated track), so they are rotated into the body frame. Repeated stamps (3
    significant digits: 1 s resolution after t = 100 s) are averaged and the run resampled to
    ``sample_time`` (1 s by default, the resolution of the late stamps).
    """
    path = Path(path)
    rows = []
    for line in _read_text(path, "latin-1").splitlines()[2:]:
        parts = [p for p in line.replace(",", " ").split() if p]
        if len(parts) < len(KVLCC2_COLUMNS):
            continue
        try:
            rows.append([float(p) for p in parts[: len(KVLCC2_COLUMNS)]])
        except ValueError:
            continue
    if len(rows) < MIN_SAMPLES:
        raise RecordingError(f"{path}: only {len(rows)} data rows of 11 tab-separated numbers; is this a MARIN .dat file?")
    a = np.array(rows)
    cols = {k: a[:, i] for i, k in enumerate(KVLCC2_COLUMNS)}
    for k in ("phi", "psi", "p", "r", "delta"):
        cols[k] = np.radians(cols[k])
    cols["n"] = cols["n"] / 60.0
    meta = {"source": "MARIN KVLCC2 (SIMMAN 2008)", "scale": "full", "scale_factor": "1"}
    t_raw = cols["t"]
    if not np.all(np.isfinite(t_raw)) or np.any(np.diff(t_raw) < 0) or len(np.unique(t_raw)) < 3:
        build_recording(str(path), cols, meta=meta, sample_time=sample_time)  # raises the time axis's own error
    t, g, _ = _group_repeated(t_raw, {k: v for k, v in cols.items() if k != "t"})
    # which frame are u, v in? compare with the differentiated track (early, finely sampled part)
    early = t < 100.0 if np.sum(t < 100.0) > 20 else slice(None)
    with np.errstate(all="ignore"):
        xd, yd = np.gradient(g["x"], t)[early], np.gradient(g["y"], t)[early]
        c, s = np.cos(g["psi"][early]), np.sin(g["psi"][early])
        err_earth = np.mean((xd - g["u"][early]) ** 2 + (yd - g["v"][early]) ** 2)
        ub, vb = g["u"][early], g["v"][early]
        err_body = np.mean((xd - (c * ub - s * vb)) ** 2 + (yd - (s * ub + c * vb)) ** 2)
    note = "u, v as published are body-frame velocities"
    if err_earth < err_body:
        c, s = np.cos(cols["psi"]), np.sin(cols["psi"])
        cols["u"], cols["v"] = c * cols["u"] + s * cols["v"], -s * cols["u"] + c * cols["v"]
        # only this reader rotates: the MARIN format is the one place the frame is known; a CSV
        # with earth-frame u, v is refused (recording_checks.check_frame)
        note = ("u, v as published in MARIN .dat files are earth-frame (dx0/dt, dy0/dt): rotated into the body frame "
                "(CSV recordings must give body-frame u, v)")
    rec = build_recording(str(path), cols, meta=meta, sample_time=sample_time)[0]
    rec.notes.insert(0, note)
    return rec


def load_recording(path: str | Path, *, sample_time: float | None = None) -> list[Recording]:
    """Read a recording file by its suffix (.csv or MARIN .dat); a list of gap-free pieces."""
    p = Path(path)
    if p.suffix.lower() == ".dat":
        return [read_marin_dat(p, sample_time=sample_time or 1.0)]
    if p.suffix.lower() in (".csv", ".txt"):
        return read_csv(p, sample_time=sample_time)
    raise RecordingError(f"{p}: unknown recording format {p.suffix!r}; give a .csv (BRIEF section 7) or MARIN .dat file")


def write_csv(rec: Recording, path: str | Path, *, meta: dict[str, str] | None = None) -> Path:
    """Write a recording as a BRIEF section 7 CSV (atomically)."""
    from primitives.io import atomic_write_text

    m = dict(rec.meta)
    m.update(meta or {})
    m.setdefault("sample_time", f"{rec.sample_time:g}")
    cols = {"t": rec.t, "x": rec.pos[:, 0], "y": rec.pos[:, 1], "psi": rec.psi,
            "u": rec.y[:, 0], "v": rec.y[:, 1], "r": rec.y[:, 2], **rec.channels}
    lines = [f"# {k}: {v}" for k, v in m.items()]
    lines.append(",".join(cols) + ("," + "segment" if rec.segments is not None else ""))
    arr = np.column_stack(list(cols.values()))
    for i, row in enumerate(arr):
        line = ",".join("nan" if not np.isfinite(x) else f"{x:.9g}" for x in row)
        if rec.segments is not None:
            line += "," + str(rec.segments[i])
        lines.append(line)
    return atomic_write_text(path, "\n".join(lines) + "\n")
