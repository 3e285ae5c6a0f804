"""Manoeuvres sized to the sea room: shorter forms of a rudder ship's library manoeuvres.

The rudder dictionary (:func:`primitives.library.rudder_dictionary`) sails each family at the
length a delivery trial on open water would: zig-zags of five rudder executes, excitation
zig-zags of seven, a seventeen-step direct spiral, speed changes between 100 % and 50 % of the
approach rpm run until the speed has settled, a stopping manoeuvre. In a fjord or a bay they fit
nowhere. A master there sails the same families shorter: the IMO MSC.137(76) / ITTC
7.5-04-02-01 zig-zag of three or four executes (enough for the first and second overshoot), a
spiral of fewer steps, a shallower speed change recorded until most of the change is over, a
stop to a higher speed, or with the engine astern when the ship has astern power.

:data:`SHORT_FORMS` says, family by family, which shorter forms exist (data, for any rudder
ship); :func:`short_forms` makes those of the named long manoeuvres, each simulated by the
project's one kernel (:func:`primitives.library.make_primitive`) so each gets its own information
matrix. The planner offers them only when the long forms do not fit the water
(:mod:`maps.searoom`), so a plan on large water is the one it was.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from primitives import helm as hm
from primitives.library import Primitive, make_primitive
from primitives.maneuvers import Generated
from primitives.ship import ShipProfile

# rudder executes of the short zig-zags (the library's own have n_switches = 4: five executes);
# three executes give the first and second overshoot angles of the IMO test
ZIGZAG_EXECUTES = (4, 3, 2)
# excitation zig-zags (the library's: six switches, seven executes)
EXCITATION_EXECUTES = (5, 3, 2)
# direct spiral: (rudder steps, ship lengths each is held); the library's is DIEUDONNE_STEPS, 5 L
SPIRAL_FORMS = (
    ((10.0, 5.0, 0.0, -5.0, -10.0, -5.0, 0.0, 5.0, 10.0), 4.0),
    ((10.0, 0.0, -10.0, 0.0, 10.0), 3.0),
)
# turning circles: turns (the library's: one, 360 deg), each ended by regaining speed full ahead
TURN_FORMS = (0.5,)
# speed changes: (depth as a share of the approach rpm the engine steps to or from, share of the
# speed change recorded); the library's step 100 % <-> 50 % and record until settled (98 %)
SPEED_FORMS = ((0.75, 0.9), (0.75, 0.63))
# stopping without astern: coast until the speed has fallen to this share of cruise speed
# (the library's: 0.5); with astern power: full astern until this share (the library's: 0)
COAST_TO = (0.75,)
ASTERN_TO = (0.5,)


@dataclass(frozen=True)
class ShortForm:
    """One shorter form of a library manoeuvre: its name, description and generator."""

    name: str
    description: str
    make: Callable[[], Generated]


def _zigzags(
    profile: ShipProfile, long: str, d: float, psi: float, executes: tuple[int, ...], side: str, what: str, n: float | None = None
) -> list[ShortForm]:
    """The zig-zag ``long`` with each of ``executes`` rudder executes (``what``: its description, '{e}' the executes)."""
    return [
        ShortForm(
            f"{long}_e{e}",
            what.format(e=e),
            lambda e=e: hm.zigzag(profile, d, psi, first_side=side, n_rps=n, n_switches=e - 1, regain=True),
        )
        for e in executes
    ]


def _turns(profile: ShipProfile, long: str, side: str) -> list[ShortForm]:
    full = profile.helm.max_rudder_deg
    return [
        ShortForm(
            f"{long}_{round(360 * t)}",
            f"turn of {360 * t:.0f} deg, rudder {full:g} deg {side}, then full ahead to regain speed",
            lambda t=t: hm.turning_circle(profile, side=side, turns=t, regain=True),
        )
        for t in TURN_FORMS
    ]


def _spirals(profile: ShipProfile) -> list[ShortForm]:
    return [
        ShortForm(
            f"direct_spiral_{len(steps)}",
            f"direct (Dieudonne) spiral of {len(steps)} rudder steps, each held {hold:g} ship lengths",
            lambda steps=steps, hold=hold: hm.direct_spiral(profile, steps, hold_lengths=hold, regain=True),
        )
        for steps, hold in SPIRAL_FORMS
    ]


def _speed_changes(profile: ShipProfile, n0: float, up: bool) -> list[ShortForm]:
    out = []
    lo = profile.engine.rps_limits[0]
    for depth, share in SPEED_FORMS:
        n1 = max(depth * n0, lo)
        a, b = (n1, n0) if up else (n0, n1)
        u_a, u_b = hm.steady_speed(profile, a), hm.steady_speed(profile, b)
        word = "acceleration" if up else "deceleration"
        out.append(
            ShortForm(
                f"{word}_{round(100 * depth)}_{round(100 * share)}",
                f"{word}: engine {60 * a:.0f} -> {60 * b:.0f} rpm, recorded over {100 * share:.0f} % of the speed change",
                lambda a=a, b=b, u=u_a + share * (u_b - u_a): hm.speed_change(profile, a, b, until_speed=u, regain=True),
            )
        )
    return out


def _stops(profile: ShipProfile, n0: float) -> list[ShortForm]:
    u = profile.cruise_speed_mps
    out = [
        ShortForm(
            f"stopping_coast_{round(100 * share)}",
            f"engine stop from cruise speed, coasting to {100 * share:.0f} % of it",
            lambda share=share: hm.speed_change(profile, n0, 0.0, until_speed=share * u, regain=True),
        )
        for share in COAST_TO
    ]
    if hm.has_astern(profile):
        astern = profile.engine.rps_limits[0]
        out += [
            ShortForm(
                f"stopping_astern_{round(100 * share)}",
                f"stopping: full astern ({-60 * astern:.0f} rpm) from cruise speed until {100 * share:.0f} % of it",
                lambda share=share: hm.speed_change(profile, n0, astern, until_speed=share * u, regain=True),
            )
            for share in ASTERN_TO
        ]
    return out


def short_form_table(profile: ShipProfile) -> dict[str, list[ShortForm]]:
    """{long manoeuvre's name: its shorter forms, longest first} for a rudder/propeller ship's
    dictionary (names as :func:`primitives.library.rudder_dictionary` gives them); empty for others.
    Only the generators are made here: nothing is simulated until :func:`short_forms` asks."""
    if profile.actuator != "rudder_propeller":
        return {}
    n0 = hm.steady_rps(profile)
    n_slow = max(0.6 * n0, profile.engine.rps_limits[0])
    full = profile.helm.max_rudder_deg
    table: dict[str, list[ShortForm]] = {}
    for d, s in ((10, "starboard"), (10, "port"), (20, "starboard"), (20, "port")):
        name = f"zigzag_{d}_{d}_{s[0]}"
        table[name] = _zigzags(
            profile, name, d, d, ZIGZAG_EXECUTES, s, f"zig-zag {d:g}/{d:g}, first rudder to {s}, " + "{e} rudder executes (IMO)"
        )
    for n, pct in ((n0, 100), (n_slow, round(100 * n_slow / n0))):
        for d, psi in ((10, 5), (min(25, full), 5)):
            name = f"zz_exc_{d:g}_{psi}_{pct}"
            what = f"excitation zig-zag {d:g}/{psi:g} at {pct} % of approach rpm, " + "{e} rudder executes"
            table[name] = _zigzags(profile, name, d, psi, EXCITATION_EXECUTES, "starboard", what, n)
    for s in ("starboard", "port"):
        name = f"turning_circle_{full:g}_{s[0]}"
        table[name] = _turns(profile, name, s)
    table["direct_spiral"] = _spirals(profile)
    table["deceleration"] = _speed_changes(profile, n0, up=False)
    table["stopping"] = _stops(profile, n0)
    return table


def short_forms(profile: ShipProfile, names: list[str], table: dict[str, list[ShortForm]] | None = None) -> list[Primitive]:
    """The shorter forms of the named long manoeuvres (those that have some), simulated."""
    table = short_form_table(profile) if table is None else table
    return [make_primitive(profile, f.name, f.description, f.make()) for n in names for f in table.get(n, [])]


def named_short_forms(profile: ShipProfile, names: list[str]) -> list[Primitive]:
    """The short forms called ``names`` (as :func:`short_forms` names them, e.g. a plan's
    ``stopping_coast_75``), simulated; names that are no short form are skipped."""
    want = set(names)
    forms = [f for fs in short_form_table(profile).values() for f in fs if f.name in want]
    return [make_primitive(profile, f.name, f.description, f.make()) for f in forms]
