"""The output-error Jacobian of the augmented model's baseline by forward sensitivities
(:mod:`primitives.jitsens`) instead of finite differences: one pass beside the simulated
trajectory for every column, where finite differences step one perturbed member per column
(the --fit-on baseline's covariance and left-out refits: about 60 coefficients and 3 initial
states a run on four runs of 3,500 samples). The baseline's Levenberg-Marquardt fit keeps its
finite differences: exact Jacobians change the path of that ill-conditioned fit, which stops while
it still creeps, and on the MMG battery's thrust-loss-20 it ends in another valley (a worse
objective) where the diagnosis names a wind too.

It applies to the baseline's own parameters (its term coefficients and the runs' initial states)
at a point where no candidate slot is switched on (the --fit-on fit and its covariance): a
candidate (a delay, a current, an offset...) enters the simulation around the time loop and is
left to finite differences. Where it does not apply, or the compiled kernel cannot run, the
functions here return None and the caller differences as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from primitives import jitloop, jitsens

if TYPE_CHECKING:
    from diagnose.model import AugmentedModel, Prepared


def applies(model: AugmentedModel, P: np.ndarray, free: list[int]) -> bool:
    """Whether the sensitivities hold for ``free`` at P: every free parameter a baseline
    coefficient or an initial state, every candidate slot off, and the compiled kernel usable."""
    P = np.asarray(P, float)
    return (
        P.ndim == 1
        and not np.any(P[model.n_base : model.n_slots_end] != 0)
        and all(j < model.n_base or j >= model.n_slots_end for j in free)
        and jitsens.available()
    )


def state_jacobian(model: AugmentedModel, prep: Prepared, P: np.ndarray, free: list[int], yhat: np.ndarray) -> np.ndarray | None:
    """d y_hat(k) / d P[free] (N+1, 3, len(free)) of recording ``prep`` along its simulation
    ``yhat`` (N+1, 3) at P (:func:`applies` holds); None when the kernel cannot read a term."""
    pos = {j: k for k, j in enumerate(free)}
    plan = model._plan(np.zeros((1, model.n_params)))  # nothing switched on: the recorded inputs as they are
    exo = model._exogenous(prep, plan, 1)
    loop: list[list[tuple[str, float, int]]] = [[], [], []]
    pre_val, pre_dof, pre_col = [], [], []
    for j, (i, term, names, fn) in enumerate(model.base):
        if set(names) <= set(exo):  # an input-only term (AugmentedModel._run_inputs): no state in it
            if j in pos:
                pre_val.append(np.broadcast_to(fn(exo), (1, prep.n))[0])
                pre_dof.append(i)
                pre_col.append(pos[j])
        elif not model.input_only(names):  # a term of the time loop (AugmentedModel.simulate_many)
            loop[i].append((term, float(P[j]), pos.get(j, -1)))
    tset, need = model._termset(tuple(tuple(t for t, _c, _k in dof) for dof in loop))
    need_in = sorted(need & set(exo))
    prog = jitloop.program(tset, need_in, jitloop.CALM_STATE)
    if prog is None:
        return None
    flat = [x for dof in loop for x in dof]
    s0 = np.zeros((3, len(free)))
    if prep.index is not None and prep.index < model.n_rec:
        for d in range(3):
            k = pos.get(model.n_slots_end + 3 * prep.index + d)
            if k is not None:
                s0[d, k] = 1.0
    wind = None if prep.wind_body is None else np.stack(prep.wind_body, axis=1)[:-1]
    return jitsens.state_sensitivities(
        yhat,
        np.stack([np.broadcast_to(exo[nm], (1, prep.n))[0] for nm in need_in], axis=1) if need_in else np.zeros((prep.n, 0)),
        wind,
        np.array([c for _t, c, _k in flat]),
        prog,
        np.array([k for _t, _c, k in flat], np.int64),
        np.stack(pre_val, axis=1) if pre_val else np.zeros((prep.n, 0)),
        np.array(pre_dof, np.int64),
        np.array(pre_col, np.int64),
        s0,
    )


def residual_jacobian(
    model: AugmentedModel,
    preps: list[Prepared],
    P: np.ndarray,
    free: list[int],
    w: np.ndarray | list[np.ndarray],
    res: list[np.ndarray],
    masks: list[np.ndarray] | None = None,
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """Per recording (weighted residual (N, 3), its Jacobian (N, 3, len(free))) at P from the
    residuals ``res`` (N+1, 3) there (sample 0, the initial state, dropped; rows of ``masks``
    only); None where the sensitivities do not apply (:func:`applies`) or the simulation at P is
    not finite (finite differences then say what they say)."""
    if not applies(model, P, free):
        return None
    out = []
    for i, (prep, r) in enumerate(zip(preps, res)):
        if not np.all(np.abs(r) < 1e6):  # residuals() marks a non-finite simulation 1e6
            return None
        S = state_jacobian(model, prep, P, free, prep.y - r)
        if S is None:
            return None
        wi = w[i] if isinstance(w, list) else w
        R, J = r[1:] * wi, -S[1:] * wi[None, :, None]
        if masks is not None:
            R, J = R[masks[i][1:]], J[masks[i][1:]]
        out.append((R, J))
    return out
