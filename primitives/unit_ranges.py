"""Plausible ranges of profile values whose unit is easily mistaken (degrees for radians, rev/s
for rpm): a value far outside its key's unit range is refused with the reading that would fit.

A rudder turns at most 90 deg (1.571 rad) and steers to 30-45 deg; an azimuth thruster turns a
full circle (2 pi rad); a steering gear moves at least 2.32 deg/s (SOLAS II-1/29: 35 deg one side
to 30 deg the other in 28 s). A number far outside these in the key's unit is almost always the
other unit: refused in one line naming the file, the field and the value in the key's unit.
"""

from __future__ import annotations

import math

from primitives.errors import UserError

RUDDER_MAX_RAD = math.pi / 2  # delta, delta1, delta2: no rudder or pod turns further from midships
AZIMUTH_MAX_RAD = 2 * math.pi  # alpha1, alpha2: an azimuth thruster turns a full circle
MIN_MAX_RUDDER_DEG = 5.0  # below this, [helm] max_rudder_deg is a radian value (35 deg = 0.611 rad)
MIN_RUDDER_RATE_DEG_S = 0.5  # below this, [helm] rudder_rate_deg_s is a rad/s value (2.32 deg/s = 0.0405 rad/s)
MIN_RPM_SHARE = 0.05  # an rpm below 5 % of the engine's top rev/s x 60 is a rev/s value
# a recorded yaw rate r beyond this is deg/s (11.5 deg/s: a tanker turns at under 1 deg/s, the podded naval vessel
# at 0.06 rad/s): the one bound of the steering and yawid readers
YAW_RATE_MAX_RAD_S = 0.2


def _angle_bound(input_name: str) -> float | None:
    if input_name.startswith("delta"):
        return RUDDER_MAX_RAD
    if input_name.startswith("alpha"):
        return AZIMUTH_MAX_RAD
    return None


def check_angle_limits(name: str, lo: float, hi: float, what: str, err: type[UserError]) -> None:
    """``input_limits.<name> = [lo, hi]`` of an angle input (delta*: rudder, alpha*: azimuth) in
    radians: beyond the angle's physical range it was given in degrees."""
    bound = _angle_bound(name)
    if bound is None or max(abs(lo), abs(hi)) <= bound + 1e-3:
        return
    kind = (
        "rudder or pod angle (at most 90 deg = 1.571 rad)"
        if bound == RUDDER_MAX_RAD
        else "azimuth angle (a full circle is 6.283 rad)"
    )
    raise err(
        f"{what} = [{lo:g}, {hi:g}] is in radians, and that is no {kind}: if these are degrees, write "
        f"{name} = [{math.radians(lo):.4f}, {math.radians(hi):.4f}]"
    )


def check_max_rudder_deg(value: float, src: str, err: type[UserError]) -> None:
    if value < MIN_MAX_RUDDER_DEG:
        raise err(
            f"{src}: field 'helm.max_rudder_deg' = {value:g} is in degrees, and no rudder steers to at most {value:g} deg "
            f"(ships: 30-45 deg): if it is radians, write max_rudder_deg = {math.degrees(value):.1f}"
        )
    if value > 90.0:
        raise err(
            f"{src}: field 'helm.max_rudder_deg' = {value:g} deg is beyond 90 deg, where no rudder turns: give the "
            "largest rudder angle in degrees, e.g. 35"
        )


def check_rudder_rate(value: float, src: str, err: type[UserError]) -> None:
    if value < MIN_RUDDER_RATE_DEG_S:
        raise err(
            f"{src}: field 'helm.rudder_rate_deg_s' = {value:g} is in deg/s, far below the SOLAS II-1/29 minimum of "
            f"2.32 deg/s: if it is rad/s, write rudder_rate_deg_s = {math.degrees(value):.3g}"
        )


def check_rpm(key: str, value: float, rps_max: float, src: str, err: type[UserError]) -> None:
    """[engine] mcr_rpm / approach_rpm against the top of the propeller's rev/s range."""
    if math.isfinite(rps_max) and value / 60.0 < MIN_RPM_SHARE * rps_max:
        raise err(
            f"{src}: field 'engine.{key}' = {value:g} is in rpm ({value / 60:.3g} rev/s), a trickle against the "
            f"propeller's {rps_max:g} rev/s ({rps_max * 60:g} rpm) top speed: if it is rev/s, write {key} = {value * 60:.4g}"
        )
