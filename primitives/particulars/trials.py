"""The standard manoeuvres of a profile, run through the project's simulation kernel
(:mod:`primitives.helm`), and their figures: IMO MSC.137(76) turning circle (advance, tactical
diameter), initial turning, zig-zag first and second overshoots, stopping; and the figures
against the IMO Standards for ship manoeuvrability (resolution MSC.137(76), 2002, section 5.3)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from primitives import helm as hm
from primitives.library import make_primitive
from primitives.maneuvers import MAX_RUDDER_DEG, model_step
from primitives.particulars.document import RUDDER_RATE_DEG_S
from primitives.particulars.fit import straight_inputs
from primitives.particulars.mmg import fixed_helm, run, zigzag_helm
from primitives.ship import ShipProfile
from primitives.simulate import model_signals

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
    second_overshoot_10: dict[str, float | None] = field(default_factory=dict)  # 10/10, by first side
    initial_turn_l: dict[str, float | None] = field(default_factory=dict)  # track to 10 deg heading, 10 deg rudder

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


def zigzag_overshoots(psi: np.ndarray, check_deg: float) -> list[float]:
    """Overshoot angles [deg] of a zig-zag: the heading's peak beyond the check angle after each
    rudder reversal (IMO MSC.137(76), 4.2.4), as many as the record holds."""
    d = np.degrees(psi - psi[0])
    s = np.sign(d[int(np.argmax(np.abs(d) > check_deg))])
    out, k = [], 0
    while True:
        past = np.nonzero(s * d[k:] >= check_deg)[0]
        if not len(past):
            return out
        k += int(past[0])
        falling = np.nonzero(np.diff(s * d[k:]) < 0)[0]
        if not len(falling):
            return out
        k += int(falling[0])
        out.append(float(s * d[k] - check_deg))
        s = -s


def initial_turn(track: np.ndarray, heading_deg: float = 10.0) -> float | None:
    """Track sailed [m] from the execute (the first sample) until the heading has changed by
    ``heading_deg`` (IMO MSC.137(76), 5.3.2 initial turning ability); None if it never does."""
    past = np.nonzero(np.abs(np.degrees(track[:, 2] - track[0, 2])) >= heading_deg)[0]
    if not len(past):
        return None
    return float(np.sum(np.linalg.norm(np.diff(track[: past[0] + 1, :2], axis=0), axis=1)))


def _nth(values: list[float], k: int) -> float | None:
    return values[k] if len(values) > k else None


def standard_trials(profile: ShipProfile) -> TrialFigures:
    """Turning circles (35 deg, both sides), 10/10 (two reversals) and 20/20 zig-zags and the
    stopping manoeuvre of the profile as the planner simulates them (a podded ship's: both pods
    steered as one rudder, :func:`pod_trials`)."""
    if profile.actuator == "azimuth":
        return pod_trials(profile)
    L = profile.length_m
    tactical, advance, os10, os20, os10b, initial = {}, {}, {}, {}, {}, {}
    for side in ("starboard", "port"):
        tc = make_primitive(profile, "tc", "turning circle", hm.turning_circle(profile, side=side))
        a, td = turn_figures(tc.track)
        advance[side], tactical[side] = (None if a is None else a / L), (None if td is None else td / L)
        zz10 = make_primitive(profile, "zz", "zig-zag", hm.zigzag(profile, 10, 10, first_side=side, n_switches=2))
        ovs = zigzag_overshoots(zz10.track[:, 2], 10)
        os10[side], os10b[side] = _nth(ovs, 0), _nth(ovs, 1)
        it = initial_turn(zz10.track)
        initial[side] = None if it is None else it / L
        zz20 = make_primitive(profile, "zz", "zig-zag", hm.zigzag(profile, 20, 20, first_side=side, n_switches=1))
        os20[side] = _nth(zigzag_overshoots(zz20.track[:, 2], 20), 0)
    gen, what = hm.stopping(profile)
    st = make_primitive(profile, "stop", what, gen)
    xy = st.track[st.split_points[0] if st.split_points else 0 :, :2]  # from the execute point
    reach = float(np.linalg.norm(xy[-1] - xy[0]))
    track = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    crash = hm.has_astern(profile)  # the stop is then full astern (helm.stopping)
    line = f"{what}: head reach {reach / L:.1f} L ({reach:.0f} m)" + (f", track reach {track / L:.1f} L" if crash else "")
    if crash and st.nu[-1, 0] > 0.01 * profile.cruise_speed_mps:  # helm.speed_change gave up at its length cap
        line += f" (not stopped: still {st.nu[-1, 0]:.1f} m/s at the end; the reaches are lower bounds)"
    return TrialFigures(tactical, advance, os10, os20, line, track / L if crash else None, os10b, initial)


# IMO MSC.137(76), 5.3: the limits on the standard manoeuvres (lengths in ship lengths)
IMO_TACTICAL_L, IMO_ADVANCE_L, IMO_OVERSHOOT_20, IMO_TRACK_REACH_L, IMO_TRACK_REACH_LARGE_L = 5.0, 4.5, 25.0, 15.0, 20.0
IMO_INITIAL_TURN_L = 2.5  # 5.3.2: track sailed by 10 deg of heading change with 10 deg rudder
IMO_MIN_LENGTH_M = 100.0  # 1.2: ships of 100 m and over (and chemical and gas carriers of any length)


def imo_overshoot_10_limit(l_over_v: float) -> float:
    """First-overshoot limit of the 10/10 zig-zag [deg] (MSC.137(76) 5.3.3.1): 10 deg if L/V < 10 s,
    20 deg if L/V >= 30 s, 5 + (L/V)/2 deg between."""
    return 10.0 if l_over_v < 10.0 else 20.0 if l_over_v >= 30.0 else 5.0 + 0.5 * l_over_v


def imo_second_overshoot_10_limit(l_over_v: float) -> float:
    """Second-overshoot limit of the 10/10 zig-zag [deg] (MSC.137(76) 5.3.3.2): 25 deg if L/V < 10 s,
    40 deg if L/V >= 30 s, 17.5 + 0.75 L/V deg between."""
    return 25.0 if l_over_v < 10.0 else 40.0 if l_over_v >= 30.0 else 17.5 + 0.75 * l_over_v


def imo_warnings(fig: TrialFigures, length: float, speed_mps: float) -> list[str]:
    """One line per IMO MSC.137(76) 5.3 criterion the simulated manoeuvres miss, "IMO criterion X:
    ours Y, limit Z", or cannot be checked because the manoeuvre never reached its figure. The
    resolution's test speed is 90 % of the speed at 85 % MCR; these manoeuvres are sailed from the
    profile's cruise speed (``speed_mps`` > 0). A coasting stop (no astern) is not the resolution's
    full-astern stopping test and is not checked (``fig.stop_track_l`` None). The resolution applies
    to ships of 100 m and over (and to chemical and gas carriers of any length): for a shorter ship
    each line says it is shown for reference."""
    if speed_mps <= 0:
        raise ValueError(f"speed_mps {speed_mps}: the manoeuvres' approach speed must be positive")
    out = []
    scope = (
        ""
        if length >= IMO_MIN_LENGTH_M
        else f" (MSC.137(76) applies to ships of {IMO_MIN_LENGTH_M:g} m and over; shown for reference)"
    )

    def over(what: str, ours: float | None, limit: float, unit: str, note: str = "") -> None:
        if ours is None:
            out.append(f"IMO criterion {what}: not reached, cannot be checked{scope}")
        elif ours > limit:
            out.append(f"IMO criterion {what}: ours {ours:.2f} {unit}, limit {limit:.3g} {unit}{note}{scope}")

    l_v = length / speed_mps
    for side in ("starboard", "port"):
        over(f"tactical diameter (35 deg turn to {side})", fig.tactical_l.get(side), IMO_TACTICAL_L, "L")
        over(f"advance (35 deg turn to {side})", fig.advance_l.get(side), IMO_ADVANCE_L, "L")
    for side in ("starboard", "port"):
        if side in fig.initial_turn_l:
            over(
                f"initial turning (10 deg rudder to {side}, track to 10 deg heading)",
                fig.initial_turn_l[side],
                IMO_INITIAL_TURN_L,
                "L",
            )
        over(
            f"10/10 zig-zag first overshoot (first to {side}, L/V {l_v:.1f} s)",
            fig.overshoot_10.get(side),
            imo_overshoot_10_limit(l_v),
            "deg",
        )
        if side in fig.second_overshoot_10:
            over(
                f"10/10 zig-zag second overshoot (first to {side}, L/V {l_v:.1f} s)",
                fig.second_overshoot_10[side],
                imo_second_overshoot_10_limit(l_v),
                "deg",
            )
        over(f"20/20 zig-zag first overshoot (first to {side})", fig.overshoot_20.get(side), IMO_OVERSHOOT_20, "deg")
    if fig.stop_track_l is not None:
        beyond = fig.stop_track_l > IMO_TRACK_REACH_LARGE_L
        note = (
            f", and over the {IMO_TRACK_REACH_LARGE_L:g} L allowed for large ships"
            if beyond
            else f" (an Administration may accept up to {IMO_TRACK_REACH_LARGE_L:g} L for a ship of large displacement)"
        )
        over("stopping track reach (full astern)", fig.stop_track_l, IMO_TRACK_REACH_L, "L", note)
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
            f"zig-zag overshoots, first to {side}: 10/10 first {f(fig.overshoot_10[side], 'deg')}, "
            f"second {f(fig.second_overshoot_10.get(side), 'deg')}; 20/20 first {f(fig.overshoot_20[side], 'deg')}; "
            f"initial turning (10 deg rudder) {f(fig.initial_turn_l.get(side), 'L', length)} to 10 deg heading"
        )
    no_astern = (
        "; the engine has no astern, so IMO's stopping criterion (full-astern track reach) is not checked"
        if fig.stop_track_l is None
        else ""
    )
    lines.append(f"stopping: {fig.stopping}{no_astern}")
    return lines


class _PodHelm:
    """A podded profile sailed through the project's kernel as a rudder ship: both pods at the
    steering angle (``delta`` + turns to starboard, so alpha = -delta), both shafts at ``n``; the
    interface :func:`primitives.particulars.mmg.run` steers (``step``, ``input_row``)."""

    def __init__(self, profile: ShipProfile):
        self.profile, self.theta = profile, profile.params()

    def input_row(self, delta: float, n: float) -> tuple[float, ...]:
        return tuple(x for _ in self.profile.thrusters for x in (n, -delta))

    def step(self, nu: np.ndarray, delta: float, n: float, dt: float) -> np.ndarray:
        sig = self.profile.generalized_forces(np.array(self.input_row(delta, n)))
        return model_step(self.profile, self.theta, nu, 0.0, {k: float(v) for k, v in sig.items()})[0]


def pod_trials(profile: ShipProfile) -> TrialFigures:
    """The standard manoeuvres of a podded (azimuth) profile, both pods steered together to the IMO
    rudder angles at the SOLAS steering rate (2.32 deg/s; IMO MSC.137(76) leaves comparative angles
    for pods to the Administration), both shafts at the rpm that holds the cruise speed; the stop
    is both shafts stopped, coasting to half speed (a built pod ship is given no astern)."""
    L, u0, ts = profile.length_m, profile.cruise_speed_mps, profile.sample_time
    ship = _PodHelm(profile)
    n0 = fit_steady_rps(profile)
    lengths = L / u0 / ts
    rate, dmax = np.radians(RUDDER_RATE_DEG_S), np.radians(MAX_RUDDER_DEG)

    def go(helm, n_lengths: float):
        r = run(ship, "pod trial", helm, u0, int(n_lengths * lengths), ts, rate, dmax)
        return np.c_[r.xy, r.psi], r

    tactical, advance, os10, os20, os10b, initial = {}, {}, {}, {}, {}, {}
    for side, s in (("starboard", 1.0), ("port", -1.0)):
        a, td = turn_figures(go(fixed_helm(s * dmax, n0), 25)[0])
        advance[side], tactical[side] = (None if a is None else a / L), (None if td is None else td / L)
        track = go(zigzag_helm(np.radians(10), s, n0), 14)[0]
        ovs = zigzag_overshoots(track[:, 2], 10)
        os10[side], os10b[side] = _nth(ovs, 0), _nth(ovs, 1)
        it = initial_turn(track)
        initial[side] = None if it is None else it / L
        os20[side] = _nth(zigzag_overshoots(go(zigzag_helm(np.radians(20), s, n0), 10)[0][:, 2], 20), 0)
    track, r = go(fixed_helm(0.0, 0.0), 40)
    slow = r.nu[:, 0] <= 0.5 * u0
    if np.any(slow):
        reach = float(np.linalg.norm(track[int(np.argmax(slow)), :2] - track[0, :2]))
        line = f"both shafts stopped from cruise speed, coasting to half speed (no astern given): head reach {reach / L:.1f} L ({reach:.0f} m)"
    else:  # not a reach to half speed: say so rather than print the end of the run as one
        line = "both shafts stopped from cruise speed (no astern given): not yet at half speed after 40 L"
    return TrialFigures(tactical, advance, os10, os20, line, None, os10b, initial)


def fit_steady_rps(profile: ShipProfile) -> float:
    """Shaft speed [rev/s] on both pods that holds the cruise speed straight ahead (bisection on the
    surge increment within the input limits)."""
    th, u = profile.params(), profile.cruise_speed_mps
    lo, hi = 0.0, profile.input_limits["n1"][1]

    def surge(n: float) -> float:
        sig = model_signals(profile, np.array([u, 0.0, 0.0]), np.array(0.0), straight_inputs(profile, n))
        return float(profile.model.increments(sig, th)[0])

    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if surge(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)
