"""The primitive library: thesis primitives tau1-tau20, standard trials and basic moves.

A :class:`Primitive` is a manoeuvre with its input sequence, its nominal (calm, simulation-set)
states and track from the start pose (0, 0, 0), its natural split points, its end pose and
the hull's swept footprint. Section 9.1.1 (tau1-tau11) and section 9.3 (tau12-tau20) of
Ljungberg (2022) defines the thesis primitives by the states they produce.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from shapely.geometry import Polygon

from primitives import helm as hm
from primitives import maneuvers as mv
from primitives.footprint import swept_footprint
from primitives.orders import Order, heading_words, orders_from_inputs, orders_to_dicts, render
from primitives.ship import ShipProfile, load_profile
from primitives.simulate import simulate
from primitives.stability import require_stable
from primitives.steady_forces import steady_forces

KNOT = 1852.0 / 3600.0


@dataclass
class Primitive:
    """One manoeuvre of the library.

    inputs: (N, m) in the profile's input units; nu: (N+1, 3) nominal body velocities;
    track: (N+1, 3) nominal pose (x north, y east, psi) from the start pose (0, 0, 0).
    kind: "informative" (used for identification) or "basic" (repositioning).
    commands: one-line summaries for the crew; orders: the helm/engine/azimuth orders in the
    ship's own terms (:mod:`primitives.orders`), a faithful description of ``inputs``.
    """

    name: str
    description: str
    profile: ShipProfile = field(repr=False)
    inputs: np.ndarray = field(repr=False)
    nu: np.ndarray = field(repr=False)
    track: np.ndarray = field(repr=False)
    split_points: list[int]
    kind: str = "informative"
    commands: list[str] = field(default_factory=list)
    orders: list[Order] = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        return self.inputs.shape[0]

    @property
    def duration_s(self) -> float:
        return self.n_samples * self.profile.sample_time

    @property
    def nu0(self) -> np.ndarray:
        return self.nu[0]

    @property
    def end_pose(self) -> np.ndarray:
        """(dx north, dy east, dpsi) of the end pose in the start-pose frame."""
        return self.track[-1].copy()

    def ranges(self) -> dict[str, tuple[float, float]]:
        return {s: (float(self.nu[:, i].min()), float(self.nu[:, i].max())) for i, s in enumerate("uvr")}

    def expectations(self) -> dict[str, float]:
        """What the nominal manoeuvre does, for abort criteria: speed over ground range (m/s and
        kn), heading change range and at the end (deg, + starboard of the initial course),
        largest yaw rate (deg/s) and duration (s). Exports add their own margins."""
        speed = np.hypot(self.nu[:, 0], self.nu[:, 1])
        dpsi = np.degrees(self.track[:, 2] - self.track[0, 2])
        return {
            "duration_s": self.duration_s,
            "speed_min_mps": float(speed.min()),
            "speed_max_mps": float(speed.max()),
            "speed_min_kn": float(speed.min() / KNOT),
            "speed_max_kn": float(speed.max() / KNOT),
            "heading_change_min_deg": float(dpsi.min()),
            "heading_change_max_deg": float(dpsi.max()),
            "heading_change_end_deg": float(dpsi[-1]),
            "yaw_rate_max_deg_s": float(np.degrees(np.abs(self.nu[:, 2]).max())),
        }

    def abort_criteria(self, speed_margin: float = 0.15, heading_margin_deg: float = 10.0, yaw_margin: float = 0.25) -> str:
        """'abort if speed below 12.1 kn or above 17.0 kn, heading outside 25° port .. 25° stbd of
        the initial course, or rate of turn above 0.90 °/s' with the given relative / absolute
        margins (no lower speed limit for a manoeuvre that reaches rest)."""
        e = self.expectations()
        lo, hi = e["speed_min_kn"] * (1 - speed_margin), e["speed_max_kn"] * (1 + speed_margin)
        h_lo, h_hi = e["heading_change_min_deg"] - heading_margin_deg, e["heading_change_max_deg"] + heading_margin_deg

        def side(a: float) -> str:
            return f"{abs(a):.0f}° {'stbd' if a >= 0 else 'port'}"

        heading = "" if h_hi - h_lo >= 360 else f" heading outside {side(h_lo)} .. {side(h_hi)} of the initial course,"
        # a straight run expects no yaw: the floor is a tenth of a 3-lengths-diameter turn's rate
        floor = np.degrees(0.1 * self.profile.cruise_speed_mps / (1.5 * self.profile.length_m))
        yaw = max(e["yaw_rate_max_deg_s"] * (1 + yaw_margin), floor)
        # a manoeuvre that starts or ends at rest has no lower speed limit ("speed < 0.0 kn" cannot happen)
        speed = f"speed above {hi:.1f} kn" if lo < 0.05 else f"speed below {lo:.1f} kn or above {hi:.1f} kn"
        return f"abort if {speed},{heading} or rate of turn above {yaw:.2f} °/s"

    def to_dict(self) -> dict:
        """JSON-ready summary: no sampled arrays, the orders as dicts, the expectations."""
        return {
            "name": self.name,
            "kind": self.kind,
            "description": self.description,
            "duration_s": self.duration_s,
            "end_pose": self.end_pose.tolist(),
            "split_points": list(self.split_points),
            "commands": list(self.commands),
            "orders": orders_to_dicts(self.orders),
            "expectations": self.expectations(),
            "abort_criteria": self.abort_criteria(),
        }

    @cached_property
    def footprint(self) -> Polygon:
        """Hull outline swept along the nominal track, in the start-pose frame (x north, y east)."""
        return swept_footprint(self.track, self.profile.length_m, self.profile.beam_m)

    def pieces(self) -> list[Primitive]:
        """The primitive cut at its natural split points (e.g. zig-zag half periods)."""
        cuts = [0] + [k for k in self.split_points if 0 < k < self.n_samples] + [self.n_samples]
        out = []
        for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
            # re-express the piece in its own start frame
            x0, y0, p0 = self.track[a]
            c, s = np.cos(p0), np.sin(p0)
            d = self.track[a : b + 1] - self.track[a]
            tr = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])
            out.append(
                Primitive(
                    f"{self.name}.{i + 1}",
                    f"{self.description} (part {i + 1})",
                    self.profile,
                    self.inputs[a:b],
                    self.nu[a : b + 1],
                    tr,
                    [],
                    self.kind,
                    self.commands,
                    _piece_orders(self.orders, a * self.profile.sample_time, b * self.profile.sample_time),
                )
            )
        return out


def _piece_orders(orders: list[Order], t0: float, t1: float) -> list[Order]:
    """Orders in [t0, t1) re-timed from t0, led by the settings in force at t0."""
    before = [o for o in orders if o.t_s < t0 - 1e-9]
    lead: dict[str, Order] = {}
    for o in before:  # the last order that set each value
        for key in o.values:
            lead[key] = o
    unique = list({id(o): o for o in lead.values()}.values())
    first = [Order(0.0, f"(continuing) {o.text}", dict(o.values)) for o in unique]
    return first + [Order(o.t_s - t0, o.text, dict(o.values)) for o in orders if t0 - 1e-9 <= o.t_s < t1 - 1e-9]


def heading_switch_orders(prim_orders: list[Order], track: np.ndarray, splits: list[int], ts: float) -> list[Order]:
    """Mark the orders at heading-switched split points with the heading change they wait for."""
    at = {k: float(np.degrees(track[k, 2] - track[0, 2])) for k in splits}
    out = []
    for o in prim_orders:
        k = int(round(o.t_s / ts))
        if k in at and k > 0:
            o = Order(o.t_s, f"{o.text} at {heading_words(at[k])}", o.values | {"at_heading_change_deg": at[k]})
        out.append(o)
    return out


def make_primitive(profile: ShipProfile, name: str, description: str, gen: mv.Generated, kind: str = "informative") -> Primitive:
    """Allocate a generator's forces to the profile's inputs (or take its inputs and orders),
    simulate it nominally and describe it as orders in the ship's own terms."""
    if gen.inputs is not None:
        inputs, orders = np.asarray(gen.inputs, float), list(gen.orders)
    else:
        # the actuators saturate at the profile's limits (a crash stop asks for more than full astern)
        inputs = profile.clip_inputs(profile.allocate(gen.forces[:, 0], gen.forces[:, 1], gen.forces[:, 2]))
        orders = orders_from_inputs(profile, inputs)
    res = simulate(profile, inputs, nu0=gen.nu0)
    if gen.heading_switched and gen.inputs is None:
        orders = heading_switch_orders(orders, res.eta[0], gen.split_points, profile.sample_time)
    return Primitive(
        name, description, profile, inputs, res.nu[0], res.eta[0], list(gen.split_points), kind, render(orders), orders
    )


# -- the thesis primitives -----------------------------------------------------------------------


def model_ship_thesis(profile: ShipProfile, n: int = 300, psi_switch: float = 0.5) -> list[Primitive]:
    """tau1-tau11 of section 9.1.1 (about 40 s each at 8 Hz). ``psi_switch`` (rad) sets the
    zig-zag period, a choice the thesis does not state."""
    zz = [
        ("tau3", "slow/flat zig-zag", 0.35, 0.1, 0.2),
        ("tau4", "moderate/flat zig-zag", 0.8, 0.1, 0.2),
        ("tau5", "fast/flat zig-zag", 1.15, 0.1, 0.2),
        ("tau6", "slow/steep zig-zag", 0.35, 0.15, 0.35),
        ("tau7", "moderate/steep zig-zag", 0.7, 0.15, 0.35),
        ("tau8", "fast/steep zig-zag", 1.0, 0.15, 0.35),
    ]
    sp = [
        ("tau9", "slow inward spiral", 0.4, 0.05),
        ("tau10", "moderate inward spiral", 0.75, 0.125),
        ("tau11", "fast inward spiral", 1.0, 0.2),
    ]
    out = [
        make_primitive(profile, "tau1", "decelerating (u 1 -> 0)", mv.free_decay(profile, n, 1.0)),
        make_primitive(profile, "tau2", "accelerating (u 0 -> 1)", mv.hold(profile, n, 1.0, nu0=(0.0, 0.0, 0.0))),
    ]
    out += [make_primitive(profile, nm, d, mv.excitation_zigzag(profile, n, u, v, r, psi_switch)) for nm, d, u, v, r in zz]
    out += [make_primitive(profile, nm, d, mv.excitation_spiral(profile, n, u, v, -0.6)) for nm, d, u, v in sp]
    return out


def full_scale_thesis(profile: ShipProfile, n: int = 200) -> list[Primitive]:
    """tau12-tau20 of section 9.3 for the two-azimuth vessel (Ts = 1 s)."""
    half = n // 2
    q = n // 4
    acc = mv.Generated(
        np.vstack([np.tile(steady_forces(profile, 3.5, 0, 0), (half, 1)), np.zeros((n - half, 3))]), (0.0, 0.0, 0.0), [half]
    )
    out = [make_primitive(profile, "tau12", "surge accelerations/decelerations (u 0 -> 3.5 -> 0)", acc)]
    steps = mv.sway_steps(profile, [(1.0, q), (0.0, q), (-1.0, q), (0.0, n - 3 * q)])
    steps.nu0 = (0.0, 0.0, 0.0)  # accelerations start from rest
    out.append(make_primitive(profile, "tau13", "sway accelerations/decelerations (v -1 .. 1)", steps))
    for nm, d, v in (("tau14", "slow pure sway", 0.65), ("tau15", "moderate pure sway", 0.9), ("tau16", "fast pure sway", 1.15)):
        out.append(make_primitive(profile, nm, f"{d} (|v| ~ {v} m/s)", mv.sway_steps(profile, [(v, half), (-v, n - half)])))
    for nm, d, u, period in (
        ("tau17", "slow high-frequency zig-zag (T ~ 30 s)", 3.0, 30.0),
        ("tau18", "fast high-frequency zig-zag (T ~ 30 s)", 4.0, 30.0),
        ("tau19", "slow low-frequency zig-zag (T ~ 100 s)", 3.0, 100.0),
        ("tau20", "fast low-frequency zig-zag (T ~ 100 s)", 4.0, 100.0),
    ):
        psi_sw = 0.03 * period / 4.0
        out.append(make_primitive(profile, nm, d, mv.excitation_zigzag(profile, n, u, 0.5, 0.03, psi_sw)))
    return out


def standard_trials(profile: ShipProfile) -> list[Primitive]:
    """IMO/ITTC standard manoeuvres as parametrised primitives, with descriptive names."""
    require_stable(profile)
    u = profile.cruise_speed_mps
    p = []
    for d, s in ((10, "starboard"), (10, "port"), (20, "starboard"), (20, "port")):
        p.append(
            make_primitive(
                profile, f"zigzag_{d}_{d}_{s[0]}", f"zig-zag {d}/{d}, first rudder to {s}", mv.zigzag(profile, d, d, first_side=s)
            )
        )
    for s in ("starboard", "port"):
        p.append(
            make_primitive(
                profile, f"turning_circle_35_{s[0]}", f"turning circle, rudder 35 deg {s}", mv.turning_circle(profile, 35, side=s)
            )
        )
    p.append(make_primitive(profile, "pull_out_20_s", "pull-out after a 20 deg starboard turn", mv.pull_out(profile, 20)))
    p.append(make_primitive(profile, "direct_spiral", "direct (Dieudonne) spiral", mv.direct_spiral(profile)))
    p.append(make_primitive(profile, "reverse_spiral", "reverse (Bech) spiral", mv.reverse_spiral(profile)))
    p.append(make_primitive(profile, "acceleration", "acceleration from rest to cruise speed", mv.speed_change(profile, 0.0, u)))
    p.append(make_primitive(profile, "deceleration", "deceleration from cruise speed to rest", mv.speed_change(profile, u, 0.0)))
    p.append(make_primitive(profile, "stopping", "crash stop from cruise speed", mv.speed_change(profile, u, 0.0, crash=True)))
    return p


def basic_moves(profile: ShipProfile, step_m: float | None = None) -> list[Primitive]:
    """Repositioning moves for the planner: straight run, turn on the spot both ways, left and
    right 90 deg turns at cruise speed. ``step_m`` is the straight-run length (default 5 L).
    A rudder ship cannot turn on the spot: it gets the straight run and the two turns, in helm
    orders (rudder, counter-rudder, midships)."""
    require_stable(profile)
    step = step_m or 5 * profile.length_m
    if profile.actuator == "rudder_propeller":
        return [
            make_primitive(profile, "straight", f"straight run {step:.0f} m", hm.straight(profile, step), "basic"),
            make_primitive(profile, "turn_s", "90 deg turn to starboard", hm.turn(profile, 90.0), "basic"),
            make_primitive(profile, "turn_p", "90 deg turn to port", hm.turn(profile, -90.0), "basic"),
        ]
    return [
        make_primitive(profile, "straight", f"straight run {step:.0f} m", mv.straight(profile, step), "basic"),
        make_primitive(
            profile, "spot_turn_s", "turn on the spot 90 deg to starboard", mv.turn_to_heading(profile, np.pi / 2, 0.0), "basic"
        ),
        make_primitive(
            profile, "spot_turn_p", "turn on the spot 90 deg to port", mv.turn_to_heading(profile, -np.pi / 2, 0.0), "basic"
        ),
        make_primitive(profile, "turn_s", "90 deg turn to starboard", mv.turn_to_heading(profile, np.pi / 2), "basic"),
        make_primitive(profile, "turn_p", "90 deg turn to port", mv.turn_to_heading(profile, -np.pi / 2), "basic"),
    ]


def rudder_dictionary(profile: ShipProfile) -> list[Primitive]:
    """Informative manoeuvres of a rudder/propeller ship, in helm and engine orders: zig-zags
    10/10 and 20/20 to both sides, thesis-style excitation zig-zags (two rudder angles switched
    at a small heading change, at the approach rpm and at 60 % of it: slow/fast, flat/steep as
    tau3-tau8), turning circles with full rudder both sides, a pull-out, a direct (Dieudonne)
    spiral, accelerations/decelerations by engine steps and a stopping manoeuvre."""
    n0 = hm.steady_rps(profile)
    n_slow = max(0.6 * n0, profile.engine.rps_limits[0])
    full = profile.helm.max_rudder_deg
    out = []
    for d, s in ((10, "starboard"), (10, "port"), (20, "starboard"), (20, "port")):
        out.append(
            make_primitive(
                profile, f"zigzag_{d}_{d}_{s[0]}", f"zig-zag {d}/{d}, first rudder to {s}", hm.zigzag(profile, d, d, first_side=s)
            )
        )
    for n, pct in ((n0, 100), (n_slow, round(100 * n_slow / n0))):
        for d, psi in ((10, 5), (min(25, full), 5)):
            out.append(
                make_primitive(
                    profile,
                    f"zz_exc_{d:g}_{psi}_{pct}",
                    f"excitation zig-zag {d:g}/{psi} at {pct} % of approach rpm",
                    hm.zigzag(profile, d, psi, n_rps=n, n_switches=6),
                )
            )
    for s in ("starboard", "port"):
        out.append(
            make_primitive(
                profile,
                f"turning_circle_{full:g}_{s[0]}",
                f"turning circle, rudder {full:g} deg {s}",
                hm.turning_circle(profile, side=s),
            )
        )
    out.append(make_primitive(profile, "pull_out_20_s", "pull-out after a 20 deg starboard turn", hm.pull_out(profile, 20)))
    out.append(make_primitive(profile, "direct_spiral", "direct (Dieudonne) spiral", hm.direct_spiral(profile)))
    half = max(0.5 * n0, profile.engine.rps_limits[0])
    out.append(
        make_primitive(
            profile,
            "acceleration",
            f"acceleration: engine {60 * half:.0f} -> {60 * n0:.0f} rpm",
            hm.speed_change(profile, half, n0),
        )
    )
    out.append(
        make_primitive(
            profile,
            "deceleration",
            f"deceleration: engine {60 * n0:.0f} -> {60 * half:.0f} rpm",
            hm.speed_change(profile, n0, half),
        )
    )
    gen, what = hm.stopping(profile)
    out.append(make_primitive(profile, "stopping", what, gen))
    return out


_THESIS = {"thesis-model-ship": model_ship_thesis, "thesis-full-scale": full_scale_thesis}


def thesis_primitives(profile: ShipProfile) -> list[Primitive]:
    """The profile's identification dictionary: the thesis's tau1-tau11 or tau12-tau20 (profile
    key ``library``), the helm dictionary of a rudder/propeller ship, else none."""
    require_stable(profile)
    if profile.library in _THESIS:
        return _THESIS[profile.library](profile)
    if profile.actuator == "rudder_propeller":
        return rudder_dictionary(profile)
    return []


SWAY_STEPS = ("sway_steps", "sway_steps_rest")  # at cruise speed, at rest


def force_dictionary(profile: ShipProfile) -> list[Primitive]:
    """Moves a generalized-force or azimuth ship can make beyond the standard trials, scaled to
    the ship as the thesis's tau13-tau16 and tau3-tau8 are: sway steps (+-0.15 u) at cruise speed
    and at rest, and excitation zig-zags (sway +-0.1 u against yaw rate +-u/(2 L)) at 60 % and
    100 % of cruise speed, about 20 ship lengths each."""
    u, L = profile.cruise_speed_mps, profile.length_m
    n = max(20, int(20 * L / u / profile.sample_time))
    out = []
    # pods aft (mv.pod_arm) cannot hold a sway speed on a steady course: a side force there turns the ship, so
    # steps of steady sway are not a manoeuvre it can sail (the planner's run-in would never reach their entry sway);
    # library_notes says so to the user
    steps = () if mv.pod_arm(profile) is not None else tuple(zip(SWAY_STEPS, (u, 0.0)))
    for name, uu in steps:
        v = 0.15 * u
        gen = mv.sway_steps(profile, [(v, n // 2), (-v, n - n // 2)], u=uu)
        out.append(make_primitive(profile, name, f"sway steps +-{v:.2f} m/s at {uu:.2f} m/s", gen))
    for pct in (60, 100):
        uu = pct / 100 * u
        gen = mv.excitation_zigzag(profile, n, uu, 0.1 * uu, uu / (2 * L), 0.25)
        out.append(make_primitive(profile, f"zz_exc_{pct}", f"excitation zig-zag at {uu:.2f} m/s", gen))
    return out


def library_notes(profile: ShipProfile) -> list[str]:
    """What the profile's library leaves out that other ships of its actuator have, and why, one
    sentence each: today the steady-sway steps of :func:`force_dictionary` for pods aft
    (:func:`primitives.maneuvers.pod_arm`); empty for a profile with a thesis dictionary."""
    arm = mv.pod_arm(profile)
    if arm is None or profile.library in _THESIS:
        return []
    return [
        f"no steady-sway steps ({', '.join(SWAY_STEPS)}) in {profile.name}'s library: its thrusters all sit at "
        f"x = {arm:+.1f} m (pods {'aft' if arm < 0 else 'forward'}), where a side force turns the ship, so it cannot "
        "hold a sway speed on a steady course; sway is excited by its zig-zags and turns instead"
    ]


def design_dictionary(profile: ShipProfile) -> list[Primitive]:
    """What the design chooses from: the dictionary of :func:`thesis_primitives`, else (a user
    profile without one) the standard trials and the sway and excitation moves of
    :func:`force_dictionary`."""
    return thesis_primitives(profile) or standard_trials(profile) + force_dictionary(profile)


def build_library(profile: ShipProfile | str, *, standard: bool = True, basic: bool = True) -> list[Primitive]:
    """Every primitive the profile supports: its dictionary, standard trials, basic moves (a
    rudder ship's dictionary already holds its standard trials, in helm orders; a profile
    without a dictionary gets what the design chooses from, :func:`design_dictionary`)."""
    if isinstance(profile, str):
        profile = load_profile(profile)
    lib = thesis_primitives(profile)
    if not lib:
        lib = design_dictionary(profile)
    elif standard and profile.actuator != "rudder_propeller":
        lib += standard_trials(profile)
    if basic:
        lib += basic_moves(profile)
    return lib


def by_name(library: list[Primitive], names: list[str]) -> list[Primitive]:
    index = {p.name: p for p in library}
    missing = [n for n in names if n not in index]
    if missing:
        raise KeyError(f"unknown primitives {missing}; the library has {sorted(index)}")
    return [index[n] for n in names]
