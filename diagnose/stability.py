"""Why a baseline model cannot be simulated: the unstable mode and the parameter that makes it so.

A diagnosis starts by simulating the given baseline on the recordings; when that diverges the
fault is the profile's (or --params') parameters, not the recording, and a refit (--fit-on) cannot
help: it starts from the same parameters and simulates them first. :func:`check_baseline` finds
the divergence before the diagnosis does and says which motion grows (surge, sway, yaw, from the
eigenvector of the linearised per-sample model (3.60) at the run's speed) and which parameter
drives it (its share of the growing mode's own damping, d nu_i(k+1) / d nu_i(k) - 1).
"""

from __future__ import annotations

import math

import numpy as np

from diagnose.model import AugmentedModel, diverges, prepare
from diagnose.recording import Recording, RecordingError
from primitives.ship import DOFS, ShipProfile
from primitives.simulate import model_signals


def _step(profile: ShipProfile, theta: np.ndarray, nu: np.ndarray, inputs: dict[str, float]) -> np.ndarray:
    sig = model_signals(profile, np.asarray(nu, float), np.array(0.0), {k: np.array(v) for k, v in inputs.items()})
    return nu + np.array([float(x) for x in profile.model.increments(sig, theta)])


def linearised(profile: ShipProfile, theta: np.ndarray, speed: float, inputs: dict[str, float]) -> np.ndarray:
    """Jacobian (3 x 3) of the per-sample map nu(k) -> nu(k+1) on a straight course at ``speed``
    (central differences, steps scaled to the ship: speed/100 in u, v and speed/(100 L) in r)."""
    nu0 = np.array([speed, 0.0, 0.0])
    h = np.array([speed, speed, speed / profile.length_m]) * 1e-2 + 1e-9
    A = np.zeros((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = h[j]
        A[:, j] = (_step(profile, theta, nu0 + e, inputs) - _step(profile, theta, nu0 - e, inputs)) / (2 * h[j])
    return A


def unstable_mode(profile: ShipProfile, theta: np.ndarray, rec: Recording) -> tuple[str, float, str, float] | None:
    """(DOF, growth per sample, parameter, its value) of the fastest growing mode at the run's
    median speed and inputs, or None when the straight-course motion is stable."""
    speed = float(np.median(np.hypot(rec.y[:, 0], rec.y[:, 1])))
    inputs = {k: float(np.median(rec.channels[k])) for k in profile.inputs if k in rec.channels}
    with np.errstate(all="ignore"):
        A = linearised(profile, theta, speed, inputs)
    if not np.all(np.isfinite(A)):
        return None
    lam, vec = np.linalg.eig(A)
    i = int(np.argmax(np.abs(lam)))
    growth = float(abs(lam[i]))
    if growth <= 1.0:
        return None
    scale = np.array([speed, speed, speed / profile.length_m])  # a common size for m/s and rad/s
    dof = int(np.argmax(np.abs(vec[:, i]) / scale))
    names = profile.param_names
    lo = profile.model.offsets[dof]
    own = range(lo, lo + len(profile.model_terms[dof]))
    share = []
    for j in own:  # each parameter's part of this DOF's own damping (the model is linear in theta)
        th = np.array(theta, float)
        th[j] = 0.0
        with np.errstate(all="ignore"):
            share.append(A[dof, dof] - linearised(profile, th, speed, inputs)[dof, dof])
    j = list(own)[int(np.nanargmax(share))]
    return DOFS[dof], growth, names[j], float(theta[j])


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
                "limits against this run")
        dof, growth, name, value = mode
        t2 = math.log(2.0) / math.log(growth) * profile.sample_time
        raise RecordingError(
            f"{where}: the baseline's {dof} motion is unstable at the run's speed (a disturbance grows x{growth:.4g} per "
            f"{profile.sample_time:g} s sample, doubling every {t2:.3g} s), so it cannot be simulated on {rec.source}; "
            f"parameter {name} = {value:+.4g} drives it (its damping must be negative): correct it in the profile or "
            "--params (--fit-on starts from these values and cannot)")
