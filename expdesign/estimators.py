"""Least-squares and instrumental-variable estimators of the block-diagonal predictor (9.2)/(3.60),
and the output-error refinement of an estimate (:func:`output_error`, :mod:`expdesign.oerefine`).

The predictor is ``y(k+1) - y(k) = Phi(k)^T theta`` with one block of regressors per DOF, so each
DOF is solved on its own (block-diagonal normal equations). The IV estimate of DOF i is

    theta_i = (sum Z~_i(k) Phi_i(k)^T)^-1 sum Z~_i(k) (y_i(k+1) - y_i(k)),

with instruments Z built from a noise-free simulation (the profile's instrument set first, then
the predictor simulated with the latest estimate until it settles), and Z~ the instruments with
their mean removed: not at all, per sub-experiment (7.19) or over the whole experiment (7.20).
Every array carries a leading batch axis B of Monte Carlo realisations; the moments are batched
(``einsum``), the small per-DOF systems solved one by one by :func:`expdesign.ivsolve.iv_solve`,
which the Monte Carlo uses too. A realisation whose system is singular or ill-conditioned gets a
NaN estimate and a note: a failure to report, never a pseudo-inverse's number.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from expdesign.errors import DesignError
from expdesign.ivsolve import iv_solve
from expdesign.oerefine import OE_TOL, OEData, OEResult, output_error, output_error_unsupported  # noqa: F401 - imported from here
from primitives.information import MEAN_SUBTRACTION, PrimitiveInfo, design_instrument_set, information_moments
from primitives.regressors import block_mask, instruments, predictor_regressors
from primitives.ship import ShipProfile


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


def solve_blocks(
    profile: ShipProfile, phis: list[np.ndarray], zs: list[np.ndarray], targets: list[np.ndarray], mean_subtraction: str = "none"
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`iv_solve` over stacked segments (each its own sub-experiment for 'batchwise').

    Returns theta (B, p), residuals (B, N, 3), cov (B, p, p), sigma2 (B, 3); NaN for a
    realisation's DOF whose system is singular or ill-conditioned.
    """
    terms = profile.predictor
    phi = np.concatenate(phis, axis=1)
    tgt = np.concatenate(targets, axis=1)
    starts = np.cumsum([0] + [p.shape[1] for p in phis[:-1]])
    theta, z, mats = iv_solve(terms, phi, np.concatenate(zs, axis=1), tgt, mean_subtraction, starts)
    bsz, p = theta.shape
    cov = np.full((bsz, p, p), np.nan)
    res = np.empty_like(tgt)
    sigma2 = np.zeros((bsz, 3))
    for i, a in enumerate(mats):
        s = terms.dof_slice(i)
        res[..., i] = tgt[..., i] - np.einsum("bki,bi->bk", phi[..., s], theta[:, s])
        sigma2[:, i] = np.mean(res[..., i] ** 2, axis=1)
        ok = np.isfinite(theta[:, s]).all(axis=1)
        if ok.any():
            ainv = np.linalg.inv(a[ok])
            zz = np.einsum("bki,bkj->bij", z[ok][..., s], z[ok][..., s])
            cov[np.ix_(ok, range(s.start, s.stop), range(s.start, s.stop))] = (
                sigma2[ok, i, None, None] * ainv @ zz @ np.swapaxes(ainv, 1, 2)
            )
    cov[:, ~block_mask(terms)] = 0.0
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
        z = instruments(
            profile,
            seg.inputs if shared else np.broadcast_to(seg.inputs, (seg.batch,) + seg.inputs.shape[-2:]),
            theta,
            nu0 if shared else np.broadcast_to(nu0, (seg.batch, 3)),
        )
        return np.broadcast_to(z, (seg.batch,) + z.shape[-2:])
    inputs = np.broadcast_to(seg.inputs, (seg.batch,) + seg.inputs.shape[-2:])
    with np.errstate(all="ignore"):  # the predictor simulated with an estimate
        return instruments(profile, inputs, theta, np.broadcast_to(nu0, (seg.batch, 3)), sim_terms=profile.predictor)


def _failed_note(theta: np.ndarray) -> list[str]:
    failed = int((~np.isfinite(theta).all(axis=1)).sum())
    return [f"{failed} realisation(s) failed: a singular or ill-conditioned IV system (their theta is NaN)"] if failed else []


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
        theta, res, cov, s2 = solve_blocks(profile, phis, phis, targets, mean_subtraction)
        return Estimate(theta, res, cov, s2, 0, True, _failed_note(theta))
    zraw = [_sim_instruments(profile, s, instrument_set) for s in segments]
    theta, res, cov, s2 = solve_blocks(profile, phis, zraw, targets, mean_subtraction)
    converged, iters, kept = False, 0, 0
    for it in range(1, max_iter + 1):
        iters = it
        znew = [_sim_instruments(profile, s, theta) for s in segments]
        ok = np.all([np.isfinite(z).all(axis=(1, 2)) & (np.abs(z).max(axis=(1, 2)) < 1e6) for z in znew], axis=0)
        kept = int((~ok & np.isfinite(theta).all(axis=1)).sum())  # a failed realisation's NaN is no divergence
        zraw = [np.where(ok[:, None, None], zn, zo) for zn, zo in zip(znew, zraw)]
        th_new, res, cov, s2 = solve_blocks(profile, phis, zraw, targets, mean_subtraction)
        with np.errstate(invalid="ignore"):
            change = np.abs(th_new - theta) / np.maximum(np.abs(th_new), 1e-12)
        theta = th_new
        finite = np.isfinite(change)  # a failed realisation (NaN) has nothing left to converge
        if not finite.any():
            break
        if change[finite].max() < rtol:
            converged = True
            break
    if kept:
        notes.append(f"{kept} realisation(s) kept earlier instruments (simulation with the estimate diverged)")
    notes += _failed_note(theta)
    return Estimate(theta, res, cov, s2, iters, converged, notes)


def data_information(
    profile: ShipProfile, segments: Sequence[Segment], instrument_set: str | np.ndarray | None = None, name: str = "prior"
) -> PrimitiveInfo:
    """Moments X, Y, Z (7.50), (7.51), (7.55) of data already collected (all realisations and
    segments pooled; every segment of the same B realisations), for the prior term (7.58) of a
    re-planned design: pass the result as ``run_design(..., prior=info, prior_samples=info.n_samples)``.
    Instruments default to the design's (:func:`primitives.information.design_instrument_set`), so
    the prior is in the same information model as the library's moments."""
    if not segments:
        raise DesignError("no data: the experiment has no segments")
    if instrument_set is None:
        instrument_set = design_instrument_set(profile)
    phi = np.concatenate([_regressors(profile, s)[0] for s in segments], axis=1)
    z = np.concatenate([_sim_instruments(profile, s, instrument_set) for s in segments], axis=1)
    return information_moments(name, phi, z, block_mask(profile.predictor))
