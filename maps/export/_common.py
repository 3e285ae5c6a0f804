"""What every exporter shares: waypoints of a plan, units, times, positions and the commanded
inputs in sailor's words.

A plan's waypoints are the manoeuvre entry points (one per :class:`maps.plan.PlanStep`) plus the
end of the track. The leg *into* waypoint i is the part of the track sailed during step i-1
(RTZ convention: the first waypoint has no leg).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from functools import lru_cache
from typing import Any

import numpy as np

from maps.plan import Plan, PlanStep
from primitives.errors import UserError

M_PER_NM = 1852.0
KN_PER_MPS = 3600.0 / M_PER_NM
TOOL = "shiptrial"
# the marks by which an export knows its own RTZ and HTML card (maps.export.ownership): written and read from here
RTZ_EXT_NS = f"urn:{TOOL}:rtz-trial:1"
HTML_GENERATOR_META = f"<meta name='generator' content='{TOOL}'>"


class ExportError(UserError):
    """A plan that cannot be exported (the message names the field and the fix)."""


@dataclass
class Waypoint:
    """A route point: id (0-based), name, WGS-84 position, time from start and entry state."""

    id: int
    name: str
    lon: float
    lat: float
    t_s: float
    heading_deg: float
    speed_mps: float
    step: PlanStep | None  # the manoeuvre that starts here (None: end of the trial)
    sample: int  # index into the plan's samples

    @property
    def speed_kn(self) -> float:
        return self.speed_mps * KN_PER_MPS


def check_plan(plan: Plan) -> None:
    """Raise :class:`ExportError` when the plan's arrays cannot describe a track."""
    k = len(plan.t)
    if k < 2:
        raise ExportError("plan has fewer than 2 samples in 'samples.t': re-create the plan with plan-trial")
    for name, arr in (("track", plan.track), ("lonlat", plan.lonlat), ("speed", plan.speed), ("step", plan.step_of_sample)):
        if len(arr) != k:
            raise ExportError(f"plan field 'samples.{name}' has {len(arr)} rows, 'samples.t' has {k}: re-create the plan")
    if not plan.steps:
        raise ExportError("plan field 'steps' is empty: nothing to sail (was the plan feasible?)")
    if not np.all(np.isfinite(plan.lonlat)):
        raise ExportError("plan field 'samples.lon/lat' has non-finite values: re-create the plan")
    if np.any(np.abs(plan.lonlat[:, 1]) > 90) or np.any(np.abs(plan.lonlat[:, 0]) > 180):
        raise ExportError("plan fields 'samples.lon/lat' are out of range (lon in [-180, 180], lat in [-90, 90])")


def vessel_name(plan: Plan, override: str | None = None) -> str:
    """The ship's name on the exports: ``override`` (``--vessel-name``), else the plan's
    ``vessel_name``, else the profile's display name, else the profile name."""
    if override is not None:
        name = " ".join(str(override).split())
        if not name:
            raise ExportError("--vessel-name is empty: give the ship's name, e.g. --vessel-name 'MT Example'")
        return name
    name = str(getattr(plan, "vessel_name", "") or "").strip()
    if name:
        return name
    try:
        from primitives.ship import builtin_profiles, load_profile

        if plan.ship in builtin_profiles():
            shown = getattr(load_profile(plan.ship), "display_name", "")
            if shown:
                return str(shown)
    except Exception:  # a plan must export without any profile
        pass
    return plan.ship


def step_slice(plan: Plan, step: PlanStep) -> slice:
    """Samples of ``step``: from its entry to the next step's entry (inclusive of that sample)."""
    idx = np.flatnonzero(plan.step_of_sample == step.index)
    if len(idx) == 0:
        a = int(np.searchsorted(plan.t, plan.t[0] + step.start_time_s))
        b = int(np.searchsorted(plan.t, plan.t[0] + step.start_time_s + step.duration_s))
        return slice(min(a, len(plan.t) - 1), min(max(b, a) + 1, len(plan.t)))
    return slice(int(idx[0]), min(int(idx[-1]) + 2, len(plan.t)))


def waypoints(plan: Plan) -> list[Waypoint]:
    """Manoeuvre entry points in sailing order plus the end of the track."""
    check_plan(plan)
    out = []
    for i, st in enumerate(plan.steps):
        k = step_slice(plan, st).start
        label = f"EXECUTE {st.primitive}" if getattr(st, "execute", False) else st.primitive
        out.append(
            Waypoint(
                i,
                f"WP{i + 1:02d} {label}",
                float(st.entry_lon),
                float(st.entry_lat),
                float(st.start_time_s),
                st.entry_heading_deg,
                float(st.entry_speed_mps),
                st,
                k,
            )
        )
    k = len(plan.t) - 1
    out.append(
        Waypoint(
            len(out),
            f"WP{len(out) + 1:02d} end",
            float(plan.lonlat[k, 0]),
            float(plan.lonlat[k, 1]),
            float(plan.t[k] - plan.t[0]),
            float(np.degrees(plan.track[k, 2]) % 360.0),
            float(plan.speed[k]),
            None,
            k,
        )
    )
    return out


def leg_samples(plan: Plan, wps: list[Waypoint], i: int) -> slice:
    """Samples of the leg into waypoint ``i`` (i >= 1)."""
    return slice(wps[i - 1].sample, wps[i].sample + 1)


def line_offsets(seg: np.ndarray) -> tuple[np.ndarray, float]:
    """Signed starboard offsets (m) of track points ``seg`` (x north, y east) from the line
    seg[0] -> seg[-1], and the line's length; a line whose ends coincide (a turn on the spot)
    gives the distances from its point and length 0."""
    a, b = seg[0], seg[-1]
    d = b - a
    length = float(np.hypot(*d))
    if length < 1e-6:
        return np.hypot(*(seg - a).T), 0.0
    n_stbd = np.array([-d[1], d[0]]) / length  # right of the direction of travel
    return (seg - a) @ n_stbd, length


def cross_track(plan: Plan, wps: list[Waypoint], i: int) -> tuple[float, float]:
    """Largest excursion (starboard, port) in metres of the track from the straight leg into
    waypoint ``i``, measured in the local metric frame of the plan. A leg whose ends coincide
    (e.g. a turn on the spot) is measured around its start point."""
    off, length = line_offsets(plan.track[leg_samples(plan, wps, i), :2])
    if length == 0.0:
        return float(off.max()), float(off.max())
    return float(max(off.max(), 0.0)), float(max(-off.min(), 0.0))


def resolve_start(plan: Plan, start: datetime | str | None) -> datetime:
    """Start time of the trial (UTC): ``start``, else ``plan.stats['start_utc']``, else the next
    full hour from now."""
    if start is None:
        start = plan.stats.get("start_utc") if isinstance(plan.stats, dict) else None
    if start is None:
        now = datetime.now(UTC)
        return now.replace(minute=0, second=0, microsecond=0) + timedelta(hours=1)
    if isinstance(start, str):
        try:
            start = datetime.fromisoformat(start.replace("Z", "+00:00"))
        except ValueError:
            raise ExportError(f"start time {start!r} is not ISO 8601: write e.g. 2026-06-01T08:00Z") from None
    if start.tzinfo is None:
        start = start.replace(tzinfo=UTC)
    return start.astimezone(UTC)


def iso(t: datetime) -> str:
    """ISO 8601 UTC with a Z; milliseconds only when the time has a fraction of a second."""
    t = t.astimezone(UTC)
    if t.microsecond:
        return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def sample_times_iso(plan: Plan, t0: datetime) -> tuple[str, ...]:
    """Every sample's UTC time, :func:`iso` of ``t0`` plus the sample's time from the track's start, as the CSV
    schedule and the GPX track write them: formatted once for both (about 3,600 datetimes for the bundled plan).
    Kept for the last track and start time, keyed on the sample times' bytes rather than on the plan object, so a
    plan changed in place (or a new plan in the same memory) never reads another track's times."""
    return _sample_times_iso(np.asarray(plan.t, dtype=np.float64).tobytes(), t0)


@lru_cache(maxsize=1)
def _sample_times_iso(t_bytes: bytes, t0: datetime) -> tuple[str, ...]:
    t = np.frombuffer(t_bytes, dtype=np.float64)
    return tuple(_iso_after(t0, t - t[0])) if len(t) else ()


def sample_times_iso_at(plan: Plan, t0: datetime, ks: Sequence[int]) -> list[str]:
    """:func:`sample_times_iso` of the samples ``ks`` only (the CSV schedule with ``every`` > 1): the same
    strings, from the same arithmetic, without formatting the samples left out."""
    t = np.asarray(plan.t, dtype=np.float64)
    return _iso_after(t0, (t - t[0])[np.asarray(ks, dtype=np.intp)]) if len(t) else []


def _iso_after(t0: datetime, seconds: np.ndarray) -> list[str]:
    """:func:`iso` of ``t0`` plus each of ``seconds``: the one formatting of both sample-time lists, so that the
    thinned CSV's times stay the strings of the full list's."""
    return [iso(t0 + timedelta(seconds=ts)) for ts in seconds.tolist()]


def clock(t_s: float) -> str:
    """Time from start as h:mm:ss (or m:ss)."""
    s = int(round(t_s))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


def deg_min(value: float, pos: str, neg: str, width: int) -> str:
    """60.12 -> 60°07.200'N (degrees and decimal minutes, as on a chart)."""
    hemi = pos if value >= 0 else neg
    v = abs(value)
    d = int(v)
    m = (v - d) * 60.0
    if round(m, 3) >= 60.0:
        d, m = d + 1, 0.0
    return f"{d:0{width}d}°{m:06.3f}'{hemi}"


def latlon_dm(lat: float, lon: float) -> str:
    return f"{deg_min(lat, 'N', 'S', 2)} {deg_min(lon, 'E', 'W', 3)}"


def _thruster_labels(plan: Plan) -> list[str]:
    """Names of the azimuth thrusters: from the built-in profile of the same name, else numbers."""
    n = sum(1 for nm in plan.input_names if nm.startswith("alpha"))
    try:
        from primitives.ship import PROFILE_DIR, builtin_profiles

        if plan.ship in builtin_profiles():
            names = _builtin_thrusters(plan.ship, (PROFILE_DIR / f"{plan.ship}.toml").read_bytes())
            if len(names) == n:
                return [f"{nm} thruster" for nm in names]
    except Exception:  # a plan must export without any profile
        pass
    return [f"thruster {i}" for i in range(1, n + 1)]


@lru_cache(maxsize=8)
def _builtin_thrusters(ship: str, text: bytes) -> tuple[str, ...]:
    """The thruster names of built-in profile ``ship`` whose file holds ``text`` (the key: its content, not its
    mtime and size, which an edit of the same length within the file system's time granularity leaves equal), read
    once per content: an export asks for them for every order it words (28 times for the default plan's crew files;
    reading the 2 kB file is 30 us, loading the profile 7 ms). A file changed while it was loaded raises (nothing
    cached; the caller numbers the thrusters)."""
    from primitives.ship import PROFILE_DIR, load_profile

    names = tuple(th.name for th in load_profile(ship).thrusters)
    if (PROFILE_DIR / f"{ship}.toml").read_bytes() != text:
        raise RuntimeError(f"profile {ship!r} changed while it was read")
    return names


def _side(angle_deg: float) -> str:
    a = (angle_deg + 180.0) % 360.0 - 180.0
    if abs(a) < 0.5:
        return "ahead (0°)"
    if abs(abs(a) - 180.0) < 0.5:
        return "astern (180°)"
    return f"{abs(a):.0f}° to {'starboard' if a > 0 else 'port'}"


def describe_inputs(plan: Plan, row: np.ndarray) -> str:
    """One input vector in sailor's words: thruster rpm (the plan's rev/s x 60) and the direction it pushes, or the
    generalized forces (tau_x ahead, tau_y to starboard, tau_n turning to starboard)."""
    names = list(plan.input_names)
    sig = dict(zip(names, np.asarray(row, float)))
    if any(n.startswith("alpha") for n in names):
        labels = _thruster_labels(plan)
        parts = []
        for i, lab in enumerate(labels, start=1):
            n, a = 60.0 * sig.get(f"n{i}", 0.0), np.degrees(sig.get(f"alpha{i}", 0.0))  # the plan holds rev/s
            rpm = f"{n:.0f}" if abs(n) >= 10 else f"{n:.1f}"
            parts.append(f"{lab} {rpm} rpm, thrust {_side(a)}" if abs(n) >= 3.0 else f"{lab} stopped")
        return "; ".join(parts)
    if {"tau_x", "tau_y", "tau_n"} <= set(names):
        tx, ty, tn = sig["tau_x"], sig["tau_y"], sig["tau_n"]
        s = [f"thrust {abs(tx):.0f} {'ahead' if tx >= 0 else 'astern'}"]
        s.append(f"side force {abs(ty):.0f} to {'starboard' if ty >= 0 else 'port'}" if abs(ty) >= 0.5 else "no side force")
        s.append(
            f"turning moment {abs(tn):.0f} to {'starboard' if tn >= 0 else 'port'}" if abs(tn) >= 0.5 else "no turning moment"
        )
        return ", ".join(s)
    if "delta" in sig:
        d = np.degrees(sig["delta"])
        rest = ", ".join(f"engine {60 * v:.0f} rpm" if k == "n" else f"{k} {v:.3g}" for k, v in sig.items() if k != "delta")
        rud = "rudder amidships" if abs(d) < 0.5 else f"rudder {abs(d):.0f}° {'starboard' if d > 0 else 'port'}"
        return f"{rud}, {rest}" if rest else rud
    return ", ".join(f"{k} {v:.3g}" for k, v in sig.items())


def _scales(plan: Plan) -> np.ndarray:
    """Change that counts as a new order, per input: 1° for angles, else 10 % of its largest value."""
    out = []
    for j, nm in enumerate(plan.input_names):
        col = plan.inputs[:, j] if plan.inputs.size else np.zeros(1)
        if nm.startswith("alpha") or nm == "delta":
            out.append(np.radians(1.0))
        else:
            out.append(max(0.1 * float(np.max(np.abs(col))), 1e-9))
    return np.asarray(out)


def _phase_mean(plan: Plan, seg: np.ndarray) -> np.ndarray:
    """Mean order of a phase (circular mean for angles)."""
    out = seg.mean(axis=0)
    for j, nm in enumerate(plan.input_names):
        if nm.startswith("alpha") or nm == "delta":
            out[j] = np.arctan2(np.sin(seg[:, j]).mean(), np.cos(seg[:, j]).mean())
    return out


def _angle_range(a: np.ndarray) -> str:
    """Smallest arc holding all angles: -20°..30° or, across astern, 150°..210°."""
    d = np.degrees(np.asarray(a, float))
    d180 = (d + 180.0) % 360.0 - 180.0
    d360 = d % 360.0
    if min(np.ptp(d360), np.ptp(d180)) > 180.0:
        return "turned through all directions"
    if np.ptp(d360) < np.ptp(d180):
        return f"{d360.min():.0f}°..{d360.max():.0f}°"
    return f"{d180.min():.0f}°..{d180.max():.0f}°"


def input_phases(plan: Plan, step: PlanStep, max_phases: int = 6) -> list[str]:
    """The commanded inputs of ``step`` as timed orders ("at +0:40: bow thruster 25 rpm, ...").

    Samples are grouped into phases of nearly constant inputs; phases shorter than 3 samples are
    merged into the one before. A step with more than ``max_phases`` phases is summarised by its
    first order and the range of each input (a closed-loop or continuously varying manoeuvre).
    """
    if plan.inputs.size == 0 or not plan.input_names:
        return []
    sl = step_slice(plan, step)
    u = plan.inputs[sl.start : max(sl.stop - 1, sl.start + 1)]
    t = plan.t[sl.start : sl.start + len(u)] - plan.t[sl.start]
    scale = _scales(plan)
    starts = [0]
    for k in range(1, len(u)):
        if np.any(np.abs(u[k] - u[starts[-1]]) > scale):
            starts.append(k)
    bounds = starts + [len(u)]
    # a phase shorter than 3 samples is a transient: merge it into the phase that follows
    segs = [[a, b] for a, b in zip(bounds[:-1], bounds[1:])]
    merged: list[list[int]] = []
    for seg in segs:
        if merged and merged[-1][1] - merged[-1][0] < 3:
            merged[-1][1] = seg[1]
        else:
            merged.append(seg)
    if len(merged) > 1 and merged[-1][1] - merged[-1][0] < 3:
        merged[-2][1] = merged.pop()[1]
    if len(merged) <= max_phases:
        return [f"at +{clock(t[a])}: {describe_inputs(plan, _phase_mean(plan, u[a:b]))}" for a, b in merged]
    first = f"at +0:00: {describe_inputs(plan, u[0])}"
    rng = []
    for j, nm in enumerate(plan.input_names):
        lo, hi = float(u[:, j].min()), float(u[:, j].max())
        if nm.startswith("alpha") or nm == "delta":
            rng.append(f"{_input_word(plan, nm)} {_angle_range(u[:, j])}")
        elif nm == "n" or (nm.startswith("n") and nm[1:].isdigit()):
            rng.append(f"{_input_word(plan, nm)} {60 * lo:.0f}..{60 * hi:.0f} rpm")
        else:
            rng.append(f"{nm} {lo:.0f}..{hi:.0f}")
    return [first, f"then {len(merged) - 1} changes of order; inputs range " + ", ".join(rng)]


def _input_word(plan: Plan, name: str) -> str:
    """An angle or shaft-speed input as the bridge names it: "rudder", "engine", "bow thruster
    angle", "bow thruster" (thruster names from the profile, as :func:`describe_inputs`)."""
    if name in ("delta", "n"):
        return {"delta": "rudder", "n": "engine"}[name]
    i = int(name[len(name.rstrip("0123456789")) :] or 1) - 1
    labels = _thruster_labels(plan)
    lab = labels[i] if 0 <= i < len(labels) else f"thruster {i + 1}"
    return f"{lab} angle" if name.startswith("alpha") else lab


def order_lines(step: PlanStep) -> list[str]:
    """The step's structured orders (``PlanStep.orders``: {"t_s", "text", ...}) as timed lines
    in the ship's own terms, e.g. "at +0:40: port 20, counter-rudder at 10° port"."""
    out = []
    for o in getattr(step, "orders", None) or []:
        if not isinstance(o, dict) or not o.get("text"):
            continue
        t = o.get("t_s")
        out.append(f"at +{clock(float(t))}: {o['text']}" if isinstance(t, (int, float)) else str(o["text"]))
    return out


def step_abort(plan: Plan, step: PlanStep) -> list[str]:
    """Abort criteria of ``step``: its own (``PlanStep.abort``) plus the plan-wide clearance."""
    own = [re.sub(r"^\s*abort if\s+", "", str(a), flags=re.I) for a in (getattr(step, "abort", None) or [])]
    clearance = f"clearance to land, shallows or any obstacle below {plan.margin_m:.0f} m"
    return own + ([clearance] if not any("clearance" in a for a in own) else [])


def xml_document(root: Any) -> bytes:
    """``ElementTree.tostring(root, encoding="utf-8", xml_declaration=True)``, the same bytes: serialised to text
    and encoded once, where ``tostring`` with an encoding passes each of the tens of thousands of pieces of a
    track's GPX through an encoder of its own (0.05 s of a plan's exports)."""
    import xml.etree.ElementTree as ET

    # xmlcharrefreplace as ElementTree's own writer: a lone surrogate (a command-line word that was not UTF-8, as
    # Python decodes argv) becomes a character reference, not a UnicodeEncodeError
    text = ET.tostring(root, encoding="unicode")
    return b"<?xml version='1.0' encoding='utf-8'?>\n" + text.encode("utf-8", "xmlcharrefreplace")
