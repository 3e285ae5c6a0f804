"""Straight-course stability of a profile's model: the unstable mode and the parameter behind it.

The per-sample model nu(k+1) = nu(k) + Phi(k)^T theta (Ljungberg 2022, eq. 3.60, 9.1) is
linearised on a straight course; an eigenvalue |lambda| > 1 of its Jacobian is a motion that
grows by itself. :func:`straight_course_mode` says which motion (the eigenvector) and which
parameter drives it (by eigenvalue sensitivity); :func:`require_stable` refuses a profile whose
simulation or instrument set cannot be simulated for a manoeuvre.
"""

from __future__ import annotations

import math

import numpy as np

from primitives.ship import DOFS, ProfileError, ShipProfile
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


def _contributions(
    profile: ShipProfile,
    theta: np.ndarray,
    speed: float,
    inputs: dict[str, float],
    A: np.ndarray,
    w: np.ndarray,
    v: np.ndarray,
    lam: complex,
) -> np.ndarray:
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


def _own_damping(
    profile: ShipProfile, theta: np.ndarray, speed: float, inputs: dict[str, float], A: np.ndarray, dof: int
) -> tuple[str, float]:
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


def straight_course_mode(
    profile: ShipProfile, theta: np.ndarray, speed: float, inputs: dict[str, float]
) -> tuple[str, float, str, float, str] | None:
    """(DOFs, growth per sample, parameter, its value, how) of the fastest growing mode on a straight
    course at ``speed`` with ``inputs``, or None when that motion is stable (or cannot be
    linearised). how: 'damping' when a DOF's own damping is unstable (|A[d, d]| > 1): that DOF and
    its parameter with the largest part of it; else 'coupling' (every damping stable, e.g. a course
    instability): the parameter with the largest share of the growth and the pair of motions it couples."""
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


def doubling_time(growth: float, sample_time: float) -> float:
    """Seconds in which a mode growing ``growth`` per sample doubles."""
    return math.log(2.0) / math.log(growth) * sample_time


def require_stable(profile: ShipProfile) -> None:
    """Refuse, in one line naming the profile, the parameter set, the parameter and the fix, a
    profile whose manoeuvres cannot be simulated: a damping of the wrong sign, or a straight-course
    instability that doubles a disturbance before the ship has sailed one ship length at cruise
    speed (real course-unstable ships, KVLCC2 among them, take several lengths: their manoeuvres
    are simulated as given). Planar profiles only; checked at cruise speed, inputs zero."""
    if not profile.planar:
        return
    inputs = dict.fromkeys((*profile.inputs, "tau_x", "tau_y", "tau_n"), 0.0)
    one_length_s = profile.length_m / profile.cruise_speed_mps
    for name in dict.fromkeys((profile.simulation_set, profile.instrument_set)):
        mode = straight_course_mode(profile, profile.params(name), profile.cruise_speed_mps, inputs)
        if mode is None:
            continue
        dofs, growth, param, value, how = mode
        t2 = doubling_time(growth, profile.sample_time)
        if how == "coupling" and t2 >= one_length_s:
            continue
        why = "its damping must be negative" if how == "damping" else f"the {dofs} coupling outweighs the dampings"
        raise ProfileError(
            f"ship profile {profile.name!r}: parameter set [parameters.{name}] makes the {dofs} motion unstable at cruise "
            f"speed (a disturbance grows x{growth:.4g} per {profile.sample_time:g} s sample, doubling every {t2:.3g} s), so "
            f"no manoeuvre can be simulated: {param} = {value:+.4g} drives it ({why}); correct it in the profile"
        )
