"""The planning scenario of Ljungberg (2022) section 9.4, rebuilt for the full-scale profile.

Section 9.4 plans on a sea-depth map of the port of Helsinki with three informative
primitives, each used three times: a steep and a wide zig-zag in surge and a wide zig-zag in
sway, plus basic moves (straight ahead, turn on the spot both ways). The thesis does not give
the primitives' parameters ("what manoeuvres the primitives are based on is not important in
this step"); the ones here are sized to the map: each lasts 1.5-3.5 minutes and needs
0.3-0.6 km of water.

The thesis plans on four headings and sails each primitive straight from the lattice (no
run-in): ``--scenario thesis-9.4 --headings 4 --run-in 0``. With run-ins at four headings there
is no plan: the 90 deg turns at speed and on the spot reach only 29 lattice states from the start
in the South Harbour, and the zig-zags that carry the ship out of it without a run-in no longer fit
there with one. With 8 or the default 16 headings it plans with run-ins.
"""

from __future__ import annotations

import numpy as np

from primitives import maneuvers as mv
from primitives.library import Primitive, make_primitive
from primitives.ship import ProfileError, ShipProfile
from primitives.stability import require_stable
from primitives.steady_forces import has_steady_forces, require_steady_forces

# Helsinki example (bundled map): start in the South Harbour (upper left of the thesis's
# figure 9.13 is a harbour), goal in open water to the south-east. Lat, lon, heading (deg).
HELSINKI_START = (60.1625, 24.9600, 180.0)
HELSINKI_GOAL = (60.1230, 24.9900, None)


def zigzag_periods(
    profile: ShipProfile, name: str, description: str, u: float, v_amp: float, r_amp: float, psi_switch: float, periods: int
) -> Primitive:
    """An excitation zig-zag (thesis tau3-tau8, tau17-tau20) of whole periods: it ends where the
    heading crosses zero after ``periods`` full swings, so it leaves on its entry course."""
    half = max(2.0 * psi_switch / max(r_amp, 1e-6) / profile.sample_time, 4.0)
    n = int((2 * periods + 2) * half * 3) + 100
    gen = mv.excitation_zigzag(profile, n, u, v_amp, r_amp, psi_switch)
    prim = make_primitive(profile, name, description, gen)
    psi = prim.track[:, 2]
    sp = gen.split_points
    if len(sp) < 2 * periods + 1:
        raise ProfileError(
            f"ship profile {profile.name!r}: the scenario's zig-zag {name} did not complete {periods} period(s) in {n} samples "
            f"({n * profile.sample_time:g} s): the ship does not swing its heading through +-{np.degrees(psi_switch):.0f} deg "
            "under the scenario's yaw moment; check the yaw row of the profile's parameters, or plan without --scenario"
        )
    a, b = sp[2 * periods - 1], sp[2 * periods]
    k = a + int(np.argmin(np.abs(psi[a : b + 1])))
    cmds = [
        f"steady at {u:.1f} m/s",
        f"zig-zag: yaw rate {np.degrees(r_amp):.1f} deg/s with sway {v_amp:.1f} m/s, reverse when the heading is "
        f"{np.degrees(psi_switch):.0f} deg off the base course; {periods} full period(s), end on the base course",
    ]
    return Primitive(
        name,
        description,
        profile,
        prim.inputs[:k],
        prim.nu[: k + 1],
        prim.track[: k + 1],
        [s for s in sp if s < k],
        "informative",
        cmds,
    )


def scenario_supports(profile: ShipProfile) -> bool:
    """Whether the section 9.4 scenario can be built for the ship: its zig-zags are force-level
    excitation zig-zags (thesis tau17-tau20) holding steady generalized forces, so they need a
    3-DOF ship with generalized-force or azimuth inputs
    (:data:`primitives.steady_forces.STEADY_FORCE_ACTUATORS`), not a rudder/propeller ship."""
    return has_steady_forces(profile)


def thesis_planning_scenario(profile: ShipProfile) -> tuple[list[Primitive], dict[str, int]]:
    """The three informative primitives of section 9.4 and their counts (three uses each).

    steep_zigzag_surge: short period, large yaw rate (like tau17/tau18 but steeper);
    wide_zigzag_surge: long period, small yaw rate (like tau19);
    wide_zigzag_sway: the ship crabs side to side (large alternating sway velocity) with only a
    small heading oscillation.
    """
    require_steady_forces(profile)  # see scenario_supports
    require_stable(profile)
    u = profile.cruise_speed_mps
    L = profile.length_m
    r_unit = u / L  # yaw-rate scale: 0.1 rad/s at 3 m/s for a 30 m ship
    prims = [
        zigzag_periods(
            profile,
            "steep_zigzag_surge",
            "steep zig-zag in surge (short period, large yaw rate)",
            u,
            0.1 * u,
            0.6 * r_unit,
            0.35,
            2,
        ),
        zigzag_periods(
            profile,
            "wide_zigzag_surge",
            "wide zig-zag in surge (long period, small yaw rate)",
            u,
            0.17 * u,
            0.3 * r_unit,
            0.75,
            1,
        ),
        zigzag_periods(
            profile,
            "wide_zigzag_sway",
            "wide zig-zag in sway (alternating sway, small heading swing)",
            u,
            0.27 * u,
            0.06 * r_unit,
            0.12,
            1,
        ),
    ]
    return prims, {p.name: 3 for p in prims}
