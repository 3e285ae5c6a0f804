"""Manoeuvres of rudder/propeller ships, generated in helm and engine orders.

The helm gives orders ("Starboard 20", "Port 20 at heading 20° stbd", "Engine 92 rpm"); the
rudder follows at the profile's rudder rate ([helm] rudder_rate_deg_s, max_rudder_deg) and the
shaft at the engine rate ([engine] rps_rate, rps_limits). Heading-switched manoeuvres (zig-zags,
turns, turning circle) run in closed loop on the nominal calm model and are stored as the
open-loop input sequence (delta [rad], n [rev/s]) with the orders that produced it, as the
force-level generators of :mod:`primitives.maneuvers` do for azimuth ships. Standard trials as
in IMO MSC.137(76) and ITTC 7.5-04-02-01: approach steady at the trial speed, execute, record.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from primitives.maneuvers import Generated, model_step, side_sign
from primitives.orders import Order, engine_text, engine_values, heading_words, rate_limited, rudder_text
from primitives.ship import ProfileError, ShipProfile
from primitives.simulate import model_signals


def _surge_increment(profile: ShipProfile, theta: np.ndarray, u: float, n: float) -> float:
    sig = model_signals(profile, np.array([u, 0.0, 0.0]), np.array(0.0), {"delta": 0.0, "n": n})
    return float(profile.model.increments(sig, theta)[0])


def steady_rps(profile: ShipProfile, u: float | None = None) -> float:
    """Propeller rev/s that holds speed ``u`` (default cruise) on a straight course in calm
    water, by bisection on the surge balance of the simulation model within the rps limits."""
    u = profile.cruise_speed_mps if u is None else u
    th = profile.params()
    lo, hi = max(profile.engine.rps_limits[0], 0.0), profile.engine.rps_limits[1]
    if _surge_increment(profile, th, u, hi) < 0:
        raise ProfileError(
            f"profile {profile.name!r}: the model cannot hold {u:.2f} m/s within the engine's {60 * hi:.0f} rpm; "
            "lower cruise_speed_mps or raise engine.rps_limits / input_limits.n"
        )
    if _surge_increment(profile, th, u, lo) >= 0:
        return lo
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _surge_increment(profile, th, u, mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)


def steady_speed(profile: ShipProfile, n_rps: float) -> float:
    """Straight-course speed the model settles at with ``n_rps`` (bisection on the surge balance)."""
    th = profile.params()
    lo, hi = 0.0, 3.0 * profile.cruise_speed_mps
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _surge_increment(profile, th, mid, n_rps) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


class HelmLoop:
    """Closed-loop helm on the calm nominal model: orders in, rate-limited rudder and shaft out.

    An order at sample k changes the command before sample k is applied, the same convention
    :func:`primitives.orders.inputs_from_orders` uses to rebuild the inputs."""

    def __init__(self, profile: ShipProfile, nu0: np.ndarray | tuple[float, float, float], n_rps: float):
        self.p, self.th = profile, profile.params()
        self.ts = profile.sample_time
        self.nu, self.psi, self.k = np.array(nu0, float), 0.0, 0
        self.nu0 = tuple(float(x) for x in nu0)
        self.rudder = self.cmd_rudder = 0.0
        self.shaft = self.cmd_n = float(n_rps)
        self.orders: list[Order] = []
        self.rows: list[tuple[float, float]] = []
        self.splits: list[int] = []

    @property
    def heading_deg(self) -> float:
        """Heading change from the initial course, + starboard."""
        return float(np.degrees(self.psi))

    @property
    def yaw_rate_deg_s(self) -> float:
        return float(np.degrees(self.nu[2]))

    def helm(self, rudder_deg: float, note: str = "", at_heading: bool = False) -> None:
        """Order a rudder angle (+ starboard); ``at_heading`` records the heading it waits for."""
        rudder_deg = float(np.clip(rudder_deg, -self.p.helm.max_rudder_deg, self.p.helm.max_rudder_deg))
        text = rudder_text(rudder_deg, self.p.helm.max_rudder_deg) + (f" ({note})" if note else "")
        vals = {"rudder_deg": rudder_deg}
        if at_heading:
            text += f" at {heading_words(self.heading_deg)}"
            vals["at_heading_change_deg"] = self.heading_deg
        self.orders.append(Order(self.k * self.ts, text, vals))
        self.cmd_rudder = rudder_deg

    def engine(self, n_rps: float, note: str = "") -> None:
        lo, hi = self.p.engine.rps_limits
        n_rps = float(np.clip(n_rps, lo, hi))
        text = engine_text(self.p, n_rps) + (f" ({note})" if note else "")
        self.orders.append(Order(self.k * self.ts, text, engine_values(self.p, n_rps)))
        self.cmd_n = n_rps

    def step(self, m: int = 1) -> None:
        eng = self.p.engine
        dr = self.p.helm.rudder_rate_deg_s * self.ts
        dn = np.inf if eng.rps_rate is None else eng.rps_rate * self.ts
        for _ in range(m):  # builtin min/max: this scalar loop is the generator's hot path
            self.rudder += min(max(self.cmd_rudder - self.rudder, -dr), dr)
            self.shaft += min(max(self.cmd_n - self.shaft, -dn), dn)
            row = (float(self.p.helm.delta_rad(self.rudder)), self.shaft)
            self.nu, self.psi = model_step(self.p, self.th, self.nu, self.psi, {"delta": row[0], "n": row[1]})
            self.rows.append(row)
            self.k += 1

    def generated(self) -> Generated:
        inputs = np.array(self.rows, float).reshape(-1, 2)
        return Generated(None, self.nu0, list(self.splits), inputs=inputs, orders=list(self.orders))


REGAIN_TOL = 0.01  # share of the approach speed below it at which a regained speed counts as regained
HELM_DEG = 10.0  # rudder that brings the ship back to the initial course, and meets her swing
SWING_DEG_S = 0.02  # a yaw rate below it is steady
ON_COURSE_DEG = 1.0  # a heading within it of the initial course is on it


def regain_speed(loop: HelmLoop, n_rps: float, u: float, course: float | None = 0.0) -> None:
    """Back on the initial course with the engine full ahead, then the approach rpm ``n_rps`` once
    the speed is within ``REGAIN_TOL`` of ``u``: how a master regains speed and course after a
    manoeuvre in confined water, rather than waiting for the approach rpm to bring the speed
    back (and a course-unstable hull left midships keeps turning). The helm in whole orders:
    rudder towards the initial course, counter-rudder ("meet her") when the swing would carry the
    ship onto it within two ship lengths' sailing, midships ("steady") once the swing is met
    (``course``: the heading change from the initial course to steer onto, deg; None: the swing
    met on whatever heading she has)."""
    p = loop.p
    lead = 2.0 * p.length_m / max(u, 1e-6)
    loop.helm(0.0, "midships")
    if loop.nu[0] < (1 - REGAIN_TOL) * u:
        loop.engine(p.engine.rps_limits[1], "full ahead: regain speed")
    n_max = loop.k + _lengths(p, u, 60)
    phase = "steady"
    while loop.k < n_max:
        h, r = loop.heading_deg - (course or 0.0), loop.yaw_rate_deg_s
        slow = loop.nu[0] < (1 - REGAIN_TOL) * u
        if course is None:  # any heading will do: meet the swing where she is
            h = 0.0
        onto = (h + r * lead) * h <= 0  # the swing carries her onto the course within the lead
        if phase != "meet" and abs(r) >= SWING_DEG_S and onto:
            phase = "meet"
            loop.helm(-np.sign(r) * HELM_DEG, "meet her")
        elif phase == "meet" and abs(r) < SWING_DEG_S:
            phase = "steady"
            loop.helm(0.0, "steady, midships")
        elif phase == "steady" and abs(h) > ON_COURSE_DEG and not onto:
            phase = "return"
            loop.helm(-np.sign(h) * HELM_DEG, "back to the initial course")
        elif phase == "steady" and abs(h) <= ON_COURSE_DEG and abs(r) < SWING_DEG_S and not slow:
            break
        if not slow and loop.cmd_n != n_rps:
            loop.engine(n_rps, "back to approach rpm")
        loop.step()
    if loop.cmd_n != n_rps:
        loop.engine(n_rps, "back to approach rpm")
    loop.step()


def _approach(profile: ShipProfile, n_rps: float | None) -> tuple[float, float]:
    """(rps, steady speed) of the approach: cruise speed by default."""
    if n_rps is None:
        return steady_rps(profile), profile.cruise_speed_mps
    return n_rps, steady_speed(profile, n_rps)


def _lengths(profile: ShipProfile, u: float, n_lengths: float) -> int:
    """Samples to sail ``n_lengths`` ship lengths at speed u."""
    return max(1, int(n_lengths * profile.length_m / max(u, 0.1 * profile.cruise_speed_mps) / profile.sample_time))


def zigzag(
    profile: ShipProfile,
    delta_deg: float,
    psi_deg: float,
    *,
    first_side: str = "starboard",
    n_switches: int = 4,
    n_rps: float | None = None,
    regain: bool = False,
) -> Generated:
    """Zig-zag delta/psi (IMO): rudder to one side, counter-rudder each time the heading change
    passes psi; ends at the heading after ``n_switches`` rudder reversals (``regain``: then
    :func:`regain_speed`)."""
    n, u = _approach(profile, n_rps)
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    s = side_sign(first_side)
    loop.engine(n, "approach, hold")
    loop.helm(s * delta_deg, "execute")
    n_max = _lengths(profile, u, 60)
    while loop.k < n_max:
        if s * loop.heading_deg >= psi_deg:
            if len(loop.splits) == n_switches:
                break
            s = -s
            loop.splits.append(loop.k)
            loop.helm(s * delta_deg, at_heading=True)
        loop.step()
    if regain:
        regain_speed(loop, n, u, course=None)
    return loop.generated()


def turning_circle(
    profile: ShipProfile,
    delta_deg: float | None = None,
    *,
    side: str = "starboard",
    turns: float = 1.0,
    n_rps: float | None = None,
    regain: bool = False,
) -> Generated:
    """Turning circle: full (or ``delta_deg``) rudder held until the heading has changed 360 deg x
    turns (``regain``: the rudder eased two ship lengths' sailing before, then
    :func:`regain_speed` onto that heading change)."""
    n, u = _approach(profile, n_rps)
    delta = profile.helm.max_rudder_deg if delta_deg is None else delta_deg
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    loop.engine(n, "approach, hold")
    loop.helm(side_sign(side) * delta, "execute, hold")
    n_max = _lengths(profile, u, 200)
    lead = 2.0 * profile.length_m / u if regain else 0.0
    while loop.k < n_max and abs(loop.heading_deg) + lead * abs(loop.yaw_rate_deg_s) < 360.0 * turns:
        loop.step()
    k = loop.k
    loop.splits = [k // 4, k // 2, 3 * k // 4]
    if regain:
        regain_speed(loop, n, u, course=side_sign(side) * 360.0 * turns)
    return loop.generated()


def pull_out(profile: ShipProfile, delta_deg: float = 20.0, *, side: str = "starboard", n_rps: float | None = None) -> Generated:
    """Pull-out: rudder ``delta_deg`` until the yaw rate is steady (or a full turn), then midships
    and record how the yaw rate decays (or settles, for a course-unstable ship)."""
    n, u = _approach(profile, n_rps)
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    loop.engine(n, "approach, hold")
    loop.helm(side_sign(side) * delta_deg, "execute")
    window, n_max = _lengths(profile, u, 1.0), _lengths(profile, u, 40)
    hist: list[float] = []
    while loop.k < n_max and abs(loop.heading_deg) < 360.0:
        loop.step()
        hist.append(loop.yaw_rate_deg_s)
        if len(hist) > window and abs(hist[-1] - hist[-1 - window]) < 0.02 * abs(hist[-1]):
            break
    loop.splits.append(loop.k)
    loop.helm(0.0, "hold; record the yaw-rate decay")
    loop.step(max(loop.k, _lengths(profile, u, 10)))
    return loop.generated()


DIEUDONNE_STEPS = (15.0, 10.0, 5.0, 2.0, 0.0, -2.0, -5.0, -10.0, -15.0, -10.0, -5.0, -2.0, 0.0, 2.0, 5.0, 10.0, 15.0)


def direct_spiral(
    profile: ShipProfile,
    steps_deg: tuple[float, ...] = DIEUDONNE_STEPS,
    *,
    hold_lengths: float = 5.0,
    n_rps: float | None = None,
    regain: bool = False,
) -> Generated:
    """Direct (Dieudonne) spiral: rudder steps (+ starboard), each held ``hold_lengths`` ship
    lengths for the yaw rate to settle; the engine setting is left unchanged (ITTC)
    (``regain``: then :func:`regain_speed`)."""
    n, u = _approach(profile, n_rps)
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    loop.engine(n, "approach, leave unchanged")
    m = _lengths(profile, u, hold_lengths)
    for i, d in enumerate(steps_deg):
        if i:
            loop.splits.append(loop.k)
        loop.helm(d, f"hold {m * profile.sample_time:.0f} s")
        loop.step(m)
    if regain:
        regain_speed(loop, n, u)
    return loop.generated()


def speed_change(
    profile: ShipProfile,
    rps_from: float,
    rps_to: float,
    *,
    until_speed: float | None = None,
    max_lengths: float = 40.0,
    regain: bool = False,
) -> Generated:
    """Engine step from steady ``rps_from`` to ``rps_to`` with the rudder midships: an
    acceleration or a deceleration, run until the speed is within 2 % of the change from its
    new steady value (or ``until_speed`` is passed, or ``max_lengths`` ship lengths);
    ``regain``: then back to the approach speed by :func:`regain_speed`."""
    u0 = steady_speed(profile, rps_from)
    u1 = steady_speed(profile, rps_to) if until_speed is None else until_speed
    loop = HelmLoop(profile, (u0, 0.0, 0.0), rps_from)
    loop.engine(rps_from, "approach, steady")
    loop.helm(0.0, "hold course")
    loop.step(_lengths(profile, u0, 1.0))  # a recorded steady stretch before the execute point
    loop.splits.append(loop.k)
    loop.engine(rps_to, "execute")
    n_max = loop.k + _lengths(profile, max(u0, u1), max_lengths)
    tol = 0.02 * abs(u1 - u0)
    while loop.k < n_max:
        loop.step()
        if (until_speed is not None and (loop.nu[0] - u1) * np.sign(u0 - u1) <= 0) or (
            until_speed is None and abs(loop.nu[0] - u1) < tol
        ):
            break
    if regain:
        regain_speed(loop, steady_rps(profile), profile.cruise_speed_mps)
    return loop.generated()


def has_astern(profile: ShipProfile) -> bool:
    """Whether the engine goes astern (rps_limits below 0, e.g. from [engine] astern_rpm) and the
    model's thrust reverses with it (a ship at rest gathers sternway; the stopping manoeuvre is then
    a full-astern crash stop)."""
    lo = profile.engine.rps_limits[0]
    return bool(lo < 0 and _surge_increment(profile, profile.params(), 0.0, lo) < 0)


def stopping(profile: ShipProfile) -> tuple[Generated, str]:
    """Stopping from cruise speed within what the engine allows: full astern until stopped when
    the engine goes astern (:func:`has_astern`); otherwise engine stop, coasting until the speed
    has halved. Returns the manoeuvre and its description."""
    n0 = steady_rps(profile)
    lo = profile.engine.rps_limits[0]
    if has_astern(profile):
        return speed_change(profile, n0, lo, until_speed=0.0), "crash stop: full astern from cruise speed until stopped"
    return (
        speed_change(profile, n0, 0.0, until_speed=0.5 * profile.cruise_speed_mps),
        "engine stop from cruise speed, coasting to half speed (the profile's engine has no astern)",
    )


def straight(profile: ShipProfile, distance_m: float, n_rps: float | None = None) -> Generated:
    """Straight run, rudder midships, engine at the approach setting."""
    n, u = _approach(profile, n_rps)
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    loop.engine(n, "hold")
    loop.helm(0.0, f"steady course for {distance_m:.0f} m")
    loop.step(max(1, int(round(distance_m / (u * profile.sample_time)))))
    return loop.generated()


def _turn_run(profile: ShipProfile, dpsi_deg: float, rudder_deg: float, lead_deg: float, n: float, u: float) -> HelmLoop:
    s = float(np.sign(dpsi_deg))
    loop = HelmLoop(profile, (u, 0.0, 0.0), n)
    loop.engine(n, "hold")
    loop.helm(s * rudder_deg, "execute")
    n_max = _lengths(profile, u, 40)
    while loop.k < n_max and s * loop.heading_deg < abs(dpsi_deg) - lead_deg:
        loop.step()
    r_peak = max(s * loop.yaw_rate_deg_s, 1e-6)
    loop.helm(-s * rudder_deg / 2, "counter-rudder", at_heading=True)
    while loop.k < n_max and s * loop.yaw_rate_deg_s > 0.05 * r_peak and s * loop.heading_deg < abs(dpsi_deg):
        loop.step()
    loop.helm(0.0, "steady on the new course", at_heading=True)
    loop.step(_lengths(profile, u, 0.5))
    return loop


def turn(profile: ShipProfile, dpsi_deg: float, *, rudder_deg: float = 20.0, n_rps: float | None = None) -> Generated:
    """Course change by ``dpsi_deg`` (+ starboard) at approach speed: rudder, counter-rudder at a
    heading chosen (by bisection on the nominal model) so that the ship steadies on the new
    course, then midships."""
    n, u = _approach(profile, n_rps)
    lo, hi = 0.0, abs(dpsi_deg)
    best = None
    for _ in range(10):
        lead = 0.5 * (lo + hi)
        loop = _turn_run(profile, dpsi_deg, rudder_deg, lead, n, u)
        err = abs(loop.heading_deg) - abs(dpsi_deg)
        if best is None or abs(err) < best[0]:
            best = (abs(err), loop)
        lo, hi = (lead, hi) if err > 0 else (lo, lead)
    return best[1].generated()


def validation_inputs(profile: ShipProfile, multisine: Callable[[int], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A cross-validation input unlike any manoeuvre, in helm terms: a multisine rudder within
    60 % of full rudder (moved at the rudder rate) and a multisine rpm within 70-100 % of the
    approach rpm. ``multisine(k)`` is the caller's seeded sum of k sines scaled to [-1, 1] (one
    per sample). Returns (inputs (n, 2), nu0 (3,)), starting steady at the first rpm."""
    helm = profile.helm
    rudder = rate_limited(0.6 * helm.max_rudder_deg * multisine(3), 0.0, helm.rudder_rate_deg_s * profile.sample_time)
    n0 = steady_rps(profile)
    rps = np.clip(n0 * (0.85 + 0.15 * multisine(2)), *profile.engine.rps_limits)
    return np.column_stack([helm.delta_rad(rudder), rps]), np.array([steady_speed(profile, rps[0]), 0.0, 0.0])
