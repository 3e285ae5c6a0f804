"""Regressors Phi(k) and instruments Z(k) of the linear-in-parameters predictors.

The predictor (9.2) / (3.60) is ``y(k) - y(k-1) = Phi(k)^T theta`` with a block-diagonal
Phi: one block of terms per DOF, all built from signals at k-1. Here Phi is stored as an
(N, p) array whose columns of DOF i are that DOF's terms; the target is (N, 3). The
estimator does not know the current, so u_r and v_r are the measured u and v; u_q, v_q use
the measured wind when there is one.

Instruments (section 4, (9.2)): the same regressors built from a noise-free simulation of a
chosen parameter set driven by the same inputs.
"""

from __future__ import annotations

import numpy as np

from primitives.regkernel import regressor_matrix
from primitives.ship import ShipProfile
from primitives.simulate import model_signals, signals_read, simulate
from primitives.terms import TermSet


def block_mask(terms: TermSet) -> np.ndarray:
    """Boolean (p, p) mask of the DOF blocks of a block-diagonal predictor."""
    p = terms.n_params
    mask = np.zeros((p, p), dtype=bool)
    for i in range(terms.n_dof):
        s = terms.dof_slice(i)
        mask[s, s] = True
    return mask


def predictor_regressors(
    profile: ShipProfile,
    y: np.ndarray,
    inputs: np.ndarray,
    psi: np.ndarray | None = None,
    wind_ne: np.ndarray | None = None,
    terms: TermSet | None = None,
    extra: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, target) for measured velocities y (..., N+1, 3) and inputs (..., N, m).

    Phi has shape (..., N, p) with row k built from samples k (predicting k+1); target is
    y(k+1) - y(k), shape (..., N, 3). ``extra`` adds signals (..., N) a term may read.
    """
    terms = terms or profile.predictor
    y = np.asarray(y, float)
    sig, shape = regressor_signals(profile, y, inputs, psi, wind_ne, extra)
    return signal_regressors(terms, sig, shape), np.diff(y, axis=-2)


def signal_regressors(terms: TermSet, sig: dict[str, np.ndarray], shape: tuple[int, ...]) -> np.ndarray:
    """Phi (*shape, p) of ``terms`` from the signals of :func:`regressor_signals`: the compiled
    build when worth it (:func:`primitives.regkernel.regressor_matrix`, the same bits), else numpy's."""
    phi = regressor_matrix(terms, sig, shape)
    if phi is None:
        phi = np.concatenate([terms.evaluate_dof(i, sig) for i in range(terms.n_dof)], axis=-1)
    return phi


def regressor_signals(
    profile: ShipProfile,
    y: np.ndarray,
    inputs: np.ndarray,
    psi: np.ndarray | None = None,
    wind_ne: np.ndarray | None = None,
    extra: dict[str, np.ndarray] | None = None,
) -> tuple[dict[str, np.ndarray], tuple[int, ...]]:
    """The signals the regressors of :func:`predictor_regressors` read (each broadcastable to the
    returned shape (..., N): row k from samples k) for its arguments."""
    y = np.asarray(y, float)
    inputs = np.asarray(inputs, float)
    n = inputs.shape[-2]
    if y.shape[-2] != n + 1:
        raise ValueError(f"y has {y.shape[-2]} samples; inputs need N+1 = {n + 1}")
    yk = y[..., :-1, :]
    psi_k = np.zeros(yk.shape[:-1]) if psi is None else np.asarray(psi, float)[..., :-1]
    in_sig = profile.generalized_forces(inputs)
    in_sig = {k: np.broadcast_to(v, yk.shape[:-1]) for k, v in in_sig.items()}
    sig = model_signals(profile, yk, psi_k, in_sig, None, None if wind_ne is None else wind_ne[..., :n, :])
    if extra:
        sig.update({k: v[..., :n] for k, v in extra.items()})
    return sig, yk.shape[:-1]


def instruments(
    profile: ShipProfile,
    inputs: np.ndarray,
    theta: np.ndarray | str | None = None,
    nu0: np.ndarray | tuple = (0.0, 0.0, 0.0),
    *,
    sim_terms: TermSet | None = None,
    terms: TermSet | None = None,
) -> np.ndarray:
    """Instruments Z (..., N, p): regressors of a noise-free simulation with ``theta``.

    ``theta`` defaults to the profile's instrument set and is simulated with the model
    structure (``sim_terms`` overrides it, e.g. to simulate the predictor with an estimate).
    The position is not integrated (no regressor reads it), the heading only when a term reads
    it (:func:`primitives.simulate.simulate`'s ``positions``).
    """
    if theta is None:
        theta = profile.instrument_set
    inputs = np.asarray(inputs, float)
    nu0 = np.asarray(nu0, float)
    batch = nu0.shape[0] if nu0.ndim == 2 else 1
    heading = "psi" in signals_read(terms or profile.predictor)  # the simulation keeps it if its own terms read it
    res = simulate(profile, inputs, theta, terms=sim_terms, nu0=nu0, batch=batch, positions=heading)
    y_hat = res.nu if (nu0.ndim == 2 or inputs.ndim == 3) else res.nu[0]
    psi = res.eta[..., 2] if y_hat.ndim == 3 else res.eta[0, :, 2]
    z, _ = predictor_regressors(profile, y_hat, inputs, psi, terms=terms)
    return z
