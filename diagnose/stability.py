"""Why a baseline model cannot be simulated: the unstable mode and the parameter that makes it so.

A diagnosis starts by simulating the given baseline on the recordings; when that diverges the
fault is the profile's (or --params') parameters, not the recording, and a refit (--fit-on) cannot
help: it starts from the same parameters and simulates them first. :func:`check_baseline` finds
the divergence before the diagnosis does and says which motion grows (surge, sway, yaw, from the
eigenvector of the linearised per-sample model (3.60) at the run's speed) and which parameter
drives it (its share of the growing eigenvalue, by eigenvalue sensitivity: a damping of the wrong
sign, or a coupling that makes the straight course unstable though every damping is stable).
"""

from __future__ import annotations

import numpy as np

from diagnose.model import AugmentedModel, diverges, prepare
from diagnose.recording import Recording, RecordingError
from primitives.ship import ShipProfile
from primitives.stability import doubling_time, straight_course_mode


def unstable_mode(profile: ShipProfile, theta: np.ndarray, rec: Recording) -> tuple[str, float, str, float, str] | None:
    """:func:`primitives.stability.straight_course_mode` at the run's median speed and inputs."""
    speed = float(np.median(np.hypot(rec.y[:, 0], rec.y[:, 1])))
    inputs = {k: float(np.median(rec.channels[k])) for k in profile.inputs if k in rec.channels}
    return straight_course_mode(profile, theta, speed, inputs)


def check_baseline(profile: ShipProfile, theta: np.ndarray, recs: list[Recording], where: str) -> None:
    """Refuse, naming the profile (``where``: its file or name, and --params), the growing motion
    and the parameter at fault, a baseline whose simulation diverges on one of ``recs``."""
    model = AugmentedModel(profile, theta, [])
    for rec in recs:
        if not diverges(model, [prepare(profile, rec)], model.p0()):
            continue
        mode = unstable_mode(profile, theta, rec)
        if mode is None:
            raise RecordingError(
                f"{where}: the baseline model cannot be simulated on {rec.source} (it diverges) although its straight-course "
                "motion is stable (the run's inputs drive it out of range); check the profile's parameters and input "
                "limits against this run"
            )
        dofs, growth, name, value, how = mode
        t2 = doubling_time(growth, profile.sample_time)
        if how == "damping":
            what, why = f"{dofs} motion is unstable", "(its damping must be negative)"
        else:
            what = f"{dofs} motion is unstable through their coupling" + (" (course instability)" if dofs == "sway-yaw" else "")
            why = (
                f"through the {dofs} coupling, not a damping sign (the coupling terms outweigh the product of the "
                "dampings" + (", Yuv Nur - Yur Nuv of the wrong sign" if dofs == "sway-yaw" else "") + ")"
            )
        raise RecordingError(
            f"{where}: the baseline's {what} at the run's speed (a disturbance grows x{growth:.4g} per "
            f"{profile.sample_time:g} s sample, doubling every {t2:.3g} s), so it cannot be simulated on {rec.source}; "
            f"parameter {name} = {value:+.4g} drives it {why}: correct it in the profile or "
            "--params (--fit-on starts from these values and cannot)"
        )
