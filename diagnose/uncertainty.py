"""Covariance of the findings under coloured residuals (seed 004: output error with a noise model).

The search fits by output error on noise-weighted residuals, as if they were white. They are
not: coloured measurement noise (AR(1), 0.9, in the battery) and the baseline's own misfit make
neighbouring residuals alike, so the white-noise covariance ``(J^T J)^-1 s^2`` claims several
times the real precision. Following Kallstrom's maximum-likelihood treatment (a noise model
fitted with the dynamics), each residual channel is modelled as AR(1),
``e(k) = rho e(k-1) + eps(k)`` (rho and var(eps) per channel, from the final residuals), and the
covariance of the (penalised) least-squares estimate is the sandwich

    C = H^-1 (J^T Sigma J) H^-1,   H = J^T J + D

with ``Sigma`` the AR(1) covariance and ``D`` the fit's Gaussian prior; ``J^T Sigma J`` is
``Z^T Z`` with ``Z`` the sensitivities run backwards through the AR(1) filter.

A baseline fitted on --fit-on runs is an estimate too: its parameters are held there and the
finding is measured against them. Their error (the same sandwich for the --fit-on fit) moves the
finding by ``dA/dtheta = -H_aa^-1 G_a,theta`` (the refit of the free parameters ``a`` after a
change of the held ``theta``), so that covariance is added: ``C + (dA/dtheta) C_theta (dA/dtheta)^T``.
On the MMG battery's model-scale 3 s delay (AR(1) noise) it is about a third of the variance.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from diagnose.model import AugmentedModel, Prepared, fit, residuals


def sensitivities(model: AugmentedModel, preps: list[Prepared], P: np.ndarray, cols: list[int],
                  w: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per recording (weighted residual (N, 3), its sensitivity to ``cols`` (c, N, 3)) at P,
    from one batched simulation (forward differences, the fit's steps)."""
    h = model.steps(preps, P)
    Pb = np.repeat(P[None], len(cols) + 1, axis=0)
    for k, j in enumerate(cols):
        Pb[k + 1, j] += h[j]
    out = []
    for res in residuals(model, preps, Pb):
        R = res[:, 1:] * w  # sample 0 is the initial state
        out.append((R[0], (R[1:] - R[0]) / h[cols][:, None, None]))
    return out


def ar1(pairs: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """AR(1) coefficient and innovation variance per channel of the residuals (pooled over runs)."""
    num = sum((r[1:] * r[:-1]).sum(axis=0) for r, _J in pairs)
    den = sum((r[:-1] ** 2).sum(axis=0) for r, _J in pairs)
    rho = np.clip(num / np.maximum(den, 1e-300), 0.0, 0.99)
    n = sum(len(r) - 1 for r, _J in pairs)
    s2 = sum(((r[1:] - rho * r[:-1]) ** 2).sum(axis=0) for r, _J in pairs) / max(n, 1)
    return rho, s2


def ar1_grams(pairs: list[tuple[np.ndarray, np.ndarray]], rho: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(J^T J, J^T Sigma J) summed over runs and channels, Sigma the AR(1) noise covariance."""
    c = pairs[0][1].shape[0]
    G, M = np.zeros((c, c)), np.zeros((c, c))
    for _r, J in pairs:
        for ch in range(J.shape[2]):
            Jc = J[:, :, ch]
            G += Jc @ Jc.T
            # Sigma = A A^T with A the AR(1) filter (innovation std sqrt(s2)): A^T J runs it backwards
            Z = lfilter([np.sqrt(s2[ch])], [1.0, -rho[ch]], Jc[:, ::-1], axis=1)[:, ::-1]
            M += Z @ Z.T
    return G, M


def _inv(A: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


def sandwich(pairs: list[tuple[np.ndarray, np.ndarray]], prior_D: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(covariance, H) of a penalised least-squares fit with AR(1) residuals (module docstring)."""
    rho, s2 = ar1(pairs)
    G, M = ar1_grams(pairs, rho, s2)
    H = G + (np.diag(prior_D) if prior_D is not None else 0.0)
    Hi = _inv(H)
    return Hi @ M @ Hi, H


def _prior_D(sd: np.ndarray | None, n: int) -> np.ndarray:
    """Hessian diagonal of a Gaussian prior of std ``sd`` (0 where there is none: inf, nan, 0)."""
    if sd is None:
        return np.zeros(n)
    sd = np.asarray(sd, float)
    ok = np.isfinite(sd) & (sd > 0)
    return np.where(ok, 1.0 / np.where(ok, sd, 1.0) ** 2, 0.0)


def propagated(pairs: list[tuple[np.ndarray, np.ndarray]], nf: int, prior_D: np.ndarray | None = None,
               held_cov: np.ndarray | None = None) -> np.ndarray:
    """Covariance of the first ``nf`` sensitivity columns (the fitted parameters) under AR(1)
    residuals, plus the effect of the remaining columns' parameters (held at values estimated
    elsewhere, covariance ``held_cov``) through the refit: ``dA/dtheta = -H^-1 G_a,theta``."""
    cov, H = sandwich([(r, J[:nf]) for r, J in pairs], prior_D)
    if held_cov is not None and len(held_cov):
        G_ah = sum(np.einsum("anc,bnc->ab", J[:nf], J[nf:]) for _r, J in pairs)
        dA = -_inv(H) @ G_ah
        cov = cov + dA @ held_cov @ dA.T
    return np.where(np.isfinite(cov), cov, np.nan)


def finding_cov(model: AugmentedModel, preps: list[Prepared], w: np.ndarray, P: np.ndarray, free: list[int],
                prior_sd: np.ndarray | None = None, held: list[int] | None = None,
                held_cov: np.ndarray | None = None) -> np.ndarray:
    """Covariance of the ``free`` parameters at P (coloured residuals; the fit's prior std
    ``prior_sd`` per parameter), plus the propagated covariance ``held_cov`` of the parameters
    ``held`` (fixed at P, estimated on other runs)."""
    held = list(held or []) if held_cov is not None else []
    pairs = sensitivities(model, preps, P, list(free) + held, w)
    D = _prior_D(None if prior_sd is None else np.asarray(prior_sd, float)[free], len(free))
    return propagated(pairs, len(free), D, held_cov if held else None)


def baseline_cov(model: AugmentedModel, preps: list[Prepared], w: np.ndarray, idx: list[int], sd: np.ndarray
                 ) -> np.ndarray:
    """Covariance (len(idx) x len(idx)) of the baseline parameters ``idx`` as fitted on the
    --fit-on runs ``preps`` (``model`` at their fitted values, one initial-state correction
    per run, refitted here; prior std ``sd`` per parameter, inf for none): the sandwich of
    that penalised fit, the initial states as nuisance parameters."""
    x0 = model.x0_params()
    P, _cov, _rss = fit(model, preps, model.p0(), x0, w, max_iter=5)
    pairs = sensitivities(model, preps, P, list(idx) + x0, w)
    cov, _H = sandwich(pairs, _prior_D(np.concatenate([np.asarray(sd, float)[idx], np.full(len(x0), np.inf)]), len(idx) + len(x0)))
    return cov[: len(idx), : len(idx)]
