"""Library entry points of the mass / CoG estimator (the CLI is a thin layer over these)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diagnose.rollmass.estimate import METHODS, MassEstimate, estimate
from diagnose.rollmass.model import Load, load_profile
from diagnose.rollmass.output_error import start_values
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
    if not (0 < load.m < 1e6 and abs(load.zbar) < 1e3):
        raise UserError(f"--known-load {text!r}: give a finite mass > 0 kg and a height within the hull, in metres (z down), e.g. 0.2@-0.256")
    return load


def estimate_from_files(nominal: str | Path, calibration: str | Path, loaded: str | Path, known_load: str | Load,
                        profile: str | Path | None = None, method: str = "oe", z_f: float | None = None) -> MassEstimate:
    """Read three recordings and estimate the loaded dataset's mass change and CoG height with CIs."""
    if method not in METHODS:
        raise UserError(f"--method {method!r}: choose one of {', '.join(METHODS)}")
    cal = known_load if isinstance(known_load, Load) else parse_known_load(known_load)
    prof = load_profile(profile)
    recs = [read_roll_csv(p)[0] for p in (nominal, calibration, loaded)]
    try:
        return estimate(recs, prof.known, cal, method, with_ci=True, z_f=z_f, start=start_values(prof))
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:  # a fit that cannot start or diverges is said, never printed
        raise UserError(f"the {method} estimate failed on these recordings ({str(exc).splitlines()[0]}); "
                        "check --z-f, --known-load and that the three runs come from one ship") from None
