"""The standard manoeuvres of a profile, run through the project's simulation kernel
(:mod:`primitives.helm`), and their figures: IMO MSC.137(76) turning circle (advance, tactical
diameter), zig-zag first overshoots, stopping; and the figures against the IMO Standards for
ship manoeuvrability (resolution MSC.137(76), 2002, section 5.3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primitives import helm as hm
from primitives.library import make_primitive
from primitives.ship import ShipProfile

# what ships do (IMO MSC.137(76) asks tactical diameter <= 5 L and advance <= 4.5 L; a
# tactical diameter under 2 L is beyond what rudder ships reach): outside, the profile is suspect
TACTICAL_RANGE_L = (2.0, 8.0)


@dataclass(frozen=True)
class TrialFigures:
    """Standard-manoeuvre figures of one profile (lengths in ship lengths, angles in degrees).
    None where the manoeuvre did not reach the figure (e.g. the heading never changed 180 deg)."""

    tactical_l: dict[str, float | None]  # by side
    advance_l: dict[str, float | None]
    overshoot_10: dict[str, float | None]  # first overshoot of the 10/10 zig-zag, by first side
    overshoot_20: dict[str, float | None]
    stopping: str  # one line: what the stopping manoeuvre is and its head reach
    stop_track_l: float | None = None  # track reach of a full-astern crash stop [L]; None if no astern

    def warnings(self, length: float) -> list[str]:
        lo, hi = TACTICAL_RANGE_L
        out = []
        for side, td in self.tactical_l.items():
            if td is None:
                out.append(f"the 35 deg turning circle to {side} never turned 180 deg: the profile does not turn like a ship")
            elif not lo <= td <= hi:
                out.append(
                    f"tactical diameter to {side} {td:.1f} L ({td * length:.0f} m) is outside {lo:g}-{hi:g} L, the range ships have; "
                    "check the particulars (rudder area, speed) before planning"
                )
        return out


def turn_figures(track: np.ndarray) -> tuple[float | None, float | None]:
    """(advance, tactical diameter) [m] of a turning circle from a start pose heading psi0: the
    advance along the initial course at 90 deg heading change, the transfer at 180 deg."""
    xy, psi = track[:, :2] - track[0, :2], track[:, 2] - track[0, 2]
    along = np.array([np.cos(track[0, 2]), np.sin(track[0, 2])])
    across = np.array([-along[1], along[0]])
    out = []
    for angle, axis in ((np.pi / 2, along), (np.pi, across)):
        k = int(np.argmax(np.abs(psi) >= angle))
        out.append(abs(float(xy[k] @ axis)) if np.abs(psi[k]) >= angle else None)
    return out[0], out[1]


def first_overshoot(psi: np.ndarray, check_deg: float) -> float | None:
    """Heading overshoot [deg] beyond the check angle after the first rudder reversal."""
    d = np.degrees(psi - psi[0])
    past = np.nonzero(np.abs(d) >= check_deg)[0]
    if not len(past):
        return None
    s = np.sign(d[past[0]])
    k = past[0]
    falling = np.nonzero(np.diff(s * d[k:]) < 0)[0]
    return float(s * d[k + falling[0]] - check_deg) if len(falling) else None


def standard_trials(profile: ShipProfile) -> TrialFigures:
    """Turning circles (35 deg, both sides), 10/10 and 20/20 zig-zags and the stopping manoeuvre of
    the profile as the planner simulates them."""
    L = profile.length_m
    tactical, advance, os10, os20 = {}, {}, {}, {}
    for side in ("starboard", "port"):
        tc = make_primitive(profile, "tc", "turning circle", hm.turning_circle(profile, side=side))
        a, td = turn_figures(tc.track)
        advance[side], tactical[side] = (None if a is None else a / L), (None if td is None else td / L)
        for angle, out in ((10, os10), (20, os20)):
            zz = make_primitive(profile, "zz", "zig-zag", hm.zigzag(profile, angle, angle, first_side=side, n_switches=1))
            out[side] = first_overshoot(zz.track[:, 2], angle)
    gen, what = hm.stopping(profile)
    st = make_primitive(profile, "stop", what, gen)
    xy = st.track[st.split_points[0] if st.split_points else 0 :, :2]  # from the execute point
    reach = float(np.linalg.norm(xy[-1] - xy[0]))
    track = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    crash = what.startswith("crash stop")  # helm.stopping names the full-astern stop so when the engine goes astern
    line = f"{what}: head reach {reach / L:.1f} L ({reach:.0f} m)" + (f", track reach {track / L:.1f} L" if crash else "")
    return TrialFigures(tactical, advance, os10, os20, line, track / L if crash else None)


# IMO MSC.137(76), 5.3: the limits on the standard manoeuvres (lengths in ship lengths)
IMO_TACTICAL_L, IMO_ADVANCE_L, IMO_OVERSHOOT_20, IMO_TRACK_REACH_L, IMO_TRACK_REACH_LARGE_L = 5.0, 4.5, 25.0, 15.0, 20.0


def imo_overshoot_10_limit(l_over_v: float) -> float:
    """First-overshoot limit of the 10/10 zig-zag [deg] (MSC.137(76) 5.3.3.1): 10 deg if L/V < 10 s,
    20 deg if L/V >= 30 s, 5 + (L/V)/2 deg between."""
    return 10.0 if l_over_v < 10.0 else 20.0 if l_over_v >= 30.0 else 5.0 + 0.5 * l_over_v


def imo_warnings(fig: TrialFigures, length: float, speed_mps: float) -> list[str]:
    """One line per IMO MSC.137(76) criterion the simulated manoeuvres miss, "IMO criterion X: ours
    Y, limit Z". The resolution's test speed is 90 % of the speed at 85 % MCR; these manoeuvres are
    sailed from the profile's cruise speed. A coasting stop (no astern) is not the resolution's
    full-astern stopping test and is not checked."""
    out = []

    def over(what: str, ours: float | None, limit: float, unit: str, note: str = "") -> None:
        if ours is not None and ours > limit:
            out.append(f"IMO criterion {what}: ours {ours:.2f} {unit}, limit {limit:g} {unit}{note}")

    for side in ("starboard", "port"):
        over(f"tactical diameter (35 deg turn to {side})", fig.tactical_l.get(side), IMO_TACTICAL_L, "L")
        over(f"advance (35 deg turn to {side})", fig.advance_l.get(side), IMO_ADVANCE_L, "L")
    lim10 = imo_overshoot_10_limit(length / speed_mps)
    for side in ("starboard", "port"):
        over(
            f"10/10 zig-zag first overshoot (first to {side}, L/V {length / speed_mps:.1f} s)",
            fig.overshoot_10.get(side),
            lim10,
            "deg",
        )
        over(f"20/20 zig-zag first overshoot (first to {side})", fig.overshoot_20.get(side), IMO_OVERSHOOT_20, "deg")
    large = f" (an Administration may accept up to {IMO_TRACK_REACH_LARGE_L:g} L for a ship of large displacement)"
    over("stopping track reach (full astern)", fig.stop_track_l, IMO_TRACK_REACH_L, "L",
         large if (fig.stop_track_l or 0.0) <= IMO_TRACK_REACH_LARGE_L else f", and over the {IMO_TRACK_REACH_LARGE_L:g} L allowed for large ships")  # fmt: skip
    return out


def describe(fig: TrialFigures, length: float) -> list[str]:
    """Lines a user reads to sanity-check a new profile."""

    def f(x: float | None, unit: str, scale: float = 1.0) -> str:
        return "not reached" if x is None else f"{x:.2f} {unit}" + (f" ({x * scale:.0f} m)" if scale != 1.0 else "")

    lines = []
    for side in ("starboard", "port"):
        lines.append(
            f"turning circle 35 deg {side}: advance {f(fig.advance_l[side], 'L', length)}, "
            f"tactical diameter {f(fig.tactical_l[side], 'L', length)}"
        )
    for side in ("starboard", "port"):
        lines.append(
            f"zig-zag first overshoot, first to {side}: 10/10 {f(fig.overshoot_10[side], 'deg')}, 20/20 {f(fig.overshoot_20[side], 'deg')}"
        )
    no_astern = "; IMO's stopping criterion (full astern) not checked" if fig.stop_track_l is None else ""
    lines.append(f"stopping: {fig.stopping}{no_astern}")
    return lines
