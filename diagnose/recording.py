"""Recordings: the measured motion and inputs of one trial run (the recording format of docs/commands/diagnose.md).

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
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from diagnose import recording_table as tb
from diagnose.recording_meta import (  # noqa: F401  (the header values re-exported)
    ENVIRONMENTS,
    MAX_TRIAL_WIND_MPS,
    RUDDER_SIGNS,
    WIND_REFERENCES,
    YAW_RATE_SIGNS,
    check_meta,
    true_wind,
    yaw_rate_as_said,
)
from diagnose.recording_table import INPUTS, MAX_BRIDGE_S  # noqa: F401  (re-exported)
from primitives.errors import UserError
from primitives.io import read_record_lines

MIN_SAMPLES = 50
NUMERIC = (
    "t",
    "x",
    "y",
    "lat",
    "lon",
    "psi",
    "u",
    "v",
    "r",
    "tau_x",
    "tau_y",
    "tau_n",
    "delta",
    "n",
    "n1",
    "alpha1",
    "n2",
    "alpha2",
    "wind_speed",
    "wind_dir",
    "phi",
    "p",
    "v_dot",
    "u_water",
    "v_water",
)  # v_dot: measured sway acceleration, m/s^2 (optional; change detection uses it); u_water, v_water: speed
# through the water, body axes, m/s (a log's; optional, diagnose.current_direct measures the current with it)


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
    def environment(self) -> str | None:
        """``sea``, ``basin`` or ``towing-tank`` from ``# environment:``; None when the file does not say."""
        return self.meta.get("environment")

    @property
    def in_tank(self) -> bool:
        """Recorded in a basin or towing tank: no current, no wind (header ``# environment:``)."""
        return self.environment in ("basin", "towing-tank")

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
            t=self.t[sl],
            y=self.y[sl],
            psi=self.psi[sl],
            pos=self.pos[sl],
            channels={k: v[sl] for k, v in self.channels.items()},
            segments=None if self.segments is None else self.segments[sl],
            notes=list(self.notes),
        )


# -- generic column table -> Recording ------------------------------------------------------------


def build_recording(
    src: str,
    cols: dict[str, np.ndarray],
    *,
    meta: dict[str, str] | None = None,
    segments: list[str] | None = None,
    sample_time: float | None = None,
    min_samples: int = MIN_SAMPLES,
    inputs: tuple[str, ...] | list[str] | None = None,
) -> list[Recording]:
    """Validate columns, average repeated stamps, resample uniformly, bridge or split gaps.

    ``inputs``: the input columns the ship uses (its profile's inputs): only they and the state
    split the run at a long gap (None: every input column present). Returns one recording per
    gap-free piece (most files give one).
    """
    meta = dict(meta or {})
    # u, v over ground: measured (columns, e.g. a GNSS Doppler) or derived from the track (the reader's own;
    # a header '# velocities: derived from the track', as write_csv keeps a MARIN run's, is believed, the
    # other way round it is not: without the columns they are derived here, whatever a header says)
    if "u" in cols and "v" in cols:
        meta.setdefault("velocities", "recorded")
    else:
        meta["velocities"] = "derived from the track"
    t, cols = tb.check_table(src, cols)
    t, cols, ts, notes, irregular = tb.uniform_axis(src, t, cols, sample_time, min_samples)
    valid, _ = tb.complete_rows(src, cols, inputs)
    bounds, split_note = tb.split_gaps(t, valid, ts)
    notes += [n for n in (split_note, irregular) if n]
    out = []
    for piece_no, rows in enumerate(bounds):
        grid, res = tb.resample_piece(cols, t, rows, ts)
        if len(grid) < min_samples:
            continue
        pos = np.stack([res["x"], res["y"]], axis=-1)
        pnotes = list(notes) + tb.bridged_notes(cols, rows[0], rows[-1], t, valid)
        if len(bounds) > 1:
            pnotes.append(f"piece {piece_no + 1} of {len(bounds)}: t = {t[rows[0]]:g}-{t[rows[-1]]:g} s")
        tb.check_kinematics(src, grid, pos, res)
        y, derived = tb.piece_velocities(grid, pos, res)
        pnotes += [derived] if derived else []
        chans = {k: v for k, v in res.items() if k not in ("x", "y", "psi", "u", "v", "r")}
        label = f"piece {piece_no + 1}" if len(bounds) > 1 else ""
        out.append(
            Recording(
                src + (f"[{label}]" if label else ""),
                grid,
                y,
                res["psi"],
                pos,
                chans,
                tb.piece_segments(segments, t, grid),
                meta,
                pnotes,
            )
        )
    if not out:
        n_max = max(len(np.arange(t[b][0], t[b][-1] + 1e-9 * ts, ts)) for b in bounds)
        raise RecordingError(
            f"{src}: too short: {n_max} samples at {ts:g} s; a diagnosis needs at least {min_samples} (record longer)"
        )
    if len(out) < len(bounds):
        out[0].notes.append(f"{len(bounds) - len(out)} piece(s) between gaps shorter than {min_samples} samples were left out")
    return out


# -- readers ---------------------------------------------------------------------------------------


def split_metadata(lines: list[str]) -> tuple[dict[str, str], list[str]]:
    """``# key: value`` metadata lines and the non-empty CSV lines of a recording (the recording format of docs/commands/diagnose.md)."""
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


def read_csv(
    path: str | Path,
    *,
    sample_time: float | None = None,
    inputs: tuple[str, ...] | list[str] | None = None,
    yaw_rate_sign: str | None = None,
) -> list[Recording]:
    """A recording CSV in the recording format of docs/commands/diagnose.md (one or more gap-free pieces; ``inputs``: see
    :func:`build_recording`; ``yaw_rate_sign``: stands for the header line ``# yaw_rate_sign:``)."""
    path = Path(path)
    lines, cut = _read_lines(path, "utf-8-sig")
    meta, body = split_metadata(lines)
    if not body:
        raise RecordingError(f"{path}: no header row; the first non-comment line must name the columns (t,x,y,psi,...)")
    reader = csv.reader(body)
    header = [h.strip() for h in next(reader)]
    _check_header(path, header, body[0], inputs or ())
    cols = _plain_numbers(header, body)
    if cols is not None:  # every cell a plain number: read at once (checks and errors below are for the rest)
        return _built(path, meta, cols, None, sample_time, inputs, yaw_rate_sign, cut)
    rows = list(reader)
    if not rows:
        raise RecordingError(f"{path}: header but no data rows; give the recording with its samples, one row each")
    lengths = set(map(len, rows))
    for i, row in enumerate(rows if max(lengths) > len(header) else ()):
        if len(row) > len(header) and any(c.strip() for c in row[len(header) :]):
            raise RecordingError(
                f"{path}: row {i + 2} has {len(row)} fields but the header names {len(header)} columns; "
                "fix the row (a value too many, or a decimal comma?)"
            )
    cols: dict[str, np.ndarray] = {}
    segments = None
    # every row as long as the header: its columns at once (a shorter row's missing cells read as empty below)
    whole = list(zip(*rows)) if lengths == {len(header)} else None
    for j, name in enumerate(header):
        if whole is not None and name in NUMERIC:
            try:  # numpy reads each cell with Python's float (the same numbers); an empty cell fails here
                cols[name] = np.array(whole[j], dtype=float)
                continue
            except ValueError:
                pass  # an empty or bad cell: read cell by cell below (empty is NaN, a bad one is said)
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
                    raise RecordingError(
                        f"{path}: row {i + 2}, column '{name}': {s!r} is not a number; correct the cell or cut the row (an empty cell is a gap)"
                    ) from None
        cols[name] = vals
    return _built(path, meta, cols, segments, sample_time, inputs, yaw_rate_sign, cut)


def _plain_numbers(header: list[str], body: list[str]) -> dict[str, np.ndarray] | None:
    """The columns of a CSV body (header line first) whose every column is numeric and every cell a
    plain number, every row as long as the header: numpy's parser reads each cell as Python's float
    does (correctly rounded: the same numbers), at a quarter of the CPU of the csv module and a
    float per cell (issue 26: eight recordings of 3,500 rows a diagnosis). None for anything else (a
    quote, an empty or bad cell, a row of another length, a text column): the cell-by-cell reader
    then reads it and says what is wrong."""
    if not set(header) <= set(NUMERIC) or len(body) < 2 or any('"' in line for line in body):
        return None
    try:
        table = np.loadtxt(body[1:], delimiter=",", dtype=float, comments=None, ndmin=2)
    except ValueError:
        return None
    if table.shape[1] != len(header):
        return None
    return {name: np.ascontiguousarray(table[:, j]) for j, name in enumerate(header)}


def _built(
    path: Path,
    meta: dict[str, str],
    cols: dict[str, np.ndarray],
    segments: list[str] | None,
    sample_time: float | None,
    inputs: tuple[str, ...] | list[str] | None,
    yaw_rate_sign: str | None,
    cut: str | None = None,
) -> list[Recording]:
    """:func:`read_csv`'s recordings from the columns read (``cut``: the note of a last row left out)."""
    check_meta(path, meta)
    ts = sample_time or (float(meta["sample_time"]) if "sample_time" in meta else None)
    added = [n for n in (cut, yaw_rate_as_said(cols, meta, yaw_rate_sign)) if n]
    recs = build_recording(str(path), cols, meta=meta, segments=segments, sample_time=ts, inputs=inputs)
    return [true_wind(path, replace(r, notes=[*r.notes, *added]) if added else r) for r in recs]


def _check_header(path: Path, header: list[str], line: str, inputs: tuple[str, ...] | list[str] = ()) -> None:
    """Column names as the recording format of docs/commands/diagnose.md gives them (lower case, no units, comma-separated, each once),
    every required column and ship input there (all missing ones named at once); the message quotes the header as read."""
    shown = line.strip()[:80]
    if len(header) == 1:
        sep = next((f"{name} ({c!r})" for c, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")) if c in line), "")
        raise RecordingError(
            f"{path}: the header {shown!r} has one column"
            + (f", separated by {sep}" if sep else "")
            + "; separate the columns with commas (t,x,y,psi,...)"
        )
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if name in seen:
            raise RecordingError(
                f"{path}: column {name!r} appears twice in the header (columns {seen[name] + 1} and {j + 1}); keep one"
            )
        seen[name] = j
        base = re.split(r"[\s\[\(/]", name, maxsplit=1)[0].lower()
        if name not in NUMERIC and name != "segment" and (base in NUMERIC or base == "segment"):
            raise RecordingError(
                f"{path}: column {name!r} in the header {shown!r}: name it exactly {base!r} "
                "(lower case, no unit: values are read in SI units, angles in rad)"
            )
    if "v_water" in seen and "u_water" not in seen:
        raise RecordingError(
            f"{path}: column 'v_water' without 'u_water': a log's speed through the water needs its forward part; "
            "add column u_water (m/s, body frame, forward) or drop v_water"
        )
    missing = tb.missing_columns(header, inputs)
    if missing:
        ship = f" (the ship's inputs are {', '.join(inputs)}: add them, or choose the matching --ship)" if inputs else ""
        raise RecordingError(f"{path}: missing required column(s) {', '.join(missing)}{ship}; the header read is {shown!r}")


def _read_lines(path: Path, encoding: str) -> tuple[list[str], str | None]:
    """The file's lines and the note of a last row cut short (left out: :func:`primitives.io.read_record_lines`)."""
    return read_record_lines(path, RecordingError, "a recording file (.csv saved as UTF-8, or MARIN .dat)", encoding)


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
    lines, cut = _read_lines(path, "latin-1")
    for line in lines[2:]:
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
    # free-running model tests in MARIN's basin, published at full scale, positive rudder to port
    meta = {
        "source": "MARIN KVLCC2 (SIMMAN 2008)",
        "scale": "full",
        "scale_factor": "1",
        "environment": "basin",
        "rudder_sign": "port-positive",
        "velocities": "derived from the track",  # the published u, v are dx0/dt, dy0/dt
    }
    t_raw = cols["t"]
    if not np.all(np.isfinite(t_raw)) or np.any(np.diff(t_raw) < 0) or len(np.unique(t_raw)) < 3:
        build_recording(str(path), cols, meta=meta, sample_time=sample_time)  # raises the time axis's own error
    t, g, _ = tb.group_repeated(t_raw, {k: v for k, v in cols.items() if k != "t"})
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
        # with earth-frame u, v is refused (recording_kinematics.check_frame)
        note = (
            "u, v as published in MARIN .dat files are earth-frame (dx0/dt, dy0/dt): rotated into the body frame "
            "(CSV recordings must give body-frame u, v)"
        )
    rec = build_recording(str(path), cols, meta=meta, sample_time=sample_time)[0]
    rec.notes[:0] = [note, cut] if cut else [note]
    return rec


def load_recording(
    path: str | Path,
    *,
    sample_time: float | None = None,
    inputs: tuple[str, ...] | list[str] | None = None,
    yaw_rate_sign: str | None = None,
) -> list[Recording]:
    """Read a recording file by its suffix (.csv or MARIN .dat); a list of gap-free pieces. ``inputs``:
    the input columns the ship uses (only they and the state split a run at a long gap);
    ``yaw_rate_sign``: the CSV's yaw rate convention, for its header line ``# yaw_rate_sign:``
    (a MARIN file's is known: starboard-positive)."""
    p = Path(path)
    if p.suffix.lower() == ".dat":
        return [read_marin_dat(p, sample_time=sample_time or 1.0)]
    if p.suffix.lower() in (".csv", ".txt"):
        return read_csv(p, sample_time=sample_time, inputs=inputs, yaw_rate_sign=yaw_rate_sign)
    raise RecordingError(
        f"{p}: unknown recording format {p.suffix!r}; give a .csv (docs/commands/diagnose.md: 'Recordings for diagnose') or MARIN .dat file"
    )


def write_csv(rec: Recording, path: str | Path, *, meta: dict[str, str] | None = None) -> Path:
    """Write a recording as a CSV in the recording format of docs/commands/diagnose.md (atomically)."""
    from primitives.io import atomic_write_text

    m = dict(rec.meta)
    m.update(meta or {})
    m.setdefault("sample_time", f"{rec.sample_time:g}")
    cols = {
        "t": rec.t,
        "x": rec.pos[:, 0],
        "y": rec.pos[:, 1],
        "psi": rec.psi,
        "u": rec.y[:, 0],
        "v": rec.y[:, 1],
        "r": rec.y[:, 2],
        **rec.channels,
    }
    lines = [f"# {k}: {v}" for k, v in m.items()]
    lines.append(",".join(cols) + ("," + "segment" if rec.segments is not None else ""))
    arr = np.column_stack(list(cols.values()))
    for i, row in enumerate(arr):
        line = ",".join("nan" if not np.isfinite(x) else f"{x:.9g}" for x in row)
        if rec.segments is not None:
            line += "," + str(rec.segments[i])
        lines.append(line)
    return atomic_write_text(path, "\n".join(lines) + "\n")
