"""Yaw row of the seed-000 multipurpose naval vessel, simplified model (2.18), for the detection study.

    I_r r' = A u r + N_r|r| r|r| + N_r|v| r|v| + N_|u|v |u| v + tau_r,act        (2.18)

with the nominal values of the digest's section 3.3 (Appendix A of seed 000). Surge ``u``, sway
``v`` and the actuator moment are inputs, as in the thesis (L859-860). The actuator moment here is
the two pods' side force at a fixed propeller speed, (2.9b)/(2.9d) with sigma = 0 and (2.12)
``x_pod F_y``. NOTE: this is the yaw row only, driven by prescribed u and v; the 4-DOF podded
model in the shared simulation kernel (roll as an optional DOF) remains to be done.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter


@dataclass(frozen=True)
class YawParams:
    I_r: float = 62.4e6
    A: float = -3.49658e6
    N_rr: float = -202e6
    N_rv: float = -15.6e6
    N_uv: float = -92000.0
    gain: float = 1.0  # actuator (pod) moment scale


RHO, D, A_POD, X_POD = 1025.0, 0.42, 2.5, -23.5


def pod_moment(delta: np.ndarray, u: np.ndarray, n: float) -> np.ndarray:
    """Yaw moment of two identical pods at angle ``delta`` [rad], (2.9b), (2.9d), (2.12) with sigma = 0."""
    fy_m = RHO * D**4 * np.sin(delta) * (0.484 * n**2 + 0.7 * n * D * u)
    fy_r = 0.5 * RHO * A_POD * u**2 * 1.2 * np.sin(2 * delta)
    return 2 * X_POD * (fy_m + fy_r)


def harbour_inputs(n_samples: int, dt: float, seed: int) -> dict[str, np.ndarray]:
    """Harbour-like manoeuvring: low-pass filtered random pod-angle steps, u ~ 6-8 m/s, small drift v."""
    rng = np.random.default_rng(seed)
    steps = np.repeat(rng.uniform(-0.35, 0.35, n_samples // 300 + 1), 300)[:n_samples]
    a = np.exp(-dt / 8.0)
    delta = lfilter([1 - a], [1, -a], steps)
    u = 7.0 + 1.0 * np.sin(2 * np.pi * np.arange(n_samples) * dt / 400.0)
    return {"delta": delta, "u": u, "n": np.full(n_samples, 3.0)}


def simulate_yaw(p: YawParams, inputs: dict[str, np.ndarray], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Yaw rate ``r`` and sway ``v`` by Heun's method; ``u`` may be (n,) or (n, runs) (vectorised).

    Sway is a quasi-static drift ``v = -20 r`` (pivot point ~20 m forward) [choice], so the
    ``r|v|`` and ``|u|v`` terms act in turns.
    """
    delta, u = inputs["delta"], inputs["u"]
    n = float(inputs["n"][0])
    delta = delta.reshape(len(delta), *([1] * (u.ndim - 1)))
    tau = p.gain * pod_moment(delta, u, n)

    def f(rr: np.ndarray, k: int) -> np.ndarray:
        vv = -20.0 * rr
        uk = u[k]
        return (p.A * uk * rr + p.N_rr * rr * np.abs(rr) + p.N_rv * rr * np.abs(vv) + p.N_uv * np.abs(uk) * vv + tau[k]) / p.I_r

    r = np.zeros(u.shape)
    for k in range(len(u) - 1):
        k1 = f(r[k], k)
        k2 = f(r[k] + dt * k1, k + 1)
        r[k + 1] = r[k] + 0.5 * dt * (k1 + k2)
    return r, -20.0 * r


def signatures(p: YawParams, inputs: dict[str, np.ndarray], dt: float, rel: float = 0.1) -> tuple[tuple[str, ...], np.ndarray]:
    """``d r_hat / d ln(param)`` for yaw inertia, yaw damping (all damping terms) and pod gain."""
    base, _ = simulate_yaw(p, inputs, dt)
    damp = {k: getattr(p, k) * (1 + rel) for k in ("A", "N_rr", "N_rv", "N_uv")}
    cols = [simulate_yaw(replace(p, I_r=p.I_r * (1 + rel)), inputs, dt)[0],
            simulate_yaw(replace(p, **damp), inputs, dt)[0],
            simulate_yaw(replace(p, gain=1 + rel), inputs, dt)[0]]
    return ("yaw_inertia", "yaw_damping", "pod_gain"), np.column_stack([(c - base) / rel for c in cols])
