"""Library entry points of the mass / CoG estimator (the CLI is a thin layer over these)."""

from __future__ import annotations

from pathlib import Path

from diagnose.rollmass.estimate import METHODS, MassEstimate, estimate
from diagnose.rollmass.model import Load, load_profile
from diagnose.rollmass.recording import read_roll_csv
from primitives.errors import UserError


def parse_known_load(text: str) -> Load:
    """``"KG@M"`` (mass in kg at body-frame height in m, z down) -> :class:`Load`."""
    if "@" not in text:
        raise UserError(f"--known-load {text!r}: unknown load height; write KG@M, e.g. 0.2@-0.256 (height in the body frame, z down)")
    kg, _, m = text.partition("@")
    try:
        load = Load(float(kg), float(m))
    except ValueError:
        raise UserError(f"--known-load {text!r}: not numbers; write KG@M, e.g. 0.2@-0.256") from None
    if not load.m > 0:
        raise UserError(f"--known-load {text!r}: the calibration mass must be positive")
    return load


def estimate_from_files(nominal: str | Path, calibration: str | Path, loaded: str | Path, known_load: str | Load,
                        profile: str | Path | None = None, method: str = "improved", z_f: float | None = None) -> MassEstimate:
    """Read three recordings and estimate the loaded dataset's mass change and CoG height with CIs."""
    if method not in METHODS:
        raise UserError(f"--method {method!r}: choose one of {', '.join(METHODS)}")
    cal = known_load if isinstance(known_load, Load) else parse_known_load(known_load)
    prof = load_profile(profile)
    recs = [read_roll_csv(p)[0] for p in (nominal, calibration, loaded)]
    return estimate(recs, prof.known, cal, method, with_ci=True, z_f=z_f)
