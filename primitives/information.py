"""Information matrices of primitives for the instrumental-variable predictor (Ljungberg 2022, ch. 7).

For primitive q with regressors Phi_q(k) and instruments Z_q(k) (block diagonal over the DOFs):
X_q = mean Phi Z^T (7.50), Y_q = mean Phi (7.51), Z_q = mean Z (7.55), and
Gamma_q = X_q (no mean subtraction, (7.18)) or X_q - Y_q Z_q^T (batchwise, (7.53)).
The whole-experiment subtraction (7.57) mixes the primitives' means and so is formed by the
design (``expdesign.dopt.InfoSet.gamma``) from X, Y and Z.

The instruments are those of the estimator that will be run: the project's IV iterates, re-simulating
the predictor with its latest estimate, so once converged on a ship that is the design's parameters its
instruments are that ship's noise-free regressors, Z = Phi-hat (7.12). The profile's
``instrument_set`` (a crude model) only starts that iteration, so the design does not use it where
the predictor is the simulation model; the re-design mid-trial (:mod:`expdesign.adaptive`) uses the
same model at its re-identified parameters, so a resume that learnt nothing leaves the rest as planned.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from primitives.library import Primitive
from primitives.regressors import block_mask, instruments, predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances, simulate

MEAN_SUBTRACTION = ("none", "batchwise", "complete")

# What kind of manoeuvre excites each kind of term; used when a parameter is not identifiable.
_EXCITE_HINTS = [
    ("|", "a manoeuvre with large and varying speed in that direction (acceleration/deceleration, sway moves)"),
    ("tau", "a manoeuvre that varies that actuator (steps or zig-zags of the force)"),
    ("_q", "runs at different headings relative to the wind"),
]


@dataclass
class PrimitiveInfo:
    """Per-sample information of one primitive: X (p, p), Y (p,), Z (p,) and mask (p, p)."""

    name: str
    n_samples: int
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    mask: np.ndarray

    def gamma(self, mean_subtraction: str = "batchwise") -> np.ndarray:
        """Gamma_q: X for 'none'; X - Y Z^T (within DOF blocks) for 'batchwise' (7.53).
        For 'complete' a single primitive is its own whole experiment, as 'batchwise'."""
        if mean_subtraction not in MEAN_SUBTRACTION:
            raise ValueError(f"mean subtraction must be one of {MEAN_SUBTRACTION}, got {mean_subtraction!r}")
        if mean_subtraction == "none":
            return self.X.copy()
        return self.X - np.outer(self.Y, self.Z) * self.mask


def same_structure(profile: ShipProfile) -> bool:
    """The predictor is the profile's simulation model (its parameters simulate the ship)."""
    return profile.predictor_param_names == profile.param_names and profile.predictor_terms in (None, profile.model_terms)


def design_instrument_set(profile: ShipProfile) -> str:
    """The parameter set the design simulates its instruments with: the simulation set where the
    predictor is the simulation model (the converged IV's instruments at the design's parameters,
    (7.12)); else the profile's instrument set (a predictor of another structure has no parameters
    in the profile to converge to, and the re-design then keeps the same set)."""
    return profile.simulation_set if same_structure(profile) else profile.instrument_set


def primitive_information(
    profile: ShipProfile,
    primitive: Primitive,
    *,
    instrument_set: str | np.ndarray | None = None,
    disturbances: Disturbances | None = None,
    realisations: int = 1,
    seed: int | None = None,
) -> PrimitiveInfo:
    """X, Y, Z of one primitive.

    The regressors come from simulating the primitive's inputs with the profile's simulation
    set; with ``disturbances`` (current, noise) and several realisations they are averaged over
    Monte Carlo data like the thesis's estimated matrices; without, the nominal states are used.
    Instruments come from a noise-free simulation of ``instrument_set`` (default
    :func:`design_instrument_set`: the converged IV's).
    """
    terms = profile.predictor
    if disturbances is None or (disturbances.is_calm and not any(disturbances.measurement_std)):
        y = primitive.nu[None]
        psi = primitive.track[None, :, 2]
    else:
        res = simulate(profile, primitive.inputs, nu0=primitive.nu0, disturbances=disturbances, batch=realisations, seed=seed)
        y, psi = res.y, res.psi_meas
    phi, _ = predictor_regressors(profile, y, np.broadcast_to(primitive.inputs, (y.shape[0],) + primitive.inputs.shape), psi)
    if instrument_set is None:
        instrument_set = design_instrument_set(profile)
    z = instruments(profile, primitive.inputs, instrument_set, primitive.nu0)
    return information_moments(primitive.name, phi, z, block_mask(terms))


def information_moments(name: str, phi: np.ndarray, z: np.ndarray, mask: np.ndarray) -> PrimitiveInfo:
    """X = mean Phi Z^T (7.50) within the DOF blocks of ``mask``, Y = mean Phi (7.51) and
    Z = mean Z (7.55) over the B realisations and N samples of the regressors phi (B, N, p), with
    instruments z (N, p) shared by every realisation or (B, N, p) one set each."""
    b, n = phi.shape[:2]
    X = np.einsum("bki,kj->ij" if z.ndim == 2 else "bki,bkj->ij", phi, z) / (n * b) * mask
    return PrimitiveInfo(name, n, X, phi.mean(axis=(0, 1)), z.reshape(-1, z.shape[-1]).mean(axis=0), mask)


def library_information(profile: ShipProfile, primitives: list[Primitive], **kw: Any) -> list[PrimitiveInfo]:
    """:func:`primitive_information` of every primitive (``kw`` as there)."""
    return [primitive_information(profile, p, **kw) for p in primitives]


def unidentified_parameters(profile: ShipProfile, gamma: np.ndarray, rel_tol: float = 1e-9) -> list[str]:
    """Names of predictor parameters in the null space of a (possibly asymmetric) Gamma.

    A parameter is dead when its diagonal entry is zero to rounding relative to the largest
    one (a regressor that is identically zero up to float noise, e.g. a sway force of 1e-15
    from a thruster allocation), or when the smallest singular directions of the diagonally
    scaled Gamma (so units do not decide) load on it.
    """
    names = profile.predictor_param_names
    diag = np.abs(np.diag(gamma))
    dead_mask = diag <= 1e-14 * max(diag.max(), 1e-300)
    dead = [n for n, m in zip(names, dead_mask) if m]
    d = np.sqrt(np.where(dead_mask, 1.0, diag))
    g = np.where(np.outer(dead_mask, dead_mask), 0.0, gamma / np.outer(d, d))
    g = g[np.ix_(~dead_mask, ~dead_mask)]
    live = [n for n, m in zip(names, dead_mask) if not m]
    if g.size:
        _, s, vt = np.linalg.svd(g)
        small = s < rel_tol * max(s.max(), 1e-300) + 1e-12
        for row in vt[small]:
            for n, c in zip(live, row):
                if abs(c) > 0.3 and n not in dead:
                    dead.append(n)
    return [n for n in names if n in dead]


def excitation_hint(profile: ShipProfile, names: list[str]) -> str:
    """Plain-language advice on what manoeuvre would excite the named parameters."""
    terms = {n: t for n, t in zip(profile.predictor_param_names, (t for dof in profile.predictor.terms for t in dof))}
    dofs = dict(zip(profile.predictor_param_names, np.repeat(["surge", "sway", "yaw"], profile.predictor.sizes)))
    parts = []
    for n in names:
        t = terms[n]
        hint = next((h for key, h in _EXCITE_HINTS if key in t), None)
        if hint is None:
            if "*" in t:
                hint = (
                    "a manoeuvre that moves "
                    + " and ".join(sorted(set(t.replace("|", "").split("*"))))
                    + " at the same time (zig-zags, turns, spirals)"
                )
            else:
                hint = f"a manoeuvre that varies {t} ({dofs[n]} motion)"
        parts.append(f"{n} (term {t}): {hint}")
    return "; ".join(parts)


def reduced_profile(profile: ShipProfile, held: list[str]) -> ShipProfile:
    """The profile's view for a design of the parameters not ``held``: the predictor's terms and
    names without the held ones (what the design reads the parameters' names and terms from)."""
    names = profile.predictor_names or profile.parameter_names
    terms = profile.predictor.terms
    kept_terms = tuple(tuple(t for t, n in zip(ts, ns) if n not in held) for ts, ns in zip(terms, names))
    kept_names = tuple(tuple(n for n in ns if n not in held) for ns in names)
    return replace(profile, predictor_terms=kept_terms, predictor_names=kept_names)


def restrict(infos: list[PrimitiveInfo], keep: np.ndarray) -> list[PrimitiveInfo]:
    """Each primitive's moments restricted to the parameters ``keep`` (a boolean mask): the
    information of the others when the rest are held known (their regressors' part on the left of
    the IV normal equations, Ljungberg 2022 (7.50)-(7.53); nothing estimated for them, so no Schur complement)."""
    ix = np.ix_(keep, keep)
    return [PrimitiveInfo(q.name, q.n_samples, q.X[ix], q.Y[keep], q.Z[keep], q.mask[ix]) for q in infos]
