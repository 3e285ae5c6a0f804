"""The columns ``detect`` and ``detect-prior`` read: which a recording lacks (every one in one
message), which it seems to carry under another name (refused: read as it is, the quantity would be
derived or left out instead), and notes for the columns neither reads."""

from __future__ import annotations

import difflib
from pathlib import Path

from diagnose.recording import NUMERIC
from identify.detect.checks import MOMENT
from identify.detect.inputs import POD_COLUMNS, SWAY_ACC
from identify.detect.yawmodel import SIGNALS

#: columns ``detect`` and ``detect-prior`` read (besides the recording format's t, x, y or lat, lon, psi, u, v)
KNOWN_COLUMNS = ("t", "x", "y", "lat", "lon", "psi", "u", "v", "r", "phi", "p", MOMENT, SWAY_ACC, *POD_COLUMNS, "segment")

#: names other loggers use for the columns detect reads (lower case); spelling alone does not find them
ALIASES = {
    "r": ("yaw_rate", "yawrate", "rot", "gyro_z", "wz", "psi_dot", "psidot"),
    "psi": ("heading", "hdg", "yaw"),
    "phi": ("roll", "roll_angle", "heel"),
    "p": ("roll_rate", "rollrate", "gyro_x", "wx", "phi_dot", "phidot"),
    MOMENT: ("tau_r", "tau_z", "n", "yaw_moment", "moment"),  # N: the yaw moment's usual symbol
    SWAY_ACC: ("vdot", "vd", "sway_acc"),  # not an accelerometer's a_y: it reads u r and g phi too
    "t": ("time", "timestamp"),
    "u": ("surge", "surge_speed"),
    "v": ("sway", "sway_speed", "sway_velocity"),
}


def missing_columns(header: list[str], kind: str | None) -> list[str]:
    """The columns the yaw row needs that ``header`` lacks, each with its unit and what stands in for it."""
    missing = [] if "r" in header else ["r (measured yaw rate, rad/s; not one derived from heading)"]
    pods = [c for c in POD_COLUMNS if c not in header]
    if pods and MOMENT not in header:
        missing.append(f"{MOMENT} (measured pod yaw moment, N m) or the pod inputs {', '.join(pods)} (rev/s, rad)")
    if "phi" in SIGNALS.get(kind, ()) and "phi" not in header:
        missing.append("phi (roll, rad; or use --model simplified)")
    if "p" in SIGNALS.get(kind, ()) and "p" not in header:
        missing.append(
            "p (roll rate, rad/s: the prior's yaw row has the roll-rate term N_p p; or refit the prior "
            "with detect-prior --no-roll-rate)"
        )
    if not ({"x", "y"} <= set(header) or {"lat", "lon"} <= set(header)):
        missing.insert(0, "x, y (north, east, m) or lat, lon (deg)")
    return [f"{c} ({what})" for c, what in (("t", "time, s"), ("psi", "heading, rad")) if c not in header] + missing


#: what each column detect reads is, for the messages about a renamed one
MEANING = {
    "t": "time, s",
    "r": "measured yaw rate, rad/s",
    "psi": "heading, rad",
    "phi": "roll, rad",
    "p": "roll rate, rad/s",
    MOMENT: "measured pod yaw moment, N m",
    SWAY_ACC: "measured sway acceleration, m/s^2",
    "u": "surge velocity, m/s",
    "v": "sway velocity, m/s",
}


ACCELEROMETER = ("ay", "a_y", "acc_y", "accy", "a_s", "f_y", "fy")  # an IMU's lateral channel


def _closest_known(h: str, cutoff: float | None) -> str | None:
    """The column detect reads that ``h`` most likely is: the same name in another case, an alias (another
    logger's name) or, with a ``cutoff``, a spelling within it (difflib's ratio; case ignored)."""
    low = h.strip().lower()
    alias = [c for c in KNOWN_COLUMNS if c == low] or [c for c, names in ALIASES.items() if low in names]
    close = alias or (difflib.get_close_matches(low, KNOWN_COLUMNS, n=1, cutoff=cutoff) if cutoff else [])
    return close[0] if close else None


def renamed_columns(header: list[str]) -> list[tuple[str, str, str]]:
    """``(column, known name, meaning)`` for each column detect does not read that is clearly a
    column it reads under another name (another case or an alias: ``R``, ``vdot``, ``tau_r``) while the
    file lacks that column: read as it is, the column would be ignored and the quantity derived or left
    out instead (v' differentiated from v, tau_n from the pods). A spelling match alone is a note
    (:func:`unknown_column_notes`): ``p_dot`` (roll acceleration) is not ``v_dot``, ``tau_n1`` not ``tau_n``."""
    out = []
    for h in header:
        if h in KNOWN_COLUMNS or h in NUMERIC:
            continue
        c = _closest_known(h, None)
        if c is not None and c not in header and c in MEANING:
            out.append((h, c, MEANING[c]))
    return out


def unknown_column_notes(path: Path | str, header: list[str]) -> list[str]:
    """One note per column that detect does not read, with the closest known name (a renamed
    ``vdot`` would otherwise be ignored and v' differentiated from v instead)."""
    out = []
    for h in header:
        if h in KNOWN_COLUMNS or h in NUMERIC:
            continue
        close = _closest_known(h, 0.5)
        hint = f"; did you mean '{close}'? rename it if so" if close and close not in header else ""
        if h.strip().lower() in ACCELEROMETER and SWAY_ACC not in header:
            # stop 50's sweep: 'ay' was told "did you mean 'y'" (a column the file has)
            hint = (
                f"; an accelerometer's lateral reading is not the sway acceleration '{SWAY_ACC}' (it holds u r and "
                f"g phi too): without '{SWAY_ACC}' v' is differentiated from v"
            )
        out.append(f"{path}: column '{h}' is not one detect reads and is ignored{hint}")
    return out
