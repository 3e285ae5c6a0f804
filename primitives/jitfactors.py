"""The term increments of :func:`primitives.jittime.time_loop` from a factor table: every distinct
factor of the term program that is not a signal itself (a station, a modulus or a power other than
1) is evaluated once a step into its own row beside the signals, and each term then multiplies its
coefficient by its factors' rows in one pass over the batch.

The regression model's increment is Phi(k)^T theta (seed 001 (3.60)), each term c_j * f_1 * f_2 ...
formed and summed exactly as :func:`primitives.jitloop._increments` forms them (the generated
increment function of :meth:`primitives.terms.TermSet.increment_function`): ((c_j * f_1) * f_2) ...,
the terms of a DOF added left to right, each factor |s + station * r|^power by the same IEEE
operations. A factor shared by several terms has the same value in each, so reading it from a
shared row gives the same bits; what is saved is its recomputation (two products for v_r^3, a
division for U^-1; powers as :func:`primitives.powers.int_power` forms them) and the passes over
the batch of a factor-by-factor product.
"""

from __future__ import annotations

import math

import numpy as np

from primitives import jitloop
from primitives.jitloop import inlined


@inlined
def _factor_table(n_sig, f_sig, f_mod, f_sta, f_pow):
    """The distinct factors of a term program that are not a signal itself (a station, a modulus or
    a power other than 1), each evaluated once a step into its own row after the ``n_sig`` signal
    rows: (row of every factor, and per derived row its signal, modulus, station, power). Two
    factors with the same signal, modulus, station and power have the same value, so a term reading
    the shared row multiplies the bits it would have formed itself."""
    nf = f_sig.shape[0]
    row = np.empty(nf, np.int64)
    d_sig = np.empty(nf, np.int64)
    d_mod = np.empty(nf, np.int64)
    d_sta = np.empty(nf)
    d_pow = np.empty(nf, np.int64)
    n_der = 0
    for f in range(nf):
        plain = math.isnan(f_sta[f]) and f_mod[f] == 0 and f_pow[f] == 1
        if plain:
            row[f] = f_sig[f]
            continue
        found = -1
        for d in range(n_der):
            # the same station bit for bit: 0.0 and -0.0 compare equal but can give s + station * r zeros of either sign
            same_sta = (d_sta[d] == f_sta[f] and math.copysign(1.0, d_sta[d]) == math.copysign(1.0, f_sta[f])) or (
                math.isnan(d_sta[d]) and math.isnan(f_sta[f])
            )
            if d_sig[d] == f_sig[f] and d_mod[d] == f_mod[f] and d_pow[d] == f_pow[f] and same_sta:
                found = d
                break
        if found < 0:
            found = n_der
            d_sig[n_der], d_mod[n_der], d_sta[n_der], d_pow[n_der] = f_sig[f], f_mod[f], f_sta[f], f_pow[f]
            n_der += 1
        row[f] = n_sig + found
    return row, d_sig[:n_der], d_mod[:n_der], d_sta[:n_der], d_pow[:n_der]


@inlined
def _derived_rows(sig, n_sig, d_sig, d_mod, d_sta, d_pow, batch, shared_from):
    """Each derived factor |s + station * r|^power into its row of ``sig``: the operations of
    :func:`_times_factor` in its order, one loop over the batch per operation (they vectorise).
    A factor of a signal at or after row ``shared_from`` (exogenous signals every member reads the
    same: ``n_sig`` when none is) without a station is formed for the first member only and copied
    to the others: the same operations on the same number, so the same bits, for one power a step
    instead of one a member (delta^3 of the MMG structure)."""
    for d in range(d_sig.shape[0]):
        o, s = n_sig + d, d_sig[d]
        st = d_sta[d]
        nb = 1 if s >= shared_from and math.isnan(st) else batch
        if math.isnan(st):
            for b in range(nb):
                sig[o, b] = sig[s, b]
        else:
            for b in range(nb):
                sig[o, b] = sig[s, b] + st * sig[2, b]
        if d_mod[d]:
            for b in range(nb):
                sig[o, b] = abs(sig[o, b])
        _power_row(sig, o, nb, d_pow[d])
        if nb < batch:
            x = sig[o, 0]
            for b in range(1, batch):
                sig[o, b] = x


@inlined
def _power_row(sig, o, nb, pw):
    """sig[o, :nb] = jitloop.int_power(sig[o, :nb], pw), one loop per power with the power a
    constant: int_power's branches fold away and the loop vectorises (a loop testing ``pw`` per
    element took 8.3 against 4.2 ms on a search trial's 12-member time loop, min of 21, load 5)."""
    if pw == 2:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], 2)
    elif pw == 3:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], 3)
    elif pw == 4:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], 4)
    elif pw == -1:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], -1)
    elif pw == -2:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], -2)
    elif pw != 1:
        for b in range(nb):
            sig[o, b] = jitloop.int_power(sig[o, b], pw)


@inlined
def _table_increments(inc, tmp, sig, coef, batch, dof_first, dof_n, t_first, t_n, row):
    """inc[i, b] = Phi_i^T theta per DOF i as :func:`_increments` forms it (each term
    ((c_j * f_1) * f_2) ..., the terms summed left to right), its factors read from their rows
    (:func:`_factor_table`); a term of up to three factors in one pass over the batch."""
    for i in range(dof_first.shape[0]):
        if dof_n[i] == 0:
            for b in range(batch):
                inc[i, b] = 0.0
            continue
        for t in range(dof_first[i], dof_first[i] + dof_n[i]):
            f0, nf, first = t_first[t], t_n[t], t == dof_first[i]
            if nf == 1:
                r1 = row[f0]
                for b in range(batch):
                    tmp[b] = coef[t, b] * sig[r1, b]
            elif nf == 2:
                r1, r2 = row[f0], row[f0 + 1]
                for b in range(batch):
                    tmp[b] = coef[t, b] * sig[r1, b] * sig[r2, b]
            elif nf == 3:
                r1, r2, r3 = row[f0], row[f0 + 1], row[f0 + 2]
                for b in range(batch):
                    tmp[b] = coef[t, b] * sig[r1, b] * sig[r2, b] * sig[r3, b]
            else:
                for b in range(batch):
                    tmp[b] = coef[t, b]
                for f in range(f0, f0 + nf):
                    r1 = row[f]
                    for b in range(batch):
                        tmp[b] = tmp[b] * sig[r1, b]
            if first:
                for b in range(batch):
                    inc[i, b] = tmp[b]
            else:
                for b in range(batch):
                    inc[i, b] = inc[i, b] + tmp[b]
