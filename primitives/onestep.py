"""One ship in calm water, stepped on Python floats: the fast path of the kernel's time loop.

:func:`primitives.simulate.simulate` stays the one entry point; its time loop hands over here
when :func:`applies` (a batch of one planar ship, no pods, no current, wind or process noise, a
step that can run on floats). The arithmetic is that of :meth:`VelocityStep.next_one`: the same
IEEE operations in the same order as on one-element arrays, so the same bits as the array loop
(tests/test_one_model.py), without numpy's per-call cost, which dominates a batch of one (a
primitive, a lattice move, the verification's re-simulation).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from primitives.simulate import VelocityStep


def applies(step: VelocityStep, batch: int, n_dof: int, pods: bool, moving_env: bool, noise: bool) -> bool:
    """Whether the float loop gives the array loop's numbers: one planar ship without pods, in
    still water and calm air (``moving_env``: a current or wind to rotate), without process noise
    (``noise``), and a step whose increment function runs on floats (``step.scalar``)."""
    return batch == 1 and n_dof == 3 and step.scalar and not pods and not moving_env and not noise


def one_ship_loop(
    step: VelocityStep,
    in_names: list[str],
    in_t: np.ndarray,
    nu0: np.ndarray,
    eta0: np.ndarray,
    ts: float,
    positions: bool,
    heading: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """nu, eta (1, N+1, 3) of one ship from the time-major input signals ``in_t`` (N, signals, 1)
    named ``in_names``: nu(k+1) = nu(k) + Phi(k)^T theta and eta(k+1) = eta(k) + Ts R(psi(k)) nu(k)
    (Ljungberg 2022, (3.60), (9.1); Fossen 2021, ch. 2). Without ``heading`` nothing reads the pose: psi is
    NaN after the first row, as in the array loop (primitives.simulate._time_loop); without ``positions`` x, y are NaN. The
    heading's cosine and sine are numpy's, as in the array loop."""
    inc, coef = step.inc_floats, step.coef
    u, v, r = (float(a) for a in nu0)
    x, y, psi = (float(a) for a in eta0[:3])
    nu_rows, eta_rows = [(u, v, r)], [(x, y, psi)]
    nan = float("nan")
    if not heading:
        psi = nan
    for row in in_t[:, :, 0].tolist():
        sig = dict(zip(in_names, row))
        sig["psi"] = psi
        sig["u"] = sig["u_r"] = sig["u_q"] = u  # relative_signals in still water and calm air
        sig["v"] = sig["v_r"] = sig["v_q"] = v
        sig["r"] = r
        du, dv, dr = inc(sig, coef)
        if positions:
            c, s = np.cos(psi), np.sin(psi)
            x = x + ts * (c * u - s * v)
            y = y + ts * (s * u + c * v)
        if heading:
            psi = psi + ts * r
        u, v, r = u + du, v + dv, r + dr
        nu_rows.append((u, v, r))
        eta_rows.append((x, y, psi) if positions else (nan, nan, psi))
    return np.array(nu_rows)[None], np.array(eta_rows)[None]
