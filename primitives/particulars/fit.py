"""The per-sample model of a profile fitted to an MMG model's manoeuvres: one-step least squares,
then output error, as ``benchmarks/fit_kvlcc2.py`` fits the MARIN runs."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from primitives import jitloop
from primitives.goodness import fit_percent
from primitives.maneuvers import MAX_RUDDER_DEG
from primitives.particulars.document import RUDDER_RATE_DEG_S, profile_document
from primitives.particulars.inputs import Particulars
from primitives.particulars.mmg import MMGShip, Run, fixed_helm, run, zigzag_helm
from primitives.profile_document import profile_from_dict
from primitives.regressors import predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import model_signals, simulate


def excitation_runs(ship: MMGShip, speed: float, n0: float, ts: float) -> list[Run]:
    """The standard manoeuvres (IMO MSC.137(76)) the per-sample model is fitted to: a 35 deg turning
    circle, 10/10 and 20/20 zig-zags, and an engine step to half rpm with 10 deg rudder (it
    separates resistance from thrust). One side only: the MMG model is symmetric (x_G = 0, no
    propeller side force), so the port runs would mirror these."""
    rate, dmax = math.radians(RUDDER_RATE_DEG_S), math.radians(MAX_RUDDER_DEG)
    lengths = ship.length / speed / ts  # samples per ship length at the approach

    def go(name: str, helm, n_lengths: float) -> Run:
        return run(ship, name, helm, speed, int(n_lengths * lengths), ts, rate, dmax)

    runs = [
        go("tc35", fixed_helm(dmax, n0), 25),
        go("zz10", zigzag_helm(math.radians(10), 1.0, n0), 14),
        go("zz20", zigzag_helm(math.radians(20), 1.0, n0), 14),
        go("engine-half", fixed_helm(math.radians(10), n0, n_after=0.5 * n0, at=int(2 * lengths)), 14),
    ]
    if ship.layout == "pods":  # the pods' yaw moment from unequal thrust, which a rudder ship lacks (with
        # some steering: alone, unequal thrust turns the ship so little that its 1/spread weight magnified
        # the MMG integration's last digits and the equation-error start came out unstable)
        runs.append(go("pods-split", fixed_helm(math.radians(10), (n0, 0.6 * n0)), 14))
    return runs


def one_step_ls(profile: ShipProfile, runs: list[Run]) -> np.ndarray:
    """Equation-error start: per DOF least squares of nu(k+1) - nu(k) on the regressors, each run
    weighted by the spread of its own increments (a zig-zag weighs as much as a turning circle)."""
    phis, dys = [], []
    for r in runs:
        phi, dy = predictor_regressors(profile, r.nu, r.inputs, terms=profile.model)
        w = 1.0 / np.maximum(dy.std(axis=0), 1e-12)
        phis.append((phi, w)), dys.append(dy * w)
    th = np.zeros(profile.model.n_params)
    for i in range(3):
        s = profile.model.dof_slice(i)
        A = np.concatenate([phi[:, s] * w[i] for phi, w in phis])
        th[s] = np.linalg.lstsq(A, np.concatenate([d[:, i] for d in dys]), rcond=None)[0]
    return th


def straight_inputs(profile: ShipProfile, n0: float) -> dict[str, np.ndarray]:
    """The input signals of a straight course at ``n0`` [rev/s] on every shaft, rudders or pods amidships."""
    row = np.array([n0, 0.0] * len(profile.thrusters) if profile.actuator == "azimuth" else [0.0, n0])
    return profile.generalized_forces(row)


def balance_thrust(profile: ShipProfile, theta: np.ndarray, speed: float, n0: float) -> np.ndarray:
    """The thrust coefficient (Xnn, or a podded ship's Xtau) so that the model holds ``speed``
    [m/s] straight ahead at ``n0`` [rev/s]: the surge increment of every other term there,
    cancelled by that term (linear in its coefficient)."""
    th = theta.copy()
    j = profile.param_names.index("Xtau" if profile.actuator == "azimuth" else "Xnn")
    sig = model_signals(profile, np.array([speed, 0.0, 0.0]), np.array(0.0), straight_inputs(profile, n0))
    th[j] = 0.0
    rest = float(profile.model.increments(sig, th)[0])
    th[j] = 1.0
    th[j] = -rest / (float(profile.model.increments(sig, th)[0]) - rest)
    return th


def output_error(profile: ShipProfile, theta: np.ndarray, runs: list[Run], max_nfev: int = 15) -> np.ndarray:
    """Output-error least squares of every parameter on the open-loop simulated runs, each run's
    residual scaled by its own spread (batched finite-difference Jacobian through ``simulate``)."""
    # the fit simulates every run some max_nfev x (p + 1) times: each call is below jitloop's
    # threshold, their sum decides whether loading the compiled loop pays (as jitloop.use would)
    jitloop.use(max_nfev * (theta.size + 1) * sum(len(r.nu) for r in runs))
    scale = [np.std(r.nu, axis=0) * math.sqrt(len(r.nu)) + 1e-12 for r in runs]

    def parts(P: np.ndarray) -> list[np.ndarray]:
        out = []
        for r, s in zip(runs, scale):
            nu = simulate(profile, r.inputs, P, nu0=r.nu[0], batch=len(P), positions=False).nu
            out.append(((r.nu[None] - nu)[:, 1:] / s).reshape(len(P), -1))
        return out

    return relative_least_squares(parts, theta, max_nfev)


def relative_least_squares(parts, theta: np.ndarray, max_nfev: int) -> np.ndarray:
    """Least squares of the stacked residual ``parts(P)`` (one (batch, m) array per run for a batch of
    parameter rows P) over relative changes z of ``theta`` (P = (1 + z) theta, so z = 0 is the start
    and x_scale 0.05 sets the first trust region to 5 %: larger steps leave the stable region of the
    open-loop model), with a batched forward-difference Jacobian; non-finite residuals count 1e3."""
    typ = np.where(theta != 0, theta, 1e-9)  # signed: z = 0 is the start

    def resid(Z: np.ndarray) -> np.ndarray:
        P = (1.0 + np.atleast_2d(Z)) * typ
        with np.errstate(all="ignore"):
            R = np.concatenate(parts(P), axis=1)
        return np.where(np.isfinite(R), np.clip(R, -1e3, 1e3), 1e3)

    def jac(z: np.ndarray) -> np.ndarray:
        h = 1e-5
        Z = np.repeat(z[None], len(z) + 1, axis=0)
        Z[1:] += h * np.eye(len(z))
        R = resid(Z)
        return ((R[1:] - R[0]) / h).T

    sol = least_squares(lambda z: resid(z)[0], np.zeros_like(theta), jac=jac, method="trf", x_scale=0.05, max_nfev=max_nfev)
    return (1.0 + sol.x) * typ


def run_fit_percent(profile: ShipProfile, theta: np.ndarray, r: Run) -> tuple[float, float, float]:
    """Open-loop NRMSE fit % per DOF of the profile on one MMG run."""
    nu = simulate(profile, r.inputs, theta, nu0=r.nu[0], positions=False).nu[0]
    return tuple(float(x) for x in fit_percent(r.nu, nu))


def fit_profile(p: Particulars, ship: MMGShip, n0: float, ts: float, n_max: float, oe_nfev: int = 15) -> tuple[np.ndarray, dict]:
    """The per-sample model fitted to the MMG model's manoeuvres; per-run fit % as evidence."""
    shell = profile_from_dict(profile_document(p, ts, n0, n_max), p.name)
    runs = excitation_runs(ship, p.speed, n0, ts)
    theta = balance_thrust(shell, one_step_ls(shell, runs), p.speed, n0)
    if oe_nfev:
        theta = balance_thrust(shell, output_error(shell, theta, runs, oe_nfev), p.speed, n0)
    if not np.all(np.isfinite(theta)):
        raise FloatingPointError("the fit of the per-sample model diverged")
    return theta, {r.name: run_fit_percent(shell, theta, r) for r in runs}
