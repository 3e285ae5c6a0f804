"""The standard manoeuvres of a profile, run through the project's simulation kernel
(:mod:`primitives.helm`), and their figures: IMO MSC.137(76) turning circle (advance, tactical
diameter), zig-zag first overshoots, stopping."""

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
    reach = float(np.linalg.norm(st.track[-1, :2] - st.track[0, :2]))
    return TrialFigures(tactical, advance, os10, os20, f"{what}: head reach {reach / L:.1f} L ({reach:.0f} m)")


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
    lines.append(f"stopping: {fig.stopping}")
    return lines
