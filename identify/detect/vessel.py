"""The detection study's ships: seed 000's naval vessel in the shared kernel, nominal or changed.

Truth is :func:`primitives.simulate.simulate` on the 4-DOF podded profile ``naval-vessel``
(surge, sway, yaw, roll; Appendix A, pods of Table 2.1; the choices the thesis leaves open are
written down in that profile and in ``primitives/pods.py``). There is no second simulator here:
a changed ship is the same profile with changed data (:meth:`Vessel.profile`):

- yaw inertia: the rigid body's ``I_z`` (``dataclasses.replace`` of ``profile.rigid_body``;
  seed 000's "10 % more I_z", L1591, moves ``I_r = I_z - N_rdot`` by 5.4 %), or ``I_r`` as a whole;
- yaw damping: every hydrodynamic yaw coefficient of the simulation set (the yaw row's terms
  that are not a pod force; the Coriolis ``-m x_g u r`` is rigid-body and stays);
- pod gain: the coefficients of the pod forces ``tau_x, tau_y, tau_k, tau_n`` in every row (a
  fouled or weaker propulsor). What a recording carries as ``tau_r`` is the pod model's moment
  at gain 1 from the pod inputs and the motion, so a gain change shows in the residual.

Each change is a new parameter set of the profile made its simulation set, so the kernel needs
nothing ship-specific.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import lru_cache

import numpy as np

from identify.yawid.experiment import Noise, pods_inputs, yaw_row_signals
from primitives.ship import ShipProfile, load_profile
from primitives.simulate import simulate

PROFILE = "naval-vessel"
POD_FORCES = ("tau_x", "tau_y", "tau_k", "tau_n")
#: Table 4.1 white measurement noise (standard deviations) of the signals the prior model uses.
TABLE_4_1 = asdict(Noise())  # seed 000 Table 4.1, one source: identify.yawid.experiment.Noise
LEAD_IN_S = 120.0  # straight run from rest before a manoeuvre, so it starts at cruise speed


@lru_cache(maxsize=4)
def base_profile(name: str = PROFILE) -> ShipProfile:
    """The shared kernel's profile of the podded ship (loaded once)."""
    return load_profile(name)


@dataclass(frozen=True)
class Vessel:
    """Scales of the properties a change can hit (1 = the profile as it is)."""

    inertia: float = 1.0  # rigid-body I_z (cargo)
    damping: float = 1.0  # hydrodynamic yaw coefficients
    pod_gain: float = 1.0  # pod force coefficients, all rows
    lumped_inertia: float = 1.0  # I_r = I_z - N_rdot as a whole (the other reading of "10 %")

    def profile(self, base: ShipProfile | None = None) -> ShipProfile:
        """``base`` (default ``naval-vessel``) with this change as profile data."""
        base = base or base_profile()
        if self == Vessel():
            return base
        rb = base.rigid_body
        n_rdot = rb.added["N_rdot"]
        i_r = (rb.i_z * self.inertia - n_rdot) * self.lumped_inertia
        theta = base.params().copy()
        i = 0
        for dof, terms in enumerate(base.model_terms):
            for term in terms:
                if term in POD_FORCES:
                    theta[i] *= self.pod_gain
                elif dof == 2:  # yaw (state order u, v, r, p)
                    theta[i] *= self.damping
                i += 1
        sets = {**base.parameter_sets, "changed": theta}
        return replace(base, rigid_body=replace(rb, i_z=i_r + n_rdot), parameter_sets=sets, simulation_set="changed")


def harbour_inputs(n_samples: int, dt: float, seed: int, n_rps: float = 60.0) -> np.ndarray:
    """Kernel inputs (n_samples, 4) = (n1, delta1, n2, delta2) of harbour-like manoeuvring [choice;
    seed 000 does not give its signals]: random pod-angle steps (both pods together, |delta| <=
    26 deg, one every 15 s) through a 2 s low-pass, propeller speed ``n_rps`` +- 8 rev/s over 400 s
    so that u varies (about 6.3-8.2 m/s) and A u r separates from N_r|r| r|r|. The ship keeps going
    ahead, so the lumped A u r term of (2.17) stays valid (the thesis's pods-at-90-degree harbour
    exit goes astern)."""
    rng = np.random.default_rng(seed)
    hold = int(round(15.0 / dt))
    steps = np.repeat(rng.uniform(-0.45, 0.45, n_samples // hold + 1), hold)[:n_samples]
    n = n_rps + 8.0 * np.sin(2 * np.pi * np.arange(n_samples) * dt / 400.0)
    return pods_inputs(n, steps, dt, tau_s=2.0)


def _run(profile: ShipProfile, inputs: np.ndarray, nu0, eta0) -> tuple[np.ndarray, np.ndarray]:
    res = simulate(profile, inputs, nu0=nu0, eta0=eta0)
    return res.nu[0], res.eta[0]


def truth(
    inputs: np.ndarray,
    vessel: Vessel = Vessel(),
    changed: Vessel | None = None,
    change_at: int | None = None,
    lead_in_s: float = LEAD_IN_S,
) -> dict[str, np.ndarray]:
    """Noise-free signals of a kernel simulation, each (n,) for the ``inputs`` (n, 4) of
    :func:`harbour_inputs`: ``vessel`` throughout, or ``changed`` from sample ``change_at`` on (a
    step change; the second simulation starts from the first one's state).

    A straight lead-in of ``lead_in_s`` at the first propeller speed brings the ship from rest to
    cruise speed; it is dropped. ``v_dot`` is the kernel's Euler increment ``(v(k+1) - v(k)) / Ts``
    and ``tau_r`` the pod model's yaw moment at sample k, so the full yaw row (2.17) with the
    profile's parameters reproduces the kernel's yaw rate exactly (as identify.yawid.true_signals).
    """
    base = base_profile()
    ts = base.sample_time
    lead = np.zeros((int(round(lead_in_s / ts)), inputs.shape[1]))
    lead[:, 0::2] = inputs[0, 0::2]
    nu, eta = _run(vessel.profile(base), np.vstack([lead, inputs]), (0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))
    nu, eta = nu[len(lead) :], eta[len(lead) :]
    eta[:, :2] -= eta[0, :2]
    if change_at is not None:
        k = change_at
        nu_b, eta_b = _run((changed or vessel).profile(base), inputs[k:], nu[k], eta[k])
        nu, eta = np.concatenate([nu[:k], nu_b]), np.concatenate([eta[:k], eta_b])
    yaw = yaw_row_signals(base, nu, eta, inputs)
    return {
        "u": yaw["u"],
        "v": yaw["v"],
        "r": yaw["r"],
        "p": nu[:-1, 3],
        "x": eta[:-1, 0],
        "y": eta[:-1, 1],
        "psi": eta[:-1, 2],
        "phi": yaw["phi"],
        "v_dot": yaw["v_dot"],
        "tau_r": yaw["tau_r"],
    }


def measure(
    tr: dict[str, np.ndarray], noise: dict[str, float], rng: np.random.Generator, runs: int | None = None
) -> dict[str, np.ndarray]:
    """Measured signals with white noise of the given standard deviations (Table 4.1 names);
    ``runs`` adds a second axis of independent realisations."""
    n = len(tr["r"])
    shape = (n,) if runs is None else (n, runs)
    out = {}
    for k in ("u", "v", "r", "phi", "v_dot", "tau_r"):
        x = tr[k] if runs is None else tr[k][:, None]
        out[k] = x + noise.get(k, 0.0) * rng.standard_normal(shape)
    return out
