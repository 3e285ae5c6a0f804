"""The regressor matrix Phi of a term set built in one compiled pass (numba, once the simulation
kernel has loaded it, :mod:`primitives.jitloop`), the numpy build otherwise.

Phi(k) holds one column per term of the block-diagonal predictor (seed 001 (3.60), (9.2)), each
term the product of its factors ``|x@s|^k`` left to right (:meth:`primitives.terms.Factor.value`).
The numpy build makes a temporary array per factor and per term and then stacks and concatenates
them; this pass reads each sample's signals once and writes its row of Phi. The operations are
numpy's, in numpy's order, on the same doubles: x + s r for a station, abs, the power by
:func:`primitives.powers.int_power` (the products both builds use), the factors multiplied left to
right (the first times 1.0, exact). So the bits are the numpy build's; a term with a power pow()
forms (outside :data:`primitives.powers.PRODUCT_POWERS`: numpy's vectorised pow against the C
library's, see :mod:`primitives.jitloop`) keeps the numpy build (tests/test_regkernel.py compares the two).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from primitives import jitloop
from primitives.powers import PRODUCT_POWERS
from primitives.terms import TermSet


@lru_cache(maxsize=64)
def _program(terms: tuple[tuple[str, ...], ...]) -> tuple | None:
    """(signal names, per term its first factor and factor count, per factor the signal index,
    modulus, station (NaN: none) and power, the index of r); None when a power is not exact."""
    names: list[str] = []
    t_first, t_n, f_sig, f_mod, f_sta, f_pow = [], [], [], [], [], []

    def index(n: str) -> int:
        if n not in names:
            names.append(n)
        return names.index(n)

    for dof in jitloop._factors(terms):
        for term in dof:
            t_first.append(len(f_sig))
            t_n.append(len(term))
            for name, modulus, station, power in term:
                if power not in PRODUCT_POWERS:
                    return None
                f_sig.append(index(name))
                f_mod.append(int(modulus))
                f_sta.append(math.nan if station is None else float(station))
                f_pow.append(power)
    r_idx = index("r") if any(not math.isnan(s) for s in f_sta) else 0
    ints = [np.asarray(a, np.int64) for a in (t_first, t_n, f_sig, f_mod, f_pow)]
    return tuple(names), ints[0], ints[1], ints[2], ints[3], np.asarray(f_sta, float), ints[4], r_idx


def _stacked(terms: TermSet, sig: dict[str, np.ndarray], shape: tuple[int, ...]) -> tuple[tuple, np.ndarray] | None:
    """The compiled program of ``terms`` (:func:`_program`) and the signals it reads, one row each, broadcast to
    ``shape`` and flattened; None when the numpy build is to be used (a power it does not form, the compiled code
    not loaded, or a signal missing: the numpy build raises its usual error)."""
    prog = _program(terms.terms)
    if prog is None or not jitloop.loaded():
        return None
    names = prog[0]
    if any(n not in sig for n in names):
        return None
    s = np.empty((len(names), int(np.prod(shape))))
    for i, n in enumerate(names):
        s[i] = np.broadcast_to(sig[n], shape).reshape(-1)
    return prog, s


def regressor_matrix(terms: TermSet, sig: dict[str, np.ndarray], shape: tuple[int, ...]) -> np.ndarray | None:
    """Phi (*shape, p) from the signals ``sig`` (each broadcastable to ``shape``) in one compiled
    pass, or None when the numpy build is to be used: a power outside PRODUCT_POWERS, no terms or no
    samples, or the compiled code not loaded in this process (no compiler, ``SHIPTRIAL_KERNEL=numpy``,
    or no simulation large enough to load it has run yet).

    This build never loads numba itself: loading costs about 0.6 s of CPU (4 s the first time
    after install) and the compiled build gains little over numpy's (20 x 1000 samples, model-ship:
    1.8 ms against 1.5 ms; 500 x 1000: 74 ms against 87 ms, CPU medians under load)."""
    size = int(np.prod(shape))
    got = _stacked(terms, sig, shape) if size and terms.n_params else None
    if got is None:
        return None
    (_, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx), s = got
    out = np.empty((size, terms.n_params))
    _build(s, out, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx)
    return out.reshape(shape + (terms.n_params,))


@jitloop.inlined
def _factor(x, r, station, modulus, power):
    """|x + station r|^power, one factor of a term as numpy evaluates it (module doc): the station
    term when ``station`` is not NaN, the modulus, the power by :func:`primitives.powers.int_power`. Shared
    by :func:`_build` and :func:`_moments`; :func:`primitives.jitloop._times_factor` does the same
    arithmetic over the simulation kernel's batch layout (r at a fixed row, any power)."""
    if not math.isnan(station):
        x = x + station * r
    if modulus:
        x = abs(x)
    return jitloop.int_power(x, power)


@jitloop.compiled
def _build(sig, out, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx):
    size, p = out.shape
    for m in range(size):
        for t in range(p):
            acc = 1.0
            for f in range(t_first[t], t_first[t] + t_n[t]):
                acc = acc * _factor(sig[f_sig[f], m], sig[r_idx, m], f_sta[f], f_mod[f], f_pow[f])
            out[m, t] = acc


def block_moments(
    terms: TermSet, sig: dict[str, np.ndarray], shape: tuple[int, ...], blocks: list[slice]
) -> tuple[np.ndarray, np.ndarray] | None:
    """Sums over the last axis of ``shape`` (B, N) of Phi Phi^T within the DOF ``blocks`` (zero
    between them) and of Phi: ((B, p, p), (B, p)), from the signals ``sig`` in one compiled pass
    that never stores Phi (each row built as :func:`regressor_matrix` builds it, the same bits);
    None when :func:`regressor_matrix` would use the numpy build. Phi is built 128 samples at a
    time and each tile's products summed by BLAS, so the sums differ from those over the whole Phi
    (numpy's pairwise sum, one BLAS product per block) by their order, rounding only."""
    size = int(np.prod(shape))
    got = _stacked(terms, sig, shape) if size and terms.n_params and len(shape) == 2 else None
    if got is None:
        return None
    (_, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx), s = got
    p = terms.n_params
    block_end = np.arange(1, p + 1, dtype=np.int64)  # parameters outside every block pair with themselves only
    for b in blocks:
        block_end[b] = b.stop
    xx, ss = np.zeros((shape[0], p, p)), np.zeros((shape[0], p))
    _moments(s, shape[1], xx, ss, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx, block_end)
    return xx, ss


_TILE = 128  # samples per tile of Phi: (128, p) doubles stay in the first-level cache


@jitloop.compiled
def _moments(sig, n, xx, ss, t_first, t_n, f_sig, f_mod, f_sta, f_pow, r_idx, block_end):
    """:func:`block_moments`' sums into ``xx`` (B, p, p) and ``ss`` (B, p); the rows of draw b are
    ``sig[:, b n : (b + 1) n]``; ``block_end[i]``: one past the last parameter of i's block."""
    n_b, p = ss.shape
    tile = np.empty((_TILE, p))
    lx, ls = np.empty((p, p)), np.empty(p)  # one draw's sums
    for b in range(n_b):
        lx[:] = 0.0
        ls[:] = 0.0
        for c0 in range(0, n, _TILE):
            w = min(_TILE, n - c0)
            m0 = b * n + c0
            for t in range(p):  # column t of Phi over the tile, factor by factor as _build multiplies them
                for j in range(w):
                    tile[j, t] = 1.0
                for f in range(t_first[t], t_first[t] + t_n[t]):
                    g, st, mod, pw = f_sig[f], f_sta[f], f_mod[f], f_pow[f]
                    for j in range(w):
                        tile[j, t] = tile[j, t] * _factor(sig[g, m0 + j], sig[r_idx, m0 + j], st, mod, pw)
            part = tile[:w]
            lx += np.dot(part.T, part)  # BLAS on the tile (the products across blocks are dropped below)
            for j in range(w):
                for t in range(p):
                    ls[t] += part[j, t]
        for i in range(p):
            ss[b, i] = ls[i]
            for j in range(i, block_end[i]):
                xx[b, i, j] = lx[i, j]
                xx[b, j, i] = lx[i, j]
