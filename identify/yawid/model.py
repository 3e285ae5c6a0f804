"""Yaw models (2.17) "full" and (2.18) "simplified" of the podded-ship MSc thesis with the lumped parameters (2.19).

    I_r r_dot = -M_v v_dot + A u r + N_r|r| r|r| + N_r|v| r|v| + N_phiu|r| phi u|r|
                + N_|u|v |u|v + N_phi|uv| phi|uv| + N_phiu|u| phi u|u| + tau_r,act        (2.17)
    I_r r_dot = A u r + N_r|r| r|r| + N_r|v| r|v| + N_|u|v |u|v + tau_r,act               (2.18)

    I_r = I_z - N_rdot,  M_v = m x_g - N_vdot,  A = N_|u|r - m x_g                        (2.19)

The lumping of N_|u|r |u| r with the Coriolis -m x_g u r into A u r holds only for u >= 0
(section 2.4.2): :func:`forward_only` says when a recording breaks it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primitives.ship import ProfileError, ShipProfile

# r-dependent regressors: name -> (value(r, w), d value / d r); w holds the measured inputs at k.
STATE_TERMS = {
    "A": (lambda r, w: w["u"] * r, lambda r, w: w["u"]),
    "N_rr": (lambda r, w: r * np.abs(r), lambda r, w: 2.0 * np.abs(r)),
    "N_rv": (lambda r, w: r * np.abs(w["v"]), lambda r, w: np.abs(w["v"])),
    "N_phiur": (lambda r, w: w["phi"] * w["u"] * np.abs(r), lambda r, w: w["phi"] * w["u"] * np.sign(r)),
}
# regressors of the measured inputs only
INPUT_TERMS = {
    "M_v": lambda w: -w["v_dot"],
    "N_uv": lambda w: np.abs(w["u"]) * w["v"],
    "N_phiuv": lambda w: w["phi"] * np.abs(w["u"] * w["v"]),
    "N_phiuu": lambda w: w["phi"] * w["u"] * np.abs(w["u"]),
    "N_p": lambda w: w["p"],
}
# Sign constraints of section 4.3 (L1240-1243): I_r > 0 and the damping coefficients <= 0. The
# cross couplings M_v, N_phiu|u|, N_phi|uv| are left free (they are not damping terms).
NEGATIVE = frozenset({"A", "N_rr", "N_rv", "N_phiur", "N_uv"})


@dataclass(frozen=True)
class YawModel:
    """One estimation model: its parameter names in the thesis's order (Table 6.1, Fig. 4.8)."""

    name: str
    params: tuple[str, ...]

    @property
    def state_terms(self) -> tuple[str, ...]:
        return tuple(p for p in self.params if p in STATE_TERMS)

    @property
    def input_terms(self) -> tuple[str, ...]:
        return tuple(p for p in self.params if p in INPUT_TERMS)

    @property
    def signals(self) -> tuple[str, ...]:
        """Measured signals this model needs besides r and tau_r."""
        need = {"u", "v"}
        if "M_v" in self.params:
            need.add("v_dot")
        if any(p.startswith("N_phi") for p in self.params):
            need.add("phi")
        if "N_p" in self.params:
            need.add("p")
        return tuple(s for s in ("v_dot", "u", "v", "phi", "p") if s in need)


FULL = YawModel("full", ("I_r", "M_v", "A", "N_rr", "N_rv", "N_phiur", "N_uv", "N_phiuu", "N_phiuv"))
SIMPLIFIED = YawModel("simplified", ("I_r", "A", "N_rr", "N_rv", "N_uv"))
MODELS = {"full": FULL, "simplified": SIMPLIFIED}
#: (2.17) with a yaw moment from the roll rate, ``+ N_p p``: a real hull's roll-yaw coupling that
#: (2.17) leaves out (Blanke and Christensen 1993 list roll-rate terms in the roll and sway rows;
#: a strongly rolling ship's yaw feels its own). Not one of yawid's models: the change detector's
#: prior uses it when the recording has the roll rate ``p``.
FULL_P = YawModel("full-p", (*FULL.params, "N_p"))

# Symbols as the thesis prints them, for tables.
LABELS = {
    "I_r": "I_r",
    "M_v": "M_v",
    "A": "A",
    "N_rr": "N_r|r|",
    "N_rv": "N_r|v|",
    "N_phiur": "N_phiu|r|",
    "N_uv": "N_|u|v",
    "N_phiuu": "N_phiu|u|",
    "N_phiuv": "N_phi|uv|",
    "N_p": "N_p",
}


def true_parameters(profile: ShipProfile, theta: str | np.ndarray | None = None) -> dict[str, float]:
    """The lumped yaw parameters (2.19) of a 4-DOF profile's parameter set (all nine of (2.17))."""
    rb = profile.rigid_body
    if rb is None or profile.n_dof != 4:
        raise ProfileError(
            f"ship {profile.name!r} has no roll DOF and rigid body: yaw identification needs a 4-DOF profile like 'naval-vessel'"
        )
    vals = profile.params(theta)[profile.model.dof_slice(2)]
    yaw = dict(zip(profile.model.terms[2], vals))

    def coef(term: str) -> float:
        return float(yaw.get(term, 0.0))

    return {
        "I_r": rb.i_z - rb.added["N_rdot"],
        "M_v": rb.mass * rb.x_g - rb.added["N_vdot"],
        "A": coef("|u|*r") - rb.mass * rb.x_g,
        "N_rr": coef("r*|r|"),
        "N_rv": coef("r*|v|"),
        "N_phiur": coef("phi*u*|r|"),
        "N_uv": coef("|u|*v"),
        "N_phiuu": coef("phi*u*|u|"),
        "N_phiuv": coef("phi*|u|*|v|"),
    }


def forward_only(u: np.ndarray, tol: float = 0.0) -> float:
    """Fraction of samples with u < -tol: where A u r of (2.17) no longer equals
    N_|u|r |u| r - m x_g u r (section 2.4.2)."""
    return float(np.mean(np.asarray(u) < -tol))
