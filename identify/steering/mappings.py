"""Hydrodynamic derivatives -> Nomoto transfer-function parameters, prime system (Källström 1977).

The linear sway-yaw model in the prime system (time in units of L/V, mass unit rho L^3 / 2),
Källström (1977) eq. (3.1) without wind and delay:

    M x' = N x + b delta,   x = [v', r'],
    M = [[m'-Y_vdot', m'x_G'-Y_rdot'], [m'x_G'-N_vdot', I_z'-N_rdot']]   (theta_1..theta_4)
    N = [[Y_v', Y_r'-m'], [N_v', N_r'-m'x_G']]                             (theta_5..theta_8)
    b = [Y_delta', N_delta']                                                (theta_11, -theta_11 theta_12)

gives the transfer functions (3.6)/(3.7), primed by (3.8):

    psi/delta = K' (1 + s T3') / (s (1 + s T1')(1 + s T2')) = K1' (s + 1/T3') / (s (s + 1/T1')(s + 1/T2'))
    v'/delta  = K_v' (1 + s T3v') / ((1 + s T1')(1 + s T2')) = K1v' (s + 1/T3v') / ((s + 1/T1')(s + 1/T2'))

and the observable canonical form (4.1) with phi_3 = 0 gives (4.2)/(4.3):
    phi_1 = 1/T1' + 1/T2',  phi_2 = 1/(T1' T2'),  phi_4 = K1',  phi_5 = K1'/T3'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Table 3.1 (Källström 1977): SSPA's adjusted model-test values for a tanker similar to the Sea Splendour
SSPA_DERIVATIVES = {
    "th1": 0.0156,
    "th2": 0.0,
    "th3": 0.0,
    "th4": 0.00096,
    "Yv": -0.0113,
    "Yr": -0.0048,
    "Nv": -0.0018,
    "Nr": -0.0024,
    "Yd": 0.0018,
    "Nd": -0.00086,
}


@dataclass(frozen=True)
class Nomoto2:
    """Second-order Nomoto parameters in the prime system (3.6)-(3.8); T1' >= T2' when both are real.
    Complex time constants (an oscillatory yaw mode) are NaN."""

    K: float
    K1: float
    T1: float
    T2: float
    T3: float
    Kv: float = float("nan")
    K1v: float = float("nan")
    T3v: float = float("nan")

    def as_dict(self) -> dict[str, float]:
        return {
            "K'": self.K,
            "K1'": self.K1,
            "T1'": self.T1,
            "T2'": self.T2,
            "T3'": self.T3,
            "Kv'": self.Kv,
            "K1v'": self.K1v,
            "T3v'": self.T3v,
        }


def prime_state_matrices(d: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """A' = M^-1 N and B' = M^-1 b of (3.1) for x = [v', r'] in prime time (t V / L)."""
    M = np.array([[d["th1"], d["th2"]], [d["th3"], d["th4"]]], float)
    N = np.array([[d["Yv"], d["Yr"]], [d["Nv"], d["Nr"]]], float)
    b = np.array([d["Yd"], d["Nd"]], float)
    return np.linalg.solve(M, N), np.linalg.solve(M, b)


def _time_constants(trace: float, det: float) -> tuple[float, float]:
    """T1', T2' = -1/eigenvalues of a 2x2 matrix from its trace and determinant (T1' the larger
    when both are positive: the slow mode; an unstable mode gives a negative T)."""
    disc = trace * trace - 4.0 * det
    if disc < 0:
        return float("nan"), float("nan")
    lam = np.array([(trace + np.sqrt(disc)) / 2.0, (trace - np.sqrt(disc)) / 2.0])
    with np.errstate(divide="ignore"):
        T = -1.0 / lam
    # slow mode first: the eigenvalue closest to zero
    order = np.argsort(np.abs(lam))
    return float(T[order[0]]), float(T[order[1]])


def derivatives_to_nomoto(d: dict[str, float]) -> Nomoto2:
    """Table 3.3/3.6's mapping: prime derivatives (keys of :data:`SSPA_DERIVATIVES`) -> K', K1', T1',
    T2', T3', K_v', K1v', T3v' of (3.6)-(3.8)."""
    A, B = prime_state_matrices(d)
    T1, T2 = _time_constants(float(np.trace(A)), float(np.linalg.det(A)))
    det = float(np.linalg.det(A))
    adj = np.array([[A[1, 1], -A[0, 1]], [-A[1, 0], A[0, 0]]])
    with np.errstate(divide="ignore", invalid="ignore"):
        static = -(adj @ B) / det  # steady [v', r'] per unit rudder (infinite at a zero eigenvalue)
    # numerators of r/delta and v/delta: e^T adj(sI - A) B = s B_i + (A_ij B_j - A_jj B_i)
    K1, K1v = float(B[1]), float(B[0])
    z_r = A[1, 0] * B[0] - A[0, 0] * B[1]
    z_v = A[0, 1] * B[1] - A[1, 1] * B[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        T3, T3v = K1 / z_r, K1v / z_v
    return Nomoto2(float(static[1]), K1, T1, T2, float(T3), float(static[0]), K1v, float(T3v))


def canonical_to_nomoto(ph1: float, ph2: float, ph4: float, ph5: float) -> Nomoto2:
    """Table 4.2's mapping: the coefficients of (4.2) with phi_3 = 0 -> K', K1', T1', T2', T3' of (4.3)."""
    T1, T2 = _time_constants(-ph1, ph2)
    with np.errstate(divide="ignore", invalid="ignore"):
        K = ph5 / ph2
        T3 = ph4 / ph5
    return Nomoto2(float(K), float(ph4), T1, T2, float(T3))


def nomoto_to_canonical(K: float, T1: float, T2: float, T3: float) -> tuple[float, float, float, float]:
    """The inverse of :func:`canonical_to_nomoto`: (phi_1, phi_2, phi_4, phi_5) of (4.2) from K', T1', T2', T3'."""
    ph2 = 1.0 / (T1 * T2)
    ph5 = K * ph2
    return 1.0 / T1 + 1.0 / T2, ph2, ph5 * T3, ph5
