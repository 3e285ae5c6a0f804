"""The term program and the other arrays the compiled time loops read (:mod:`primitives.jitloop`,
:mod:`primitives.jittime`, expdesign's passes): the regressor terms of :mod:`primitives.terms` as
factor records over a per-step signal vector (the state signals of
:func:`primitives.velocitystep.relative_signals` first, the exogenous signals after), a podded
profile's pods (Gierusz 2015 / seed 000 (2.9)-(2.12)) and a rigid-body profile's M^-1 (seed 000
(2.13)). Pure Python and numpy: made once per term list and signal names, read by the loops.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from primitives.terms import TermSet, parse_factor

# Indices of the state signals in the per-step signal vector; the exogenous signals follow.
_STATE = ("u", "v", "r", "u_r", "v_r", "u_q", "v_q", "U", "wx", "wy", "wn", "psi", "p", "phi", "tau_x", "tau_y", "tau_k", "tau_n")
_IDX = {n: i for i, n in enumerate(_STATE)}
N_STATE = len(_STATE)
POD_TAUS = ("tau_x", "tau_y", "tau_k", "tau_n")
_NO_STATION = math.nan


@lru_cache(maxsize=256)
def _factors(terms: tuple[tuple[str, ...], ...]) -> tuple:
    """The parsed factors of every term, per DOF: [[(name, modulus, station, power), ...] per term]."""
    return tuple(
        tuple(tuple((f.name, f.modulus, f.station, f.power) for f in (parse_factor(s) for s in t.split("*"))) for t in dof)
        for dof in terms
    )


# the state signals the calm-water time loop provides to a term program (:func:`program`)
CALM_STATE = frozenset({"u", "v", "r", "u_r", "v_r", "u_q", "v_q", "U", "wx", "wy", "wn"})


def program(terms: TermSet, in_names: list[str], state_names: frozenset[str]) -> tuple[np.ndarray, ...] | None:
    """:func:`_program` of the term strings, made once per term list and signal names (a
    diagnosis simulates the same few hundred times; the loop only reads the arrays)."""
    return _program(terms.terms, tuple(in_names), state_names)


@lru_cache(maxsize=256)
def _program(
    terms: tuple[tuple[str, ...], ...], in_names: tuple[str, ...], state_names: frozenset[str]
) -> tuple[np.ndarray, ...] | None:
    """The term set as arrays the compiled loop reads: per DOF its first term and term count, per
    term its first factor and factor count, per factor the signal index, modulus, station (NaN:
    none) and power. Signals are looked up as the numpy loop's dictionary resolves them: the state
    signals ``state_names`` (set by the loop) before the exogenous ``in_names``. None when a term
    reads a signal neither provides (the numpy loop then raises its usual error)."""
    index = {n: N_STATE + i for i, n in enumerate(in_names)}
    index.update({n: _IDX[n] for n in state_names})
    dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow = [], [], [], [], [], [], [], []
    for dof in _factors(terms):
        dof_first.append(len(t_first))
        dof_n.append(len(dof))
        for term in dof:
            t_first.append(len(f_sig))
            t_n.append(len(term))
            for name, modulus, station, power in term:
                names = (name,) if station is None else (name, "r")
                if any(n not in index for n in names):
                    return None
                f_sig.append(index[name])
                f_mod.append(int(modulus))
                f_sta.append(_NO_STATION if station is None else float(station))
                f_pow.append(power)
    ints = [np.asarray(a, np.int64) for a in (dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_pow)]
    return (*ints[:6], np.asarray(f_sta, float), ints[6])


def pod_arrays(profile, index: dict[str, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A podded profile's pods for the compiled loop: positions (n_pods, 3), the signal indices of
    each pod's propeller speed and angle (n_pods, 2), and the shared coefficients (see
    :func:`_pod_forces`); empty arrays without pods."""
    if profile is None or not profile.pods:
        return np.zeros((0, 3)), np.zeros((0, 2), np.int64), np.zeros(12)
    m = profile.pod_model
    pos = np.array([(p.x, p.y, p.z) for p in profile.pods], float)
    sig = np.array([(index[f"n{i}"], index[f"delta{i}"]) for i in range(1, len(profile.pods) + 1)], np.int64)
    # the Python-float products of PodModel.local_forces, formed once as they are there
    coef = np.array(
        [
            m.rho * m.diameter**4,
            m.diameter,
            m.c_mx1,
            m.c_mx2,
            m.c_my1,
            m.c_my2,
            0.5 * m.rho * m.strut_area,
            m.c_rx1,
            m.c_rx2,
            m.c_ry,
            1.0 if m.yaw_moment == "full" else 0.0,
            0.0,
        ]
    )
    return pos, sig, coef


def rigid_arrays(rigid) -> tuple[np.ndarray, np.ndarray]:
    """M^-1 (4, 4) and (m, x_g, z_g) of a rigid-body profile; empty without one."""
    if rigid is None:
        return np.zeros((0, 0)), np.zeros(3)
    return np.ascontiguousarray(rigid.inverse_mass), np.array([rigid.mass, rigid.x_g, rigid.z_g])


def writable(a: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` as a C-contiguous writable float array (the one array type the compiled loop is built
    for, so a warm process loads one cached specialisation), or an empty one of ``shape``."""
    if a is None:
        return np.zeros(shape)
    return np.require(a, float, ["C", "W"])
