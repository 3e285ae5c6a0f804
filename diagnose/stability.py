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


def _contributions(profile: ShipProfile, theta: np.ndarray, speed: float, inputs: dict[str, float], A: np.ndarray,
                   w: np.ndarray, v: np.ndarray, lam: complex) -> np.ndarray:
    """Each parameter's share of the growth |lambda| of the mode (right eigenvector v, left w), by
    eigenvalue sensitivity: the model is linear in theta, so theta_j's part of A is A less A with
    theta_j = 0, dA_j, and its part of lambda is w^H dA_j v / w^H v; of |lambda|, the component of
    that along lambda (first order)."""
    wv = complex(np.conj(w) @ v)
    along = np.conj(lam) / abs(lam)
    total = np.zeros(len(theta))
    for j in range(len(theta)):
        th = np.array(theta, float)
        th[j] = 0.0
        with np.errstate(all="ignore"):
            dA = A - linearised(profile, th, speed, inputs)
        if not np.all(np.isfinite(dA)):
            continue
        total[j] = float(np.real(along * (np.conj(w) @ dA @ v) / wv))
    return total


def _own_damping(profile: ShipProfile, theta: np.ndarray, speed: float, inputs: dict[str, float], A: np.ndarray,
                 dof: int) -> tuple[str, float]:
    """(name, value) of the parameter of DOF ``dof``'s own equation with the largest part of its
    damping A[dof, dof] - 1 (the model is linear in theta)."""
    lo = profile.model.offsets[dof]
    own = range(lo, lo + len(profile.model_terms[dof]))
    share = []
    for j in own:
        th = np.array(theta, float)
        th[j] = 0.0
        with np.errstate(all="ignore"):
            share.append(A[dof, dof] - linearised(profile, th, speed, inputs)[dof, dof])
    j = list(own)[int(np.nanargmax(share))]
    return profile.param_names[j], float(theta[j])


def unstable_mode(profile: ShipProfile, theta: np.ndarray, rec: Recording) -> tuple[str, float, str, float, str] | None:
    """(DOFs, growth per sample, parameter, its value, how) of the fastest growing mode at the run's
    median speed and inputs, or None when the straight-course motion is stable. how: 'damping' when
    a DOF's own damping is unstable (|A[d, d]| > 1): that DOF and its parameter with the largest part
    of it; else 'coupling' (every damping stable, e.g. a course instability): the parameter with the
    largest share of the growth (:func:`_contributions`) and the pair of motions it couples."""
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
    lam_l, wvec = np.linalg.eig(A.T)
    w = wvec[:, int(np.argmin(np.abs(lam_l - lam[i])))]
    own = np.flatnonzero(np.abs(np.diag(A)) > 1.0)
    if len(own):  # a damping of the wrong sign: wrong in itself, whatever the coupling adds
        dof = int(own[np.argmax(np.abs(np.diag(A))[own])])
        return DOFS[dof], growth, *_own_damping(profile, theta, speed, inputs, A, dof), "damping"
    # every damping is stable: a coupling makes the mode grow; the parameter with the largest
    # share of the growth, and the motions it couples (the mode's sensitivity to A's off-diagonal)
    total = _contributions(profile, theta, speed, inputs, A, w, vec[:, i], lam[i])
    j = int(np.nanargmax(total))
    sens = np.abs(np.outer(np.conj(w), vec[:, i]) * (A - np.diag(np.diag(A))))
    a, b = sorted(np.unravel_index(int(np.argmax(sens)), sens.shape))
    return f"{DOFS[a]}-{DOFS[b]}", growth, profile.param_names[j], float(theta[j]), "coupling"


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
        dofs, growth, name, value, how = mode
        t2 = math.log(2.0) / math.log(growth) * profile.sample_time
        if how == "damping":
            what, why = f"{dofs} motion is unstable", "(its damping must be negative)"
        else:
            what = f"{dofs} motion is unstable through their coupling" + (" (course instability)" if dofs == "sway-yaw" else "")
            why = (f"through the {dofs} coupling, not a damping sign (the coupling terms outweigh the product of the "
                   "dampings" + (", Yuv Nur - Yur Nuv of the wrong sign" if dofs == "sway-yaw" else "") + ")")
        raise RecordingError(
            f"{where}: the baseline's {what} at the run's speed (a disturbance grows x{growth:.4g} per "
            f"{profile.sample_time:g} s sample, doubling every {t2:.3g} s), so it cannot be simulated on {rec.source}; "
            f"parameter {name} = {value:+.4g} drives it {why}: correct it in the profile or "
            "--params (--fit-on starts from these values and cannot)")
