"""Identifiability of the yaw row, section 2.4.2 of the podded-ship MSc thesis checked on data.

In the yaw row (2.15) written in its physical parameters,

    0 = -I_z r_dot + N_rdot r_dot - m x_g (v_dot + u r) + N_vdot v_dot + N_|u|r |u| r + ... + tau_r,

I_z and N_rdot have the same regressor (only I_z - N_rdot is identifiable), and when u >= 0 the
regressor of m x_g is minus the sum of those of N_vdot and N_|u|r, so only M_v = m x_g - N_vdot
and A = N_|u|r - m x_g are (2.19). :func:`yaw_identifiability` builds the equation-error regressor
matrix of either parameterisation on a noise-free recording and reports its normalised singular
values: an exactly zero one is a direction the data cannot see.

The same dependence holds when u < 0 throughout, with the other sign: an astern recording lumps
-N_|u|r - m x_g (about +5.9e6 for Appendix A, against A = -3.5e6 ahead). So a recording that goes
astern measures a different A, and one that goes both ways has no single A: there |u| r and u r
separate (one zero singular value fewer in the physical parameterisation) and the A u r of (2.17)
is a structural error. The thesis's harbour exit (pods at 90 deg) does exactly that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.yawid.experiment import YawData

COMMON = {
    "N_rr": lambda s: s["r"] * np.abs(s["r"]),
    "N_rv": lambda s: s["r"] * np.abs(s["v"]),
    "N_phiur": lambda s: s["phi"] * s["u"] * np.abs(s["r"]),
    "N_uv": lambda s: np.abs(s["u"]) * s["v"],
    "N_phiuu": lambda s: s["phi"] * s["u"] * np.abs(s["u"]),
    "N_phiuv": lambda s: s["phi"] * np.abs(s["u"] * s["v"]),
}
PHYSICAL = {
    "I_z": lambda s: -s["r_dot"],
    "N_rdot": lambda s: s["r_dot"],
    "m_x_g": lambda s: -(s["v_dot"] + s["u"] * s["r"]),
    "N_vdot": lambda s: s["v_dot"],
    "N_|u|r": lambda s: np.abs(s["u"]) * s["r"],
} | COMMON
LUMPED = {
    "I_r": lambda s: -s["r_dot"],
    "M_v": lambda s: -s["v_dot"],
    "A": lambda s: s["u"] * s["r"],
} | COMMON


@dataclass(frozen=True)
class Identifiability:
    names: tuple[str, ...]
    singular_values: np.ndarray  # of the column-normalised regressor matrix, largest first
    null_directions: list[dict[str, float]]  # one per (numerically) zero singular value

    @property
    def rank_deficiency(self) -> int:
        return len(self.null_directions)


def yaw_identifiability(data: YawData, parameterisation: str = "lumped", rel_tol: float = 1e-9) -> Identifiability:
    """Singular values of the yaw row's regressors on a noise-free recording (section 2.4.2).

    ``parameterisation``: "lumped" (I_r, M_v, A of (2.19)) or "physical" (I_z, N_rdot, m x_g,
    N_vdot, N_|u|r separately).
    """
    table = {"lumped": LUMPED, "physical": PHYSICAL}[parameterisation]
    s = {k: np.asarray(v, float).ravel() for k, v in data.signals.items()}
    ts = data.sample_time
    s["r_dot"] = np.gradient(s["r"], ts)
    cols = np.column_stack([fn(s) for fn in table.values()])
    cols = cols / np.maximum(np.linalg.norm(cols, axis=0), 1e-300)
    _, sv, vt = np.linalg.svd(cols, full_matrices=False)
    null = [dict(zip(table, np.round(vt[i], 6).tolist())) for i in range(len(sv)) if sv[i] < rel_tol * sv[0]]
    return Identifiability(tuple(table), sv, null)
