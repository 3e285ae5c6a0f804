"""The Monte Carlo's validation and scoring (Ljungberg (2022) section 9.1.2): the seeded
cross-validation input unlike any primitive, each estimate's simulation RMSE against the
noise-free true output with its divergence flag, and the parameter errors against the true
parameters, gathered into an :class:`expdesign.mc_result.MCResult`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from expdesign import oekernel
from expdesign.estimators import OEData
from expdesign.mc_result import MCResult
from primitives.ship import ShipProfile
from primitives.simulate import simulate
from primitives.steady_forces import steady_forces_many

if TYPE_CHECKING:
    from expdesign.montecarlo import MCShared

EXPLODE = 100.0  # a validation output this many times the true one's maximum has diverged


def validation_input(profile: ShipProfile, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Seeded cross-validation input unlike any primitive: multisine surge speed, a smoothed
    random binary sway and a multisine yaw rate reference, turned into feed-forward forces.
    Returns (inputs (n, m), nu0 (3,))."""
    rng = np.random.default_rng([seed, 0x5EED])
    t = np.arange(n) / n
    c, L = profile.cruise_speed_mps, profile.length_m

    def multisine(k: int) -> np.ndarray:
        f = rng.choice(np.arange(2, 12), k, replace=False)
        ph = rng.uniform(0, 2 * np.pi, k)
        s = np.sum(np.sin(2 * np.pi * f[:, None] * t + ph[:, None]), axis=0)
        return s / np.abs(s).max()

    if profile.actuator == "rudder_propeller":  # no force allocation: the same idea in helm terms
        from primitives.helm import validation_inputs

        return validation_inputs(profile, multisine)

    prbs = np.repeat(rng.choice([-1.0, 1.0], n // 50 + 1), 50)[:n]
    prbs = np.convolve(prbs, np.ones(15) / 15, mode="same")
    u = c * (0.7 + 0.3 * multisine(3))
    v = 0.1 * c * prbs
    r = 0.3 * c / L * multisine(3)
    forces = steady_forces_many(profile, u, v, r)  # each sample's steady_forces, in one batch
    return profile.allocate(forces[:, 0], forces[:, 1], forces[:, 2]), np.array([u[0], v[0], r[0]])


def validate(sh: MCShared, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validation RMSE per DOF (B, 3) of the estimated models against the noise-free true
    output, and the diverged flags (B,)."""
    b = theta.shape[0]
    finite = np.isfinite(theta).all(axis=1)
    th = np.where(finite[:, None], theta, 0.0)
    bound = EXPLODE * np.abs(sh.val_true).max()
    rmse = np.full((b, 3), np.inf)
    val = OEData(sh.val_inputs[None], np.broadcast_to(sh.val_nu0, (b, 3)), sh.val_true[None])
    calm = oekernel.calm_runs(sh.profile, sh.predictor, [val])
    if calm is not None:  # time-major, compiled: the same simulation, sums in the same order, made as it steps
        over = np.zeros(b, np.bool_)  # |x| <= bound is |x| < the next double above it (NaN and inf fail both)
        coef = np.ascontiguousarray(th.T)
        sim_t, sums = oekernel.run_scored(
            calm.in_t[0],
            calm.y_t[0],
            calm.nu0[0],
            np.zeros(b, np.int64),
            coef,
            calm.prog[0],
            calm.speed,
            0,
            np.nextafter(bound, np.inf),
            over,
        )
        diverged = ~finite | over
        good = np.flatnonzero(~diverged)
        rmse[good] = np.sqrt(sums[good] / sim_t.shape[0])
        return rmse, diverged
    with np.errstate(all="ignore"):
        sim = simulate(sh.profile, sh.val_inputs, th, terms=sh.predictor, nu0=sh.val_nu0, batch=b, positions=False).nu
    with np.errstate(invalid="ignore"):
        diverged = ~finite | ~(np.abs(sim) <= bound).all(axis=(1, 2))  # NaN and inf too
    good = np.flatnonzero(~diverged)
    rmse[good] = np.sqrt(np.mean((sim[good] - sh.val_true) ** 2, axis=1))  # per run over the samples in order
    return rmse, diverged


def scored(
    sh: MCShared,
    design: str,
    ids: list[int],
    theta: np.ndarray,
    estimator: str,
    notes: list[str],
    validation: tuple[np.ndarray, np.ndarray] | None = None,
) -> MCResult:
    """Validation and parameter errors of the estimates ``theta`` of runs ``ids`` (``validation``:
    their :func:`validate` result when already computed)."""
    sim_rmse, diverged = validate(sh, theta) if validation is None else validation
    prm = np.full(len(ids), np.nan)
    if sh.theta0 is not None:
        with np.errstate(all="ignore"):  # per run: a mean over a row's contiguous parameters, numpy's sum of each row
            e = (theta - sh.theta0) / np.abs(sh.theta0)
            prm[:] = np.where(np.isfinite(e).all(axis=1), np.sqrt(np.mean(e * e, axis=1)), np.inf)
    return MCResult(
        design,
        np.array(ids, dtype=np.int64),
        theta,
        prm,
        sim_rmse,
        diverged,
        sh.config.runs,
        sh.param_names,
        sh.theta0,
        notes,
        estimator,
    )
