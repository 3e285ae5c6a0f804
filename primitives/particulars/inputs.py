"""What a user gives ``shiptrial profile new``, and the checks that refuse particulars no ship has."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from primitives.errors import UserError
from primitives.library import KNOT
from primitives.particulars import regressions as rg

# single screw and rudder; twin screws with a rudder behind each; two steerable pods (azimuth units)
ACTUATORS = ("rudder_propeller", "twin_screw", "azimuth")


class ParticularsError(UserError):
    """A main particular out of the range ships have, or one the chosen actuator needs missing."""


@dataclass(frozen=True)
class Particulars:
    """What an owner or a yard knows before the trial [m, -, kn, m^2, m, -, rpm, kW]."""

    name: str
    length: float
    beam: float
    draught: float
    cb: float
    speed_kn: float
    rudder_area: float | None = None
    prop_diameter: float | None = None
    pitch_ratio: float | None = None
    rpm: float | None = None
    mcr_kw: float | None = None
    actuator: str = "rudder_propeller"

    @property
    def hull(self) -> rg.Hull:
        return rg.Hull(self.length, self.beam, self.draught, self.cb)

    @property
    def speed(self) -> float:
        return self.speed_kn * KNOT


def _positive(name: str, value: float | None, unit: str) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ParticularsError(f"--{name} {value!r}: must be a number > 0 {unit}".rstrip())


NAME = re.compile(r"[A-Za-z0-9_-]+")  # the profile's name: a file stem and a one-line TOML comment


def _check_name(name: str) -> None:
    """The profile's name: a file stem, and not a bundled profile's (plans, exports and reports would name a bundled
    ship for this one; export looks the draught up by it)."""
    if not NAME.fullmatch(name):
        raise ParticularsError(f"--name {name!r}: use letters, digits, '_' and '-' only (e.g. my-coaster)")
    from primitives.ship import builtin_profiles

    if name.lower() in builtin_profiles():
        raise ParticularsError(f"--name {name!r}: a bundled profile's name ({', '.join(builtin_profiles())}); choose another")


def check_particulars(p: Particulars) -> None:
    """Refuse particulars no ship has, one line naming the value and the plausible range."""
    _check_name(p.name)
    if p.actuator not in ACTUATORS:
        raise ParticularsError(
            f"--actuator {p.actuator!r}: must be rudder_propeller (single screw, one rudder), twin_screw (two screws,"
            " two rudders) or azimuth (two steerable pods)"
        )
    if p.actuator == "azimuth" and p.rudder_area is not None:
        raise ParticularsError(
            f"--rudder-area {p.rudder_area:g}: an azimuth ship steers with its pods and has no rudder; leave --rudder-area"
            " out (the pods' housings are sized from --propeller-diameter)"
        )
    for name, val, unit in (
        ("length", p.length, "m"),
        ("beam", p.beam, "m"),
        ("draught", p.draught, "m"),
        ("block-coefficient", p.cb, ""),
        ("speed", p.speed_kn, "kn"),
        ("rudder-area", p.rudder_area, "m^2"),
        ("propeller-diameter", p.prop_diameter, "m"),
        ("pitch-ratio", p.pitch_ratio, ""),
        ("rpm", p.rpm, "rpm"),
        ("mcr-kw", p.mcr_kw, "kW"),
    ):
        _positive(name, val, unit)
    if not 0.35 <= p.cb <= 0.9:
        raise ParticularsError(f"--block-coefficient {p.cb:g}: outside 0.35-0.9, the range of displacement ships")
    if not 3.0 <= p.length / p.beam <= 9.0:
        raise ParticularsError(
            f"--beam {p.beam:g} m: L/B {p.length / p.beam:.2f} with the length {p.length:g} m; ships have L/B 3-9 "
            f"({p.length / 9:.4g}-{p.length / 3:.4g} m of beam for this length)"
        )
    if not 1.5 <= p.beam / p.draught <= 5.0:
        raise ParticularsError(
            f"--draught {p.draught:g} m: B/T {p.beam / p.draught:.2f} with the beam {p.beam:g} m; ships have B/T 1.5-5 "
            f"({p.beam / 5:.4g}-{p.beam / 1.5:.4g} m of draught for this beam)"
        )
    lt = p.length * p.draught
    if p.rudder_area is not None and not 0.01 * lt <= p.rudder_area <= 0.05 * lt:
        raise ParticularsError(
            f"--rudder-area {p.rudder_area:g} m^2: {100 * p.rudder_area / lt:.2g} % of L*T; rudders are 1-5 % of L*T "
            f"({0.01 * lt:.4g}-{0.05 * lt:.4g} m^2 for this ship)"
        )
    if p.prop_diameter is not None and not 0.4 * p.draught <= p.prop_diameter <= 0.8 * p.draught:
        raise ParticularsError(
            f"--propeller-diameter {p.prop_diameter:g} m: {p.prop_diameter / p.draught:.2f} x the draught {p.draught:g} m; "
            f"screws are 0.4-0.8 x the draught ({0.4 * p.draught:.3g}-{0.8 * p.draught:.3g} m)"
        )
    if p.actuator != "rudder_propeller" and p.prop_diameter is not None and p.prop_diameter > 0.5 * p.beam:
        raise ParticularsError(
            f"--propeller-diameter {p.prop_diameter:g} m: two screws a quarter beam off the centre line are"
            f" {0.5 * p.beam:.3g} m apart with the beam {p.beam:g} m; give at most {0.5 * p.beam:.3g} m"
        )
    if p.pitch_ratio is not None and not 0.5 <= p.pitch_ratio <= 1.4:
        raise ParticularsError(f"--pitch-ratio {p.pitch_ratio:g}: outside 0.5-1.4, the range of the Wageningen B-series")
    fn = p.speed / math.sqrt(9.81 * p.length)
    if fn < 0.05:
        raise ParticularsError(
            f"--speed {p.speed_kn:g} kn: Froude number {fn:.3f} on a {p.length:g} m hull; trials are sailed at a service "
            f"speed, Froude number 0.05-0.45 ({0.05 * math.sqrt(9.81 * p.length) / KNOT:.1f}-"
            f"{0.45 * math.sqrt(9.81 * p.length) / KNOT:.1f} kn)"
        )
    if fn > 0.45:
        raise ParticularsError(
            f"--speed {p.speed_kn:g} kn: Froude number {fn:.2f} on a {p.length:g} m hull; a displacement ship's regressions "
            f"hold below 0.45 (at most {0.45 * math.sqrt(9.81 * p.length) / KNOT:.1f} kn)"
        )
