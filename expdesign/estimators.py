"""Least-squares and instrumental-variable estimators of the block-diagonal predictor (9.2)/(3.60).

The predictor is ``y(k+1) - y(k) = Phi(k)^T theta`` with one block of regressors per DOF, so each
DOF is solved on its own (block-diagonal normal equations). The IV estimate of DOF i is

    theta_i = (sum Z~_i(k) Phi_i(k)^T)^-1 sum Z~_i(k) (y_i(k+1) - y_i(k)),

with instruments Z built from a noise-free simulation (the profile's instrument set first, then
the predictor simulated with the latest estimate until it settles), and Z~ the instruments with
their mean removed: not at all, per sub-experiment (7.19) or over the whole experiment (7.20).
Every array carries a leading batch axis B of Monte Carlo realisations; the solves are batched
(``einsum`` + ``numpy.linalg.solve``), so 500 realisations cost about as much as one Python loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from expdesign.errors import DesignError
from primitives.information import MEAN_SUBTRACTION, PrimitiveInfo
from primitives.regressors import block_mask, instruments, predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import simulate


@dataclass
class Segment:
    """One sub-experiment: inputs (N, m) or (B, N, m), measured y (B, N+1, 3), heading psi (B, N+1)
    and the initial state nu0 ((3,) or (B, 3)) the instruments are simulated from."""

    inputs: np.ndarray
    y: np.ndarray
    nu0: np.ndarray
    psi: np.ndarray | None = None

    @property
    def batch(self) -> int:
        return self.y.shape[0]


@dataclass
class Estimate:
    """theta (B, p); residuals (B, N_total, 3) of all segments stacked; cov (B, p, p) estimated
    covariance (block diagonal); sigma2 (B, 3) residual variances; iterations of the IV loop."""

    theta: np.ndarray
    residuals: np.ndarray
    cov: np.ndarray
    sigma2: np.ndarray
    iterations: int
    converged: bool
    notes: list[str] = field(default_factory=list)


def _batched_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve a x = b for a batch; singular systems fall back to the pseudo-inverse."""
    try:
        return np.linalg.solve(a, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("bij,bj->bi", np.linalg.pinv(a), b)


def _subtract_mean(zs: list[np.ndarray], mean_subtraction: str) -> list[np.ndarray]:
    """Instrument mean removal: 'none', 'batchwise' (7.19) or 'complete' (7.20)."""
    if mean_subtraction == "none":
        return zs
    if mean_subtraction == "batchwise":
        return [z - z.mean(axis=1, keepdims=True) for z in zs]
    n = sum(z.shape[1] for z in zs)
    zbar = sum(z.sum(axis=1, keepdims=True) for z in zs) / n
    return [z - zbar for z in zs]


def solve_blocks(
    profile: ShipProfile, phis: list[np.ndarray], zs: list[np.ndarray], targets: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Block-diagonal IV solve over stacked segments (Z = Phi gives least squares).

    Returns theta (B, p), residuals (B, N, 3), cov (B, p, p), sigma2 (B, 3).
    """
    terms = profile.predictor
    phi = np.concatenate(phis, axis=1)
    z = np.concatenate(zs, axis=1)
    tgt = np.concatenate(targets, axis=1)
    bsz, n, p = phi.shape
    theta = np.zeros((bsz, p))
    cov = np.zeros((bsz, p, p))
    res = np.empty_like(tgt)
    sigma2 = np.zeros((bsz, 3))
    for i in range(3):
        s = terms.dof_slice(i)
        a = np.einsum("bki,bkj->bij", z[..., s], phi[..., s])
        rhs = np.einsum("bki,bk->bi", z[..., s], tgt[..., i])
        th = _batched_solve(a, rhs)
        theta[:, s] = th
        res[..., i] = tgt[..., i] - np.einsum("bki,bi->bk", phi[..., s], th)
        sigma2[:, i] = np.mean(res[..., i] ** 2, axis=1)
        try:
            ainv = np.linalg.inv(a)
        except np.linalg.LinAlgError:
            ainv = np.linalg.pinv(a)
        zz = np.einsum("bki,bkj->bij", z[..., s], z[..., s])
        cov[:, s, s] = sigma2[:, i, None, None] * ainv @ zz @ np.swapaxes(ainv, 1, 2)
    return theta, res, cov, sigma2


def _regressors(profile: ShipProfile, seg: Segment) -> tuple[np.ndarray, np.ndarray]:
    inputs = np.broadcast_to(seg.inputs, (seg.batch,) + seg.inputs.shape[-2:])
    return predictor_regressors(profile, seg.y, inputs, seg.psi)


def _sim_instruments(profile: ShipProfile, seg: Segment, theta: np.ndarray | str | None) -> np.ndarray:
    """Instruments of one segment, (B, N, p): a noise-free simulation driven by its inputs."""
    nu0 = np.asarray(seg.nu0, float)
    if theta is None or isinstance(theta, str):
        # the instrument set is the same for every realisation: simulate once per distinct input
        shared = seg.inputs.ndim == 2 and nu0.ndim == 1
        z = instruments(profile, seg.inputs if shared else np.broadcast_to(seg.inputs, (seg.batch,) + seg.inputs.shape[-2:]),
                        theta, nu0 if shared else np.broadcast_to(nu0, (seg.batch, 3)))
        return np.broadcast_to(z, (seg.batch,) + z.shape[-2:])
    terms = profile.predictor
    inputs = np.broadcast_to(seg.inputs, (seg.batch,) + seg.inputs.shape[-2:])
    with np.errstate(all="ignore"):
        sim = simulate(profile, inputs, theta, terms=terms, nu0=np.broadcast_to(nu0, (seg.batch, 3)), batch=seg.batch)
        z, _ = predictor_regressors(profile, sim.nu, inputs, sim.eta[..., 2])
    return z


def estimate(
    profile: ShipProfile,
    segments: Sequence[Segment],
    *,
    method: str = "iv",
    mean_subtraction: str = "complete",
    instrument_set: str | np.ndarray | None = None,
    max_iter: int = 3,
    rtol: float = 1e-3,
) -> Estimate:
    """LS or IV estimate of the predictor parameters from stacked sub-experiments.

    ``method='ls'`` uses the regressors as instruments; ``'iv'`` starts from instruments simulated
    with ``instrument_set`` (default the profile's nominal set) and re-simulates the predictor with
    the latest estimate (per realisation) until the relative change of theta is below ``rtol`` or
    ``max_iter`` re-simulations were made. A realisation whose estimate makes the simulation
    diverge keeps its previous instruments. Mean subtraction: 'none', 'batchwise' (7.19),
    'complete' (7.20).
    """
    if method not in ("ls", "iv"):
        raise DesignError(f"estimator method must be 'ls' or 'iv', got {method!r}")
    if mean_subtraction not in MEAN_SUBTRACTION:
        raise DesignError(f"mean subtraction must be one of {MEAN_SUBTRACTION}, got {mean_subtraction!r}")
    if not segments:
        raise DesignError("no data: the experiment has no segments")
    regs = [_regressors(profile, s) for s in segments]
    phis = [r[0] for r in regs]
    targets = [r[1] for r in regs]
    notes: list[str] = []
    if method == "ls":
        zs = _subtract_mean(phis, mean_subtraction)
        theta, res, cov, s2 = solve_blocks(profile, phis, zs, targets)
        return Estimate(theta, res, cov, s2, 0, True, notes)
    zraw = [_sim_instruments(profile, s, instrument_set) for s in segments]
    theta, res, cov, s2 = solve_blocks(profile, phis, _subtract_mean(zraw, mean_subtraction), targets)
    converged, iters, kept = False, 0, 0
    for it in range(1, max_iter + 1):
        iters = it
        znew = [_sim_instruments(profile, s, theta) for s in segments]
        ok = np.all([np.isfinite(z).all(axis=(1, 2)) & (np.abs(z).max(axis=(1, 2)) < 1e6) for z in znew], axis=0)
        kept = int((~ok).sum())
        zraw = [np.where(ok[:, None, None], zn, zo) for zn, zo in zip(znew, zraw)]
        th_new, res, cov, s2 = solve_blocks(profile, phis, _subtract_mean(zraw, mean_subtraction), targets)
        change = np.abs(th_new - theta) / np.maximum(np.abs(th_new), 1e-12)
        theta = th_new
        if np.nanmax(change) < rtol:
            converged = True
            break
    if kept:
        notes.append(f"{kept} realisation(s) kept earlier instruments (simulation with the estimate diverged)")
    return Estimate(theta, res, cov, s2, iters, converged, notes)


def segments_from_primitives(profile: ShipProfile, prims, y_list=None) -> list[Segment]:
    """Noise-free sub-experiments from library primitives (their nominal states as data)."""
    out = []
    for i, p in enumerate(prims):
        y = p.nu[None] if y_list is None else y_list[i]
        out.append(Segment(p.inputs, y, p.nu0, p.track[None, :, 2] if y_list is None else None))
    return out


def data_information(profile: ShipProfile, segments: Sequence[Segment], instrument_set: str | np.ndarray | None = None,
                     name: str = "prior") -> PrimitiveInfo:
    """Moments X, Y, Z (7.50), (7.51), (7.55) of data already collected (all realisations and
    segments pooled), for the prior term (7.58) of a re-planned design: pass the result as
    ``run_design(..., prior=info, prior_samples=info.n_samples)``."""
    if not segments:
        raise DesignError("no data: the experiment has no segments")
    phi = np.concatenate([_regressors(profile, s)[0].reshape(-1, profile.predictor.n_params) for s in segments])
    z = np.concatenate([_sim_instruments(profile, s, instrument_set).reshape(-1, profile.predictor.n_params) for s in segments])
    mask = block_mask(profile.predictor)
    n = phi.shape[0] // max(1, segments[0].batch)
    return PrimitiveInfo(name, n, phi.T @ z / phi.shape[0] * mask, phi.mean(axis=0), z.mean(axis=0), mask)
