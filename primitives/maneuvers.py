"""Input-signal generators of manoeuvre primitives.

Generators work in generalized forces (tau_x, tau_y, tau_n) and the profile allocates them to
its actuators (for azimuth thrusters via (3.55)). Heading-switched manoeuvres (zig-zag,
turning circle, pull-out, spirals, turns to a heading) are generated in closed loop on the
nominal undisturbed model and then stored as open-loop input sequences: the sequence is what
the information matrix and the planner see; the switching logic is what the crew is told.

For generalized-force profiles the yaw force plays the rudder: ``rudder_force`` maps a rudder
angle to a yaw force with 35 deg giving a steady turn of diameter 3 L at cruise speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from primitives.ship import ShipProfile
from primitives.simulate import VelocityStep
from primitives.steady_forces import steady_forces

MAX_RUDDER_DEG = 35.0


@dataclass
class Generated:
    """Input sequence of a manoeuvre and facts the library and the trial card need.

    Either ``forces`` (N, 3) generalized forces that the profile allocates to its actuators,
    or ``inputs`` (N, m) in the profile's own input units (rudder ships, see primitives.helm)
    together with the ``orders`` that produced them. ``heading_switched``: the split points are
    where the helm reverses at a heading, so their orders are given at that heading.
    """

    forces: np.ndarray | None  # (N, 3) generalized forces
    nu0: tuple[float, float, float]
    split_points: list[int] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)  # legacy one-liners; primitives render their orders
    inputs: np.ndarray | None = None
    orders: list = field(default_factory=list)
    heading_switched: bool = False


Policy = Callable[[int, np.ndarray, float, dict], tuple[float, float, float] | None]


def closed_loop(
    profile: ShipProfile,
    policy: Policy,
    n_max: int,
    nu0: np.ndarray | tuple[float, float, float],
    theta: np.ndarray | str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``policy(k, nu, psi, memo) -> forces or None (stop)`` on the calm model.

    Returns (forces (N, 3), psi (N+1,)). Scalar loop: used only to generate signals.
    """
    th = profile.params(theta)
    act = Actuators.of(profile)
    nu, psi, memo = np.array(nu0, float), 0.0, {}
    forces, psis = [], [0.0]
    for k in range(n_max):
        f = policy(k, nu, psi, memo)
        if f is None:
            break
        f = act.feasible(f)
        nu, psi = model_step(profile, th, nu, psi, {"tau_x": f[0], "tau_y": f[1], "tau_n": f[2]})
        forces.append(f)
        psis.append(psi)
    return np.array(forces, float).reshape(-1, 3), np.array(psis)


# thrusters within this fraction of a length of one another along the hull act at one lever arm: two pods aft
# cannot push the stern sideways without turning the ship, so sway and yaw are not commanded apart
POD_SPREAD_L = 0.1


def pod_arm(profile: ShipProfile) -> float | None:
    """The thrusters' common x (m) when an azimuth ship's thrusters all sit within
    :data:`POD_SPREAD_L` of a length of one another, away from midships (pods aft), else None
    (thrusters fore and aft: sway and yaw can be commanded apart). With one lever arm x_T the side force and the yaw moment
    are tied, tau_n = x_T tau_y + sum_i -y_i F_x,i (Ljungberg 2022, eq. 3.55); the pods give a yaw moment apart from
    the side force only through unequal thrust, a lever of y_i (a quarter beam)."""
    if profile.actuator != "azimuth" or not profile.thrusters:
        return None
    xs = [float(t.x) for t in profile.thrusters]
    if max(xs) - min(xs) > POD_SPREAD_L * profile.length_m or abs(float(np.mean(xs))) < POD_SPREAD_L * profile.length_m:
        return None
    return float(np.mean(xs))


class Actuators:
    """What the actuators give for a requested generalized force, one sample at a time: the
    scalar hot path of every closed-loop generator. The allocation matrix's pseudo-inverse is
    formed once per profile (not once per step), with the same arithmetic as
    ``ShipProfile.allocate`` / ``clip_inputs`` / ``generalized_forces`` (3.55)."""

    _cache: dict[int, tuple[ShipProfile, Actuators]] = {}

    def __init__(self, profile: ShipProfile):
        self.p = profile
        self.azimuth = profile.actuator == "azimuth" and bool(profile.input_limits)
        if self.azimuth:
            th = profile.thrusters
            b_mat = np.array(
                [np.ravel([[1.0, 0.0] for _ in th]), np.ravel([[0.0, 1.0] for _ in th]), np.ravel([[-t.y, t.x] for t in th])]
            )
            self.pinv = np.linalg.pinv(b_mat)
            big = (-np.inf, np.inf)
            self.lim = [
                (profile.input_limits.get(f"n{i}", big), profile.input_limits.get(f"alpha{i}", big))
                for i in range(1, len(th) + 1)
            ]
            self.arm = [(t.x, t.y) for t in th]
            self.order = [profile.inputs.index(f"{k}{i}") for i in range(1, len(th) + 1) for k in ("n", "alpha")]

    @classmethod
    def of(cls, profile: ShipProfile) -> Actuators:
        hit = cls._cache.get(id(profile))
        if hit is None or hit[0] is not profile:
            hit = cls._cache[id(profile)] = (profile, cls(profile))
        return hit[1]

    def feasible(self, f: tuple[float, float, float] | np.ndarray) -> tuple[float, float, float]:
        if not self.azimuth:
            return feasible(self.p, f)
        comp = (self.pinv @ np.array([[f[0]], [f[1]], [f[2]]], float))[:, 0].tolist()  # the (4, 1) product allocate() forms
        tx = ty = tn = 0.0
        for i, ((n_lim, a_lim), (x, y)) in enumerate(zip(self.lim, self.arm)):
            fx, fy = comp[2 * i], comp[2 * i + 1]
            n = min(max(math.hypot(fx, fy), n_lim[0]), n_lim[1])  # np.clip(np.hypot(...)) on one value
            a = min(max(math.atan2(fy, fx), a_lim[0]), a_lim[1])
            c, s = np.cos(a), np.sin(a)
            tx, ty, tn = tx + n * c, ty + n * s, tn + n * (x * s - y * c)
        return float(tx), float(ty), float(tn)


def feasible(profile: ShipProfile, f: tuple[float, float, float] | np.ndarray) -> tuple[float, float, float]:
    """The generalized forces the actuators actually give for a request ``f``: allocated,
    clipped to the profile's input limits and mapped back (3.55)."""
    if not profile.input_limits:
        return tuple(f)
    row = profile.clip_inputs(profile.allocate(*(np.array([x], float) for x in f)))
    g = profile.generalized_forces(row)
    return float(g["tau_x"][0]), float(g["tau_y"][0]), float(g["tau_n"][0])


def model_step(profile: ShipProfile, theta: np.ndarray, nu: np.ndarray, psi: float, input_sig: dict) -> tuple[np.ndarray, float]:
    """One calm-water step of (3.60) for one ship: (nu(k+1), psi(k+1)).

    The velocity step is the shared kernel's (:class:`primitives.velocitystep.VelocityStep`, the
    step of :func:`primitives.simulate.simulate`) on a batch of one, so a closed-loop generator
    sees the same signals (speed through the water ``U`` included) and the same arithmetic as
    every simulation of its inputs (stepped on floats, :meth:`VelocityStep.next_one`: the same bits);
    the heading is integrated as the kernel's Euler kinematics."""
    step = _kernel_step(profile, theta)
    exo = dict(input_sig)
    exo["psi"] = psi
    return step.next_one(nu, exo), psi + profile.sample_time * nu[2]


# The kernel step of the last (profile, theta) a closed-loop generator ran, per profile: building
# one generates and parses the model's increment function, which a per-sample call cannot afford.
_STEPS: dict[int, tuple[ShipProfile, bytes, VelocityStep]] = {}


def _kernel_step(profile: ShipProfile, theta: np.ndarray) -> VelocityStep:
    th = np.asarray(theta, float)
    key = th.tobytes()
    hit = _STEPS.get(id(profile))
    if hit is None or hit[0] is not profile or hit[1] != key:
        hit = _STEPS[id(profile)] = (profile, key, VelocityStep(profile.model, th, profile.rigid_body, profile.sample_time))
    return hit[2]


def rudder_force(profile: ShipProfile, delta_deg: float, speed: float | None = None) -> float:
    """Yaw force equivalent to a rudder angle (35 deg -> steady turn of diameter 3 L)."""
    u = profile.cruise_speed_mps if speed is None else speed
    r_full = profile.cruise_speed_mps / (1.5 * profile.length_m)
    tn_full = steady_forces(profile, u, 0.0, r_full)[2]
    return tn_full * delta_deg / MAX_RUDDER_DEG


def side_sign(first_side: str) -> float:
    """+1 for starboard, -1 for port."""
    if first_side not in ("starboard", "port"):
        raise ValueError(f"first_side must be 'starboard' or 'port', got {first_side!r}")
    return 1.0 if first_side == "starboard" else -1.0


# -- thesis-style excitation signals ----------------------------------------------------------


def hold(
    profile: ShipProfile,
    n: int,
    u: float,
    v: float = 0.0,
    r: float = 0.0,
    nu0: np.ndarray | tuple[float, float, float] | None = None,
) -> Generated:
    """Constant forces that hold (u, v, r); starting from ``nu0`` gives accelerations."""
    f = np.tile(steady_forces(profile, u, v, r), (n, 1))
    return Generated(f, tuple(nu0) if nu0 is not None else (u, v, r))


def free_decay(profile: ShipProfile, n: int, u0: float, v0: float = 0.0) -> Generated:
    """All forces zero from (u0, v0, 0): a deceleration."""
    return Generated(np.zeros((n, 3)), (u0, v0, 0.0))


def excitation_zigzag(
    profile: ShipProfile, n: int, u: float, v_amp: float, r_amp: float, psi_switch: float, first_side: str = "starboard"
) -> Generated:
    """Zig-zag holding speed u with yaw rate +-r_amp and sway velocity -+v_amp (thesis tau3-tau8,
    tau17-tau20); the yaw (and sway) force switches sign when the heading passes +-psi_switch."""
    side = side_sign(first_side)
    pos = steady_forces(profile, u, -v_amp, r_amp)
    neg = steady_forces(profile, u, v_amp, -r_amp)
    splits: list[int] = []

    def policy(k, nu, psi, memo):
        return pos if _zigzag_side(k, psi, memo, side, psi_switch, splits) > 0 else neg

    forces, _ = closed_loop(profile, policy, n, (u, 0.0, 0.0))
    return Generated(forces, (u, 0.0, 0.0), splits, heading_switched=True)


def _zigzag_side(k: int, psi: float, memo: dict, first: int, psi_switch: float, splits: list[int]) -> int:
    """The side (+1 starboard, -1 port; ``first`` at the start, kept in ``memo``) a zig-zag pushes to at step ``k``:
    reversed, and ``k`` added to ``splits``, once the heading ``psi`` has passed ``psi_switch`` on the side pushed to."""
    s = memo.setdefault("s", first)
    if s * psi >= psi_switch:
        memo["s"] = -s
        splits.append(k)
    return memo["s"]


def excitation_spiral(profile: ShipProfile, n: int, u: float, v: float, r_end: float) -> Generated:
    """Inward spiral: the yaw rate ramps from 0 to r_end at speed u and sway v (tau9-tau11)."""
    rs = np.linspace(0.0, r_end, n)
    f = np.array([steady_forces(profile, u, v, r) for r in rs])
    return Generated(f, (u, v, 0.0), [n // 2])


def sway_steps(profile: ShipProfile, levels: list[tuple[float, int]], u: float = 0.0) -> Generated:
    """Sway-force steps that hold sway velocities ``(v, samples)`` in turn (tau13-tau16)."""
    f, splits, k = [], [], 0
    for v, m in levels:
        f += [steady_forces(profile, u, v, 0.0)] * m
        k += m
        splits.append(k)
    return Generated(np.array(f), (u, levels[0][0] if levels[0][0] else 0.0, 0.0), splits[:-1])


# -- standard trials (IMO MSC.137(76), ITTC 7.5-04-02-01) ---------------------------------------


def zigzag(
    profile: ShipProfile,
    delta_deg: float,
    psi_deg: float,
    *,
    speed: float | None = None,
    first_side: str = "starboard",
    n_switches: int = 4,
    n_max: int | None = None,
) -> Generated:
    """Zig-zag delta/psi: rudder delta to one side, reverse when the heading change passes psi."""
    u = profile.cruise_speed_mps if speed is None else speed
    side, tn = side_sign(first_side), rudder_force(profile, delta_deg, u)
    tx = steady_forces(profile, u, 0.0, 0.0)[0]
    psi_sw = np.radians(psi_deg)
    n_max = n_max or int(40 * profile.length_m / max(u, 1e-3) / profile.sample_time) + 10
    splits: list[int] = []

    def policy(k, nu, psi, memo):
        s = _zigzag_side(k, psi, memo, side, psi_sw, splits)
        return None if len(splits) > n_switches else (tx, 0.0, s * tn)

    forces, _ = closed_loop(profile, policy, n_max, (u, 0.0, 0.0))
    return Generated(forces, (u, 0.0, 0.0), splits[:n_switches], heading_switched=True)


def turning_circle(
    profile: ShipProfile, delta_deg: float = 35.0, *, speed: float | None = None, side: str = "starboard", turns: float = 1.0
) -> Generated:
    """Turning circle: full rudder held until the heading has changed 360 deg x turns."""
    u = profile.cruise_speed_mps if speed is None else speed
    s, tn = side_sign(side), rudder_force(profile, delta_deg, u)
    tx = steady_forces(profile, u, 0.0, 0.0)[0]
    n_max = int(200 * profile.length_m / max(u, 1e-3) / profile.sample_time)

    def policy(k, nu, psi, memo):
        return None if abs(psi) >= 2 * np.pi * turns else (tx, 0.0, s * tn)

    forces, _ = closed_loop(profile, policy, n_max, (u, 0.0, 0.0))
    n = len(forces)
    return Generated(forces, (u, 0.0, 0.0), [n // 4, n // 2, 3 * n // 4])


def pull_out(profile: ShipProfile, delta_deg: float = 20.0, *, speed: float | None = None, side: str = "starboard") -> Generated:
    """Pull-out: steady turn with rudder delta, then rudder amidships and let the yaw rate decay."""
    u = profile.cruise_speed_mps if speed is None else speed
    s, tn = side_sign(side), rudder_force(profile, delta_deg, u)
    tx = steady_forces(profile, u, 0.0, 0.0)[0]
    n_leg = int(8 * profile.length_m / max(u, 1e-3) / profile.sample_time)
    f = np.array([(tx, 0.0, s * tn)] * n_leg + [(tx, 0.0, 0.0)] * n_leg)
    return Generated(f, (u, 0.0, 0.0), [n_leg])


def direct_spiral(
    profile: ShipProfile,
    deltas_deg: tuple[float, ...] = (15, 10, 5, 2, 0, -2, -5, -10, -15, -10, -5, -2, 0, 2, 5, 10, 15),
    *,
    speed: float | None = None,
    hold_lengths: float = 6.0,
) -> Generated:
    """Direct (Dieudonne) spiral: rudder steps, each held until the yaw rate is steady."""
    u = profile.cruise_speed_mps if speed is None else speed
    tx = steady_forces(profile, u, 0.0, 0.0)[0]
    m = int(hold_lengths * profile.length_m / max(u, 1e-3) / profile.sample_time)
    f = np.array([(tx, 0.0, rudder_force(profile, d, u)) for d in deltas_deg for _ in range(m)])
    return Generated(f, (u, 0.0, 0.0), [m * i for i in range(1, len(deltas_deg))])


def reverse_spiral(
    profile: ShipProfile, rates_deg_s: tuple[float, ...] | None = None, *, speed: float | None = None, hold_lengths: float = 6.0
) -> Generated:
    """Reverse (Bech) spiral: the helm holds a sequence of yaw rates; the rudder is recorded."""
    u = profile.cruise_speed_mps if speed is None else speed
    r_full = u / (1.5 * profile.length_m)
    rates = np.radians(rates_deg_s) if rates_deg_s is not None else r_full * np.array([0.6, 0.3, 0.1, -0.1, -0.3, -0.6])
    m = int(hold_lengths * profile.length_m / max(u, 1e-3) / profile.sample_time)
    f = np.array([steady_forces(profile, u, 0.0, r) for r in rates for _ in range(m)])
    f[:, 1] = 0.0
    return Generated(f, (u, 0.0, 0.0), [m * i for i in range(1, len(rates))])


def speed_change(
    profile: ShipProfile, u_from: float, u_to: float, *, duration_lengths: float = 15.0, crash: bool = False
) -> Generated:
    """Acceleration / deceleration between two speeds; ``crash`` reverses full until stopped."""
    m = int(duration_lengths * profile.length_m / max(u_from, u_to, 1e-3) / profile.sample_time)
    if crash:
        lo = -abs(steady_forces(profile, profile.cruise_speed_mps, 0.0, 0.0)[0]) * 1.5

        def policy(k, nu, psi, memo):
            if nu[0] <= 0.0 or k >= m:
                return None
            return (lo, 0.0, 0.0)

        forces, _ = closed_loop(profile, policy, m, (u_from, 0.0, 0.0))
        return Generated(forces, (u_from, 0.0, 0.0), [])
    tx = steady_forces(profile, u_to, 0.0, 0.0)[0] if u_to > 0 else 0.0
    return Generated(np.tile((tx, 0.0, 0.0), (m, 1)), (u_from, 0.0, 0.0), [m // 2])


# -- basic repositioning moves for the planner ---------------------------------------------------


def straight(profile: ShipProfile, distance_m: float, speed: float | None = None) -> Generated:
    """Straight run at constant speed."""
    u = profile.cruise_speed_mps if speed is None else speed
    m = max(1, int(round(distance_m / (u * profile.sample_time))))
    return Generated(
        np.tile(steady_forces(profile, u, 0.0, 0.0), (m, 1)),
        (u, 0.0, 0.0),
        [],
        [f"steady course, {u:.2f} m/s for {distance_m:.0f} m"],
    )


def turn_to_heading(profile: ShipProfile, dpsi: float, speed: float | None = None, gain: float = 4.0) -> Generated:
    """Turn by ``dpsi`` rad (positive = starboard) and steady on the new heading.

    With speed 0 it is a turn on the spot; with cruise speed a left/right turn. A
    proportional-derivative helm on the yaw force lands the heading within 1 deg.
    """
    u = profile.cruise_speed_mps if speed is None else speed
    tx = steady_forces(profile, u, 0.0, 0.0)[0] if u > 0 else 0.0
    r_max = max(u, 0.3 * profile.cruise_speed_mps) / (1.5 * profile.length_m)
    tn_max = abs(steady_forces(profile, u, 0.0, r_max)[2])
    tn_max = max(tn_max, abs(steady_forces(profile, 0.0, 0.0, r_max)[2]))
    ts = profile.sample_time
    n_max = int(4 * abs(dpsi) / r_max / ts) + int(40 / ts) + 20

    def policy(k, nu, psi, memo):
        err = dpsi - psi
        if abs(err) < np.radians(1.0) and abs(nu[2]) < r_max * 0.05:
            return None
        r_ref = np.clip(gain * err / (np.pi / 2) * r_max, -r_max, r_max)
        tn_ff = steady_forces(profile, max(nu[0], 0.0), 0.0, r_ref)[2]
        tn = np.clip(tn_ff + tn_max * 2.0 * (r_ref - nu[2]) / r_max, -2 * tn_max, 2 * tn_max)
        return (tx, 0.0, float(tn))

    forces, _ = closed_loop(profile, policy, n_max, (u, 0.0, 0.0))
    return Generated(forces, (u, 0.0, 0.0), [])
