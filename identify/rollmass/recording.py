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
import re
from pathlib import Path

import numpy as np

from diagnose.recording import RecordingError, split_metadata
from identify.rollmass.simulate import RollRecording
from primitives.io import atomic_write_text, read_record_lines

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
    "phi": ("roll", "roll_angle", "heel", "heel_angle"),
}
MAX_PHI = 1.0  # rad: a roll angle column beyond it is in degrees (or the ship capsized)
MAX_T = 1.0  # s: the sign checks' roll band reaches 0.45 Hz, under the Nyquist frequency 1 / (2 T) for T < 1.11 s
MIN_ROWS = 100
META_KEYS = ("role", "speed_m_s", "imu_z_m", "imu_x_m", "load_kg", "load_z_m", "ship", "dataset", "sample_time")
META_WHAT = {
    "role": "nominal, calibration or loaded",
    "speed_m_s": "mean speed, m/s",
    "imu_z_m": "IMU z, m, positive down",
    "imu_x_m": "IMU x, m, forward of midship",
    "load_kg": "load, kg",
    "load_z_m": "load z, m, positive down",
    "ship": "the profile's ship name",
    "dataset": "a name",
    "sample_time": "s",
}


def _closest(name: str, spelling: bool = True) -> str | None:
    """The known column an unknown one most likely means (alias table, then, with ``spelling``, the
    nearest spelling; case is ignored: a logger's ``R`` or ``A_S`` is our ``r`` or ``a_s``)."""
    low = name.strip().lower()
    if low in REQUIRED + OPTIONAL:
        return low
    for col, names in ALIASES.items():
        if low in names:
            return col
    hit = difflib.get_close_matches(low, REQUIRED + OPTIONAL, n=1, cutoff=0.6) if spelling else []
    return hit[0] if hit else None


def _missing_message(path: Path, header: list[str], missing: list[str]) -> str:
    """Every missing column in one line, each with the file's column that most likely is it; the
    file's other unread columns are listed too (a name no table knows, say ``acc``, may be it)."""
    parts, named = [], set()
    for c in missing:
        cand = [h for h in header if h not in REQUIRED + OPTIONAL and _closest(h) == c]
        named.update(cand[:1])
        hint = f" (the file has '{cand[0]}': if that is it, rename it '{c}' and check its sign)" if cand else ""
        parts.append(f"'{c}' ({WHAT[c]}){hint}")
    rest = [h for h in header if h not in REQUIRED + OPTIONAL and h not in named]
    unread = f"; the file's unread column{'s' if len(rest) > 1 else ''} {', '.join(repr(h) for h in rest)}" if rest else ""
    return (
        f"{path}: missing column{'s' if len(missing) > 1 else ''} "
        + ", ".join(parts)
        + f"; columns must include {','.join(REQUIRED)}{unread}"
    )


def write_roll_csv(rec: RollRecording, path: str | Path, meta: dict[str, str] | None = None) -> Path:
    """Write one dataset atomically; ``u`` and ``phi`` are written when present."""
    buf = io.StringIO()
    for k, v in {"sample_time": f"{rec.T:g}", **(meta or {})}.items():  # no ship the caller did not name
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
    # a last row with no line break is cut short (a number cut in it reads as another): left out, with a note
    lines, cut = read_record_lines(path, RecordingError, "a roll recording CSV (t, delta, p, a_s, r)")
    meta, body = split_metadata(lines)
    header_notes = _header_keys(path, meta)
    if not body:
        raise RecordingError(f"{path}: no header row; expected columns {','.join(REQUIRED)}")
    rows = list(csv.reader(body))
    header = [h.strip() for h in rows[0]]
    if len(header) == 1 and (sep := next((c for c in ";\t " if c in header[0]), None)):
        raise RecordingError(f"{path}: the header row is one column separated by {sep!r}; separate the columns with commas")
    if "" in header:
        raise RecordingError(
            f"{path}: the header's column {header.index('') + 1} has no name (a trailing or doubled comma?); "
            "remove the extra commas or name the column"
        )
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise RecordingError(_missing_message(path, header, missing))
    _refuse_renamed_optional(path, header)
    notes = header_notes + ([f"{path}: {cut}"] if cut else [])
    for h in header:
        if h not in REQUIRED + OPTIONAL:
            near = _closest(h)
            notes.append(
                f"{path.name}: column '{h}' is not read"
                + (f" (did you mean '{near}'?)" if near else f" (known columns: {','.join(REQUIRED + OPTIONAL)})")
            )
    # the file's line of each data row: comment and blank lines are not in ``body`` but count in the file
    line_numbers = [k + 1 for k, line in enumerate(lines) if line.strip() and not line.startswith("#")][1:]
    arr = _numbers(path, header, rows[1:], line_numbers)
    col = {h: arr[:, i] for i, h in enumerate(header)}
    for c in REQUIRED:
        if not np.all(np.isfinite(col[c])):
            raise RecordingError(f"{path}: column '{c}' has empty or non-finite values; fill or cut them")
    T = _sample_time(path, col["t"], meta)
    if np.std(col["p"]) < 1e-6:
        raise RecordingError(f"{path}: column 'p' is constant: the recording has no roll motion")
    phi = col.get("phi")
    if phi is not None and not np.all(np.isfinite(phi)):
        raise RecordingError(
            f"{path}: column 'phi' (roll angle, rad) has empty or non-finite values; fill or cut them, or drop the column"
        )
    if phi is not None and np.max(np.abs(phi)) >= MAX_PHI:
        raise RecordingError(
            f"{path}: column 'phi' (roll angle, rad) must be under {MAX_PHI:g} rad; it reaches "
            f"{np.max(np.abs(phi)):g}: give it in radians, or drop the column"
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


UNIT_WORDS = ("m", "s", "kg", "g", "cm", "mm", "kn", "kt", "knots", "ms", "mps")  # unit suffixes a key may carry


def _stem(key: str) -> str:
    """A header key without case, separators ('-', ' ', '_') and trailing unit words: ``IMU-z-m`` and ``imu_z``
    give ``imuz``, ``Speed_kn`` gives ``speed``; ``imu_y_m`` stays ``imuy`` (another axis is another key)."""
    words = [w for w in re.split(r"[-_ ]+", key.strip().lower()) if w]
    while len(words) > 1 and words[-1] in UNIT_WORDS:
        words.pop()
    return "".join(words)


def _header_keys(path: Path, meta: dict[str, str]) -> list[str]:
    """Refuse a header key that is one of :data:`META_KEYS` in another case, with other separators or another
    unit suffix (``imu_z``, ``IMU-z-m``, ``speed_kn``, ``Speed_m_s``) while the file lacks that key: it was
    ignored and the profile's value used instead (stop 52's sweep: '# imu_z: -0.05' left the IMU at the
    profile's -0.09 m without a word). Any other key is named in a note: a spelling match (``imu_y_m``,
    ``sample_rate``, ``date``) is another quantity as often as not (stop 52's review, 3). ``load_height_m``
    is refused as ambiguous by the mass API."""
    notes, stems = [], {_stem(k): k for k in META_KEYS}
    for key, value in meta.items():
        if key in META_KEYS or key == "load_height_m":
            continue
        near = stems.get(_stem(key))
        if near and near not in meta:
            raise RecordingError(
                f"{path}: header '# {key}: {value}' is not a key mass reads; did you mean '# {near}:' "
                f"({META_WHAT[near]})? rename it (known keys: {', '.join(META_KEYS)})"
            )
        notes.append(f"{path.name}: header '# {key}:' is not read (known keys: {', '.join(META_KEYS)})")
    return notes


def _refuse_renamed_optional(path: Path, header: list[str]) -> None:
    """Refuse a column that is an optional one under another name (``roll`` for ``phi``, ``speed`` for
    ``u``) while the file lacks that one: read as it is it would be ignored and the answer change
    (``roll``: the wall-sided restoring left out of all three runs, the load -2 % in stop 50's sweep). Only
    the same name in other case or a name of the alias table: a spelling match is another quantity as
    often as not (a heading ``psi`` is not the roll angle ``phi``), so it stays a note."""
    for h in header:
        near = _closest(h, spelling=False) if h not in REQUIRED + OPTIONAL else None
        if near in OPTIONAL and near not in header:
            raise RecordingError(
                f"{path}: column '{h}' looks like '{near}' ({WHAT[near]}), which the file lacks: rename it "
                f"'{near}', or leave it out if it is another quantity"
            )


def _numbers(path: Path, header: list[str], rows: list[list[str]], line_numbers: list[int]) -> np.ndarray:
    """The data rows as floats; the first cell that is not a number is named by line and column
    (``line_numbers``: the file's line of each data row)."""
    for row, line in zip(rows, line_numbers):
        if len(row) != len(header):
            raise RecordingError(f"{path}: line {line} has {len(row)} values for the {len(header)} columns; complete or cut it")
        for name, x in zip(header, row):
            try:
                float(x)
            except ValueError:
                raise RecordingError(
                    f"{path}: line {line}, column '{name.strip()}': {x!r} is not a number; "
                    "fill or cut the row (empty cells too; NaN only where a gap is meant)"
                ) from None
    arr = np.array(rows, dtype=float).reshape(len(rows), len(header))
    if arr.shape[0] < MIN_ROWS:
        raise RecordingError(f"{path}: {arr.shape[0]} data rows; need at least {MIN_ROWS} (a roll recording of minutes)")
    return arr


def _sample_time(path: Path, t: np.ndarray, meta: dict[str, str]) -> float:
    """The uniform sample time of column ``t``: increasing, without repeats or gaps, fast enough for
    the roll band (the sign checks' 0.45 Hz band needs under MAX_T; a ``t`` in milliseconds reads
    1000 times slower), and as the header's ``sample_time`` says when it has one."""
    dt = np.diff(t)
    T = float(np.median(dt))
    if T <= 0 or np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise RecordingError(
            f"{path}: column 't' does not increase (t = {t[k]:g} s then {t[k + 1]:g} s); sort the rows and remove repeated times"
        )
    if np.max(np.abs(dt - T)) > 1e-3 * T:
        raise RecordingError(f"{path}: column 't' is not uniformly sampled (steps {dt.min():g}..{dt.max():g} s); resample it")
    said = meta.get("sample_time")
    try:
        said_T = float(said) if said is not None else None
    except ValueError:
        raise RecordingError(f"{path}: header '# sample_time: {said}' is not a number; write it in s, e.g. 0.02") from None
    if said_T is not None and abs(said_T - T) > 0.01 * T:
        raise RecordingError(
            f"{path}: header '# sample_time: {said}' contradicts column 't' (steps of {T:g} s); "
            "correct the header or give t in seconds"
        )
    if T > MAX_T:
        raise RecordingError(
            f"{path}: column 't' steps {T:g} s: the roll model needs samples under {MAX_T:g} s apart; give t in seconds "
            "(not ms) or record faster"
        )
    return T
