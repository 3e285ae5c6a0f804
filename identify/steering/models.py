"""Steering model structures and their exact zero-order-hold sampling on irregular time grids.

Three structures, all continuous-time and linear with inputs [delta, U] (rudder angle in rad and
Källström's artificial unit step U that carries the biases), measured at discrete, possibly
irregular instants (Källström 1977, eqs. (3.1) and (4.1)):

- ``nomoto1``: T r' + r = K (delta + delta_0), psi' = r (Nomoto's first-order model); states [r, psi].
- ``nomoto2``: the observable canonical form (4.1) with phi_3 = 0, psi/delta = (4.2)-(4.3); states
  [x1, r, psi]; the bias is a rudder offset delta_0 on both input columns.
- ``state-space``: (3.1) in [v, r, psi] with the acceleration derivatives theta_1..theta_4 fixed
  (Table 3.1's SSPA values unless given), force and moment biases theta_13, theta_14 on U.

Optional (``Structure(..., wind=True)``): Källström's heading-dependent wind, a steady wind's force and moment
linear in the heading — in (3.1) the prime force theta_9 psi and moment theta_9 theta_10 psi (here ``Y_psi`` and
``N_psi``, estimated separately so that neither is undetermined when the other is small), in (4.1) phi_3, the
constant term it adds to the denominator s^3 + phi_1 s^2 + phi_2 s + phi_3 (prime time). The spring is taken
about each record's initial heading psi_0: the wind's force and moment at psi_0 are constants the biases
already carry, so the biases keep their meaning. ``Structure(..., log_x=x_L)``: the Doppler log x_L metres
forward of midship measures v + x_L r (Källström's v1 = alpha2 (v + L1 r)); v stays the sway at midship.

Dynamics parameters are the primed ones (time in L/V, Källström's (3.8)), so their intervals are the
intervals of K', T'; the rate gyro and sway log get a bias on U (theta_15..theta_17, phi_8); the
heading has none (the initial heading absorbs it). Process noise enters the rate equations
(R1 of (3.1)/(4.1)), with ``Structure(..., noise_corr=True)`` correlated between them as in Källström's R1
(R1(1,2) = sqrt(R1(1,1) R1(2,2)) sin theta_20; here tanh, monotone); measurement noise is diagonal (R2).

Sampling (Källström's ISAMP = 3, exact for any step): for each distinct interval h,
Phi = e^{A h}, Gamma = int_0^h e^{A s} ds B (Van Loan 1978's block exponential), and
Qd = int_0^h e^{A s} Qc e^{A' s} ds from the block exponential [[-A, Qc], [0, A']] over h / 2^m, doubled m times.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identify.steering.mappings import SSPA_DERIVATIVES, prime_state_matrices

# the parameter of the process noise's correlation coefficient, rho = tanh(atanh_rho_q)
RHO = "atanh_rho_q"


@dataclass(frozen=True)
class Param:
    """One model parameter: name, unit text, typical size (the optimiser's scale) and role."""

    name: str
    unit: str
    scale: float
    role: str  # "dynamics" | "bias" | "initial" | "noise"


@dataclass
class Structure:
    """A model structure for given ship length L [m] and speed V [m/s] and measured channels."""

    name: str
    L: float
    V: float
    channels: tuple[str, ...]
    accel: dict[str, float] = field(default_factory=lambda: {k: SSPA_DERIVATIVES[k] for k in ("th1", "th2", "th3", "th4")})
    wind: bool = False  # estimate the heading-dependent wind (Y_psi, N_psi or phi_3)
    log_x: float = 0.0  # the sway log's distance forward of midship [m]: it measures v + log_x r
    noise_corr: bool = False  # estimate the correlation of the two rate equations' process noise (R1(1,2))

    def __post_init__(self) -> None:
        if self.name not in STRUCTURES:
            raise ValueError(f"unknown steering model {self.name!r}; one of {', '.join(STRUCTURES)}")
        if self.wind and self.name == "nomoto1":
            raise ValueError("heading-dependent wind is a parameter of the nomoto2 and state-space models (4.1), (3.1)")
        if self.noise_corr and self.name == "nomoto1":
            raise ValueError("correlated process noise needs two noisy states: the nomoto2 and state-space models (4.1), (3.1)")
        self.params: tuple[Param, ...] = STRUCTURES[self.name](self)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def n_states(self) -> int:
        return 2 if self.name == "nomoto1" else 3

    def system(self, p: dict[str, float]) -> tuple[np.ndarray, ...]:
        """(A, B, C, D, x0, Qc) in SI units for parameter values ``p`` (missing noise entries: zero)."""
        return _SYSTEMS[self.name](self, p)


# -- structures -------------------------------------------------------------------------------------


def _common(s: Structure, rate_noise: tuple[str, ...]) -> list[Param]:
    out = [Param("T_D", "s", 10.0, "delay")]
    if "v" in s.channels:
        out.append(Param("b_v", "m/s", 0.05, "bias"))
    if "r" in s.channels:
        out.append(Param("b_r", "rad/s", 1e-4, "bias"))
    out += [Param(n, "ln", 1.0, "noise") for n in rate_noise]
    if s.noise_corr:  # R1(1,2) = sqrt(R1(1,1) R1(2,2)) tanh(z): Källström's sin(theta_20) without its periodicity
        out.append(Param(RHO, "-", 1.0, "noise"))
    # measured variances relative to the heading's (fixed: the scale ambiguity of the likelihood)
    out += [Param(f"ln_R_{c}", "ln", 1.0, "noise") for c in s.channels if c != "psi"]
    return out


def _nomoto1_params(s: Structure) -> tuple[Param, ...]:
    return tuple(
        [
            Param("K'", "-", 1.0, "dynamics"),
            Param("T'", "-", 1.0, "dynamics"),
            Param("delta_0", "rad", 0.01, "bias"),
            Param("r_0", "rad/s", 1e-3, "initial"),
            Param("psi_0", "rad", 0.1, "initial"),
        ]
        + _common(s, ("ln_q_r",))
    )


def _nomoto2_params(s: Structure) -> tuple[Param, ...]:
    return tuple(
        [
            Param("phi_1", "-", 1.0, "dynamics"),
            Param("phi_2", "-", 0.5, "dynamics"),
            Param("phi_4", "-", 0.5, "dynamics"),
            Param("phi_5", "-", 0.5, "dynamics"),
            Param("delta_0", "rad", 0.01, "bias"),
            *([Param("phi_3", "-", 0.01, "wind")] if s.wind else []),
            Param("rdot_0", "rad/s^2", 1e-5, "initial"),
            Param("r_0", "rad/s", 1e-3, "initial"),
            Param("psi_0", "rad", 0.1, "initial"),
        ]
        + _common(s, ("ln_q_x", "ln_q_r"))
    )


def _state_space_params(s: Structure) -> tuple[Param, ...]:
    dyn = [Param(n, "-", 0.005, "dynamics") for n in ("Yv", "Yr", "Nv", "Nr")]
    dyn += [Param("Yd", "-", 0.002, "dynamics"), Param("Nd", "-", 0.001, "dynamics")]
    # the sway-force bias theta_13 and the log's bias b_v move the measured sway by constants only the sum of
    # which a record sees (the yaw rate's mean is fixed by the heading): with v measured, theta_13 is held at zero
    nuis = [Param("th13", "-", 1e-4, "bias")] if "v" not in s.channels else []
    nuis += [Param("Y_psi", "-", 1e-4, "wind"), Param("N_psi", "-", 1e-5, "wind")] if s.wind else []
    nuis += [
        Param("th14", "-", 1e-5, "bias"),
        Param("v_0", "m/s", 0.1, "initial"),
        Param("r_0", "rad/s", 1e-3, "initial"),
        Param("psi_0", "rad", 0.1, "initial"),
    ]
    return tuple(dyn + nuis + _common(s, ("ln_q_v", "ln_q_r")))


STRUCTURES = {"nomoto1": _nomoto1_params, "nomoto2": _nomoto2_params, "state-space": _state_space_params}


def _outputs(s: Structure, p: dict[str, float], rows: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
    n = s.n_states
    C = np.zeros((len(s.channels), n))
    D = np.zeros((len(s.channels), 2))
    for i, c in enumerate(s.channels):
        C[i, rows[c]] = 1.0
        if c == "v":
            C[i, rows["r"]] = s.log_x
        if c != "psi":
            D[i, 1] = p[f"b_{c}"]
    return C, D


# reference sizes of the noise intensities (ln_q = 0, ln_R = 0): process noise that moves the yaw rate by
# about 1e-4 rad/s in a second, heading noise of 0.1 deg (the likelihood's scale is fixed by the heading's)
Q_REF = {"ln_q_r": 1e-8, "ln_q_x": 1e-8, "ln_q_v": 1e-4}
R_REF = {"psi": np.radians(0.1) ** 2, "r": np.radians(0.01) ** 2, "v": 0.01**2}


def _q(p: dict[str, float], name: str) -> float:
    return float(Q_REF[name] * np.exp(p[name])) if name in p else 0.0


def _rate_noise(p: dict[str, float], q1: float, q2: float) -> np.ndarray:
    """R1 of (3.1)/(4.1) (Källström 1977): the two rate equations' intensities q1, q2 on the diagonal and
    sqrt(q1 q2) rho off it, |rho| < 1 so that R1 stays positive semi-definite (rho = 0 without the parameter);
    the heading's row and column are zero."""
    c = np.sqrt(q1 * q2) * float(np.tanh(p.get(RHO, 0.0)))
    return np.array([[q1, c, 0.0], [c, q2, 0.0], [0.0, 0.0, 0.0]])


def measurement_variances(s: Structure, p: dict[str, float]) -> np.ndarray:
    """Diagonal of R2 relative to the likelihood's scale: the heading's fixed, the others R_REF e^{ln_R}."""
    return np.array([R_REF[c] * (np.exp(p[f"ln_R_{c}"]) if f"ln_R_{c}" in p else 1.0) for c in s.channels])


def _nomoto1_system(s: Structure, p: dict[str, float]) -> tuple[np.ndarray, ...]:
    K, T = p["K'"] * s.V / s.L, p["T'"] * s.L / s.V
    A = np.array([[-1.0 / T, 0.0], [1.0, 0.0]])
    B = np.array([[K / T, K / T * p["delta_0"]], [0.0, 0.0]])
    C, D = _outputs(s, p, {"r": 0, "psi": 1})
    x0 = np.array([p["r_0"], p["psi_0"]])
    return A, B, C, D, x0, np.diag([_q(p, "ln_q_r"), 0.0])


def _nomoto2_system(s: Structure, p: dict[str, float]) -> tuple[np.ndarray, ...]:
    a = s.V / s.L
    ph1, ph2, ph4, ph5 = p["phi_1"], p["phi_2"], p["phi_4"], p["phi_5"]
    A = np.array([[0.0, 0.0, 0.0], [1.0, -a * ph1, -a * a * ph2], [0.0, 1.0, 0.0]])
    b = np.array([a**3 * ph5, a * a * ph4, 0.0])
    B = np.stack([b, b * p["delta_0"]], axis=1)
    if s.wind:  # x1' = ... - a^3 phi_3 (psi - psi_0): the constant part at psi_0 on the unit step
        A[0, 2] = -(a**3) * p["phi_3"]
        B[0, 1] += a**3 * p["phi_3"] * p["psi_0"]
    C, D = _outputs(s, p, {"r": 1, "psi": 2})
    # x1 from the initial yaw acceleration (r' = x1 - a phi_1 r - a^2 phi_2 psi + a^2 phi_4 delta), so that the
    # initial state does not depend on where north is; the rudder part is taken at delta = delta_0 only
    x1 = p["rdot_0"] + a * ph1 * p["r_0"] + a * a * ph2 * p["psi_0"] - a * a * ph4 * p["delta_0"]
    x0 = np.array([x1, p["r_0"], p["psi_0"]])
    return A, B, C, D, x0, _rate_noise(p, _q(p, "ln_q_x") * a * a, _q(p, "ln_q_r"))


def _state_space_system(s: Structure, p: dict[str, float]) -> tuple[np.ndarray, ...]:
    L, V = s.L, s.V
    d = dict(s.accel)
    d.update({k: p[k] for k in ("Yv", "Yr", "Nv", "Nr", "Yd", "Nd")})
    Ap, Bp = prime_state_matrices(d)
    _, Bb = prime_state_matrices({**d, "Yd": p.get("th13", 0.0), "Nd": p["th14"]})
    # prime -> SI: v = V v', r = (V/L) r', t = (L/V) t'
    Sx = np.diag([V, V / L])
    A2 = (V / L) * Sx @ Ap @ np.linalg.inv(Sx)
    A = np.zeros((3, 3))
    A[:2, :2] = A2
    A[2, 1] = 1.0
    B = np.zeros((3, 2))
    B[:2, 0] = (V / L) * Sx @ Bp
    B[:2, 1] = (V / L) * Sx @ Bb
    if s.wind:  # the wind's prime force and moment per radian of heading, about the initial heading
        _, Bw = prime_state_matrices({**d, "Yd": p["Y_psi"], "Nd": p["N_psi"]})
        A[:2, 2] = (V / L) * Sx @ Bw
        B[:2, 1] -= A[:2, 2] * p["psi_0"]
    C, D = _outputs(s, p, {"v": 0, "r": 1, "psi": 2})
    x0 = np.array([p["v_0"], p["r_0"], p["psi_0"]])
    return A, B, C, D, x0, _rate_noise(p, _q(p, "ln_q_v"), _q(p, "ln_q_r"))


_SYSTEMS = {"nomoto1": _nomoto1_system, "nomoto2": _nomoto2_system, "state-space": _state_space_system}


# -- sampling ---------------------------------------------------------------------------------------


def intervals(t: np.ndarray, rel: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """The distinct sampling intervals of ``t`` (to ``rel`` of the median) and each step's index into them."""
    dt = np.diff(np.asarray(t, float))
    tol = rel * max(float(np.median(dt)), 1e-12)
    key = np.round(dt / tol).astype(np.int64)
    _, idx = np.unique(key, return_inverse=True)
    idx = idx.astype(np.int64).ravel()
    return np.bincount(idx, dt) / np.bincount(idx), idx


def expm(M: np.ndarray) -> np.ndarray:
    """Matrix exponentials of a stack (m, k, k) of small matrices: scaling and squaring with an order-18 Taylor
    series on norms <= 1/2 (truncation below 1e-21). For the 2x2-6x6 matrices here it is about a hundred
    times cheaper than scipy.linalg.expm's general Pade path under load."""
    M = np.asarray(M, float)
    norm = np.max(np.sum(np.abs(M), axis=-1), axis=-1)
    s = int(max(0, np.ceil(np.log2(max(float(norm.max()), 1e-300) / 0.5))))
    X = M / 2.0**s
    E = np.broadcast_to(np.eye(M.shape[-1]), M.shape).copy()
    term = E.copy()
    for k in range(1, 19):
        term = term @ X / k
        E += term
    for _ in range(s):
        E = E @ E
    return E


def discretize(
    A: np.ndarray, B: np.ndarray, Qc: np.ndarray, h: np.ndarray, delay: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact zero-order-hold sampling for each interval in ``h`` with the rudder delayed by ``delay`` <= h
    (Källström's T_D): Phi (m, n, n), Gamma (m, n, 3) for the inputs [delta_k, U, delta_{k-1}], Qd (m, n, n).
    Over [t_k, t_k + T_D) the ship still feels delta_{k-1}, then delta_k: Gamma_delta = Gamma(h - T_D),
    Gamma_delta_prev = Phi(h - T_D) Gamma(T_D) (Åström and Wittenmark, Computer-Controlled Systems, sec. 2.3;
    Van Loan 1978's block matrix exponentials, batched over the intervals)."""
    n = B.shape[0]
    h = np.asarray(h, float)
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M[None] * np.concatenate([h - delay, h, np.full(1, delay)])[:, None, None])
    m = len(h)
    Ea, Eh, Ed = E[:m], E[m : 2 * m], E[2 * m]
    Phi = Eh[:, :n, :n]
    Gam = np.empty((m, n, 3))
    Gam[:, :, 0] = Ea[:, :n, n]
    Gam[:, :, 1] = Eh[:, :n, n + 1]
    Gam[:, :, 2] = Ea[:, :n, :n] @ Ed[:n, n]
    if not np.any(Qc):
        return Phi, Gam, np.zeros((len(h), n, n))
    return Phi, Gam, process_noise(A, Qc, h)


def process_noise(A: np.ndarray, Qc: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Qd = int_0^h e^{A s} Qc e^{A' s} ds for each interval: Van Loan's (1978) block exponential
    [[-A, Qc], [0, A']] over h / 2^m with ||A|| h / 2^m <= 1/2, then doubled m times,
    Qd(2 h) = Phi(h) Qd(h) Phi(h)' + Qd(h). The block exponential over the whole interval holds e^{-A h},
    which for a fast mode across a long interval (a 3 s time constant across the 210 s gap of seven lost 30 s
    readings: e^{70}) cancels catastrophically and gives an indefinite Qd, a negative innovation variance and a failed fit;
    the doubling adds positive semi-definite terms only."""
    n = A.shape[0]
    norm = float(np.max(np.sum(np.abs(A), axis=1))) * float(np.max(h))
    m = int(max(0, np.ceil(np.log2(max(norm, 1e-300) / 0.5))))
    hs = h / 2.0**m
    W = np.zeros((2 * n, 2 * n))
    W[:n, :n], W[:n, n:], W[n:, n:] = -A, Qc, A.T
    F = expm(W[None] * hs[:, None, None])
    Phi = np.swapaxes(F[:, n:, n:], 1, 2)  # e^{A hs}
    Qd = Phi @ F[:, :n, n:]
    for _ in range(m):
        Qd = Phi @ Qd @ np.swapaxes(Phi, 1, 2) + Qd
        Phi = Phi @ Phi
    return 0.5 * (Qd + np.swapaxes(Qd, 1, 2))
