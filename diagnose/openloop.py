"""The time loops of the augmented model's open-loop simulation (:meth:`diagnose.model.
AugmentedModel.simulate_many`): the compiled loop over recordings of similar length side by side
(their members in one call), the numpy loop over every recording at once (padded to the longest),
and the environment both read, the current and the air velocity turned into body axes by the
measured heading (not a simulated one).

Both loops step the primitives' time step (:class:`primitives.velocitystep.VelocityStep`) with the
same inputs in the same order: the same bits (``tests/test_diagnose_simulate.py``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from primitives import jitloop
from primitives.simulate import VelocityStep, body_from_ne
from primitives.terms import TermSet

if TYPE_CHECKING:
    from diagnose.model import Prepared

# One recording's (exogenous signals, input-only increments (B, N, 3), nu(0) (B, 3)), as
# AugmentedModel._run_inputs makes them.
RunInputs = tuple[dict, np.ndarray, np.ndarray]


def current_turning(cur: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Change of an earth-fixed current's body-frame components over each step, (B, N, 2).

    The hull feels the water-relative velocity (u_r, v_r); for a uniform current its dynamics
    are those of calm water in u_r, v_r (Fossen 2021, section 10.3), while the state here (and
    the recording) is the velocity over ground u = u_r + u_c(psi). As the ship turns, u_c(psi)
    turns with it: the over-ground velocity changes by u_c(psi(k+1)) - u_c(psi(k)) on top of
    the hydrodynamic increment (the measured heading, as for the relative velocities)."""
    uc, vc = body_from_ne(cur[:, None, :], psi[None, :])  # (B, N+1)
    return np.stack([np.diff(uc, axis=1), np.diff(vc, axis=1)], axis=-1)


def environment(prep: Prepared, cur: np.ndarray | None, use_wind: bool, B: int) -> tuple:
    """The current ``cur`` (B, 2), north and east, and the recorded air velocity of one recording
    in body axes on its measured heading: each a pair of (N, B) arrays, or None."""
    cb = wb = None
    if cur is not None:
        cb = body_from_ne(cur[None], prep.psi[:-1, None])
    if use_wind:
        wind = prep.wind_body if prep.wind_body is not None else (np.zeros(prep.n + 1),) * 2
        wb = tuple(np.broadcast_to(q[:-1, None], (prep.n, B)) for q in wind)
    return cb, wb


def compiled_loop(
    preps: list[Prepared],
    runs: list[RunInputs],
    tset: TermSet,
    coefs: list[np.ndarray],
    need_in: list[str],
    curs: list[np.ndarray] | None,
    use_wind: bool,
) -> list[np.ndarray] | None:
    """nu (B_i, N_i+1, 3) per recording from the compiled loop (recording i's members with the
    term coefficients ``coefs[i]`` (B_i, p) and the current ``curs[i]`` (B_i, 2)); None when the
    compiled loop does not apply. Whether it is worth loading is judged on the whole call's work.
    Recordings are stepped side by side in one call (:func:`_groups`, :func:`_merged`); a recording
    stepped alone reads its inputs once for every member when they are the same. Each member is
    stepped on its own in the loop: the same bits however the recordings are grouped."""
    if not jitloop.use(sum(len(c) * p.n for c, p in zip(coefs, preps))):
        return None
    outs: list[np.ndarray] = []
    for group in _groups([p.n for p in preps], [len(c) for c in coefs]):
        if len(group) == 1:
            i = group[0]
            (exo, pre, nu0), prep, B = runs[i], preps[i], len(coefs[i])
            if B == 0:  # nothing to step on this recording (a Jacobian's recording with no column)
                outs.append(np.empty((0, prep.n + 1, 3)))
                continue
            ex = {nm: np.asarray(exo[nm]).T for nm in need_in}
            env = environment(prep, None if curs is None else curs[i], use_wind, B)
            out = jitloop.open_loop(VelocityStep(tset, coefs[i]), need_in, ex, np.array(nu0), *env, pre.swapaxes(0, 1))
            part = None if out is None else [out]
        else:
            sub = [None if curs is None else curs[i] for i in group]
            part = _merged(
                [preps[i] for i in group], [runs[i] for i in group], tset, [coefs[i] for i in group], need_in, sub, use_wind
            )
        if part is None:
            return None
        outs += part
    return outs


# Members of one compiled call when recordings are stepped side by side: the loop's cost is mostly
# fixed per step (about 1 us a step for one member of the kvlcc2 model, 0.1-0.2 us for each
# further one), so the few members of a refit's trials or Jacobian on several recordings cost
# about what one recording alone costs; past some tens of members the members themselves dominate.
MERGE_MEMBERS = 48
MERGE_LENGTH = 0.8  # a recording is padded to the group's longest by at most 20 % of that (steps lost)


def _groups(lengths: list[int], members: list[int]) -> list[list[int]]:
    """Consecutive recordings stepped in one call: at most :data:`MERGE_MEMBERS` members together,
    none shorter than :data:`MERGE_LENGTH` of the group's longest."""
    out: list[list[int]] = []
    for i, (n, b) in enumerate(zip(lengths, members)):
        g = out[-1] if out else []
        ns = [lengths[j] for j in g] + [n]
        if g and sum(members[j] for j in g) + b <= MERGE_MEMBERS and min(ns) >= MERGE_LENGTH * max(ns):
            g.append(i)
        else:
            out.append([i])
    return out


def _merged(
    preps: list[Prepared],
    runs: list[RunInputs],
    tset: TermSet,
    coefs: list[np.ndarray],
    need_in: list[str],
    curs: list[np.ndarray | None],
    use_wind: bool,
) -> list[np.ndarray] | None:
    """nu (B_i, N_i+1, 3) per recording from one compiled call over every member of every recording
    side by side, the shorter ones padded to the longest with their last inputs (the padding's steps
    are cut off)."""
    cut = np.cumsum([0] + [len(c) for c in coefs])
    n_max = max(p.n for p in preps)

    def padded(arrs: list[np.ndarray]) -> np.ndarray:
        return _padded(arrs, n_max, cut)

    ex = {nm: padded([np.asarray(e[nm])[..., None] for e, _x, _n in runs])[..., 0] for nm in need_in}
    env = [environment(p, c, use_wind, len(k)) for p, c, k in zip(preps, curs, coefs)]
    cb = None if curs[0] is None else tuple(padded([e[0][q].T[..., None] for e in env])[..., 0] for q in (0, 1))
    wb = None if not use_wind else tuple(padded([e[1][q].T[..., None] for e in env])[..., 0] for q in (0, 1))
    nu0 = np.concatenate([np.array(n0) for _e, _x, n0 in runs])
    # the increments padded straight into the loop's (N, 3, B) layout, passed as its (N, B, 3)
    # view: the loop's own contiguous copy of that view is then no copy
    forced = np.empty((n_max, 3, cut[-1])).transpose(0, 2, 1)
    _fill(forced, [x for _e, x, _n in runs], cut)
    out = jitloop.open_loop(VelocityStep(tset, np.concatenate(coefs)), need_in, ex, nu0, cb, wb, forced)
    if out is None:
        return None
    return [out[cut[r] : cut[r + 1], : p.n + 1] for r, p in enumerate(preps)]


def _padded(arrs: list[np.ndarray], n_max: int, cut: np.ndarray) -> np.ndarray:
    """(n_max, cut[-1], ...) time-major (one contiguous row per step) from per-recording arrays
    (B_r or 1, n_r, ...), recording r in the columns cut[r]:cut[r+1], a shorter one padded with its
    last step (the padding's steps are cut off the outputs; each member is stepped on its own)."""
    out = np.empty((n_max, cut[-1]) + arrs[0].shape[2:])
    _fill(out, arrs, cut)
    return out


def _fill(out: np.ndarray, arrs: list[np.ndarray], cut: np.ndarray) -> None:
    """:func:`_padded` into ``out`` (n_max, cut[-1], ...), which may be a view of another layout."""
    for r, a in enumerate(arrs):
        a = a.swapaxes(0, 1)
        out[: len(a), cut[r] : cut[r + 1]] = a
        out[len(a) :, cut[r] : cut[r + 1]] = a[-1:]


def numpy_loop(
    preps: list[Prepared],
    runs: list[RunInputs],
    tset: TermSet,
    coef: np.ndarray,
    need_in: list[str],
    cur: np.ndarray | None,
    use_wind: bool,
) -> list[np.ndarray]:
    """nu (B, N_i+1, 3) per recording from the numpy loop over every recording and member at once
    (padded to the longest; the padding's steps are cut off)."""
    B, R, n_max = coef.shape[0], len(preps), max(p.n for p in preps)

    def padded(arrs: list[np.ndarray]) -> np.ndarray:
        return _padded(arrs, n_max, np.arange(R + 1) * B)

    pre = padded([pre for _e, pre, _n in runs])
    exo = {nm: padded([np.asarray(e[nm])[..., None] for e, _x, _n in runs])[..., 0] for nm in need_in}
    env = [environment(p, cur, use_wind, B) for p in preps]
    cb = None if cur is None else tuple(padded([e[0][q].T[..., None] for e in env])[..., 0] for q in (0, 1))
    wb = None if not use_wind else tuple(padded([e[1][q].T[..., None] for e in env])[..., 0] for q in (0, 1))
    step = VelocityStep(tset, np.tile(coef, (R, 1)))
    nu = np.concatenate([nu0 for _e, _x, nu0 in runs])
    out = np.empty((R * B, n_max + 1, 3))
    out[:, 0] = nu
    for k in range(n_max):
        nu = step(
            nu,
            {nm: exo[nm][k] for nm in need_in},
            (cb[0][k], cb[1][k]) if cb is not None else None,
            (wb[0][k], wb[1][k]) if wb is not None else None,
            pre[k],
        )
        out[:, k + 1] = nu
    return [out[r * B : (r + 1) * B, : p.n + 1] for r, p in enumerate(preps)]
