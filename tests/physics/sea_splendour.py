"""A simulated Sea Splendour steering experiment: the independent truth of ``shiptrial steering``.

Källström (1977), "Identification of the linear steering dynamics of the tanker Sea Splendour": a
255 000 tdw tanker in ballast, L = 329.2 m, at V = 8.2 m/s. The truth is the linear sway-yaw model in
the prime system with SSPA's derivatives (Table 3.1, the first column of Table 3.2), integrated here
with classical RK4 at a 0.5 s step, plus what the estimator does not model:

- a rudder machine with a rate limit (2.32 deg/s, the SOLAS minimum): the ship feels the rate-limited
  rudder, not the command;
- a PRBS rudder command on the process computer's clock (+-5 deg about the course-keeping angle,
  switching at most every reading, recorded as the servo command at the reading) with manual changes (10 deg towards the set course, through the computer) when the heading strays
  more than 6 deg from the set course, and the 20 deg course change to port in the middle (140 -> 120 deg);
- a 10 m/s wind from starboard whose force and moment depend on the relative wind angle (a heading
  spring that turns with the course change);
- white force and moment disturbances (sea; correlated with ``Experiment.sea_corr``), sensor biases (rate gyro 0.004 deg/s, Doppler log 0.1 kn),
  quantisation (rudder 0.6 deg, compass 1/6 deg), gyro noise 0.005 deg/s, Doppler noise 0.02 kn;
- sampling every 30 s (experiment 1) or 15 s (experiment 2), "a few seconds too long sometimes",
  and seven consecutive readings lost (1520-1700 s and 600-690 s).

It shares no code with :mod:`identify.steering`: its own prime-system equations, integration,
rudder machine and Nomoto parameters (:data:`TRUTH`, from the characteristic polynomial here).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

L, V = 329.2, 8.2
RHO_AIR, RHO_WATER = 1.226, 1025.0
# Table 3.1 (SSPA): acceleration derivatives, linear derivatives, rudder derivatives (prime system)
M_PRIME = np.array([[0.0156, 0.0], [0.0, 0.00096]])
N_PRIME = np.array([[-0.0113, -0.0048], [-0.0018, -0.0024]])
B_PRIME = np.array([0.0018, -0.00086])
RUDDER_RATE = np.radians(2.32)
STEP = 0.5


def _truth() -> dict[str, float]:
    """K', T1', T2', T3' of the linear model: poles from the characteristic polynomial, zero from the numerator
    of r/delta = (s b_r + A_rv b_v - A_vv b_r) / (s^2 - tr A s + det A) (prime time)."""
    A = np.linalg.inv(M_PRIME) @ N_PRIME
    b = np.linalg.inv(M_PRIME) @ B_PRIME
    poles = np.roots([1.0, -np.trace(A), np.linalg.det(A)])
    T = sorted((-1.0 / poles).real, reverse=True)
    num0 = A[1, 0] * b[0] - A[0, 0] * b[1]
    return {"K'": num0 / np.linalg.det(A), "T1'": T[0], "T2'": T[1], "T3'": b[1] / num0}


TRUTH = _truth()


@dataclass(frozen=True)
class Experiment:
    """Sampling and recording choices of one experiment."""

    sample_time: float = 30.0
    duration_s: float = 3120.0
    missing: tuple[float, float] = (1520.0, 1700.0)  # readings lost in this window (7 at 30 s)
    record_command: bool = True  # the servo position (command) at the reading; False: the rudder angle
    wind_speed: float = 10.0
    course_change_s: float = 1560.0
    prbs_amplitude_deg: float = 5.0
    prbs_offset_s: float = 0.0  # the PRBS switches this long after a reading
    sea: float = 1.0  # multiple of the force/moment disturbance
    sea_corr: float = 0.0  # correlation of the sea's sway force and yaw moment (waves acting off midship)
    log_x: float = 0.0  # the Doppler log's distance forward of midship [m] (Källström's fore log: 147.6 m)


EXPERIMENT_1 = Experiment()
EXPERIMENT_2 = Experiment(sample_time=15.0, duration_s=1815.0, missing=(600.0, 690.0), course_change_s=900.0)


def _wind(psi: float, speed: float) -> np.ndarray:
    """Prime wind force and moment from starboard (coming from psi0 + 90 deg of the first course): lateral area
    L x 16 m (ballast), C_Y = 0.9 sin(gamma), C_N = 0.1 sin(2 gamma), gamma the wind angle off the bow."""
    gamma = (np.radians(140.0) + np.pi / 2) - psi
    q = 0.5 * RHO_AIR * speed**2 * L * 16.0
    scale = 0.5 * RHO_WATER * L**2 * V**2
    return np.array([q * 0.9 * np.sin(gamma) / scale, q * L * 0.1 * np.sin(2 * gamma) / (scale * L)])


def _rhs(x: np.ndarray, rudder: float, force: np.ndarray) -> np.ndarray:
    """d[v, r, psi]/dt in SI from the prime equations M x' = N x + b delta + force, x' = [v/V, r L/V]."""
    xp = np.array([x[0] / V, x[1] * L / V])
    dxp = np.linalg.solve(M_PRIME, N_PRIME @ xp + B_PRIME * rudder + force)  # per unit prime time
    return np.array([dxp[0] * V * V / L, dxp[1] * V * V / (L * L), x[1]])


def _rk4(x: np.ndarray, rudder: float, w: np.ndarray, wind_speed: float) -> np.ndarray:
    """One classical Runge-Kutta step; rudder and sea force held over the step, the wind follows the heading."""

    def f(xx):
        return _rhs(xx, rudder, _wind(xx[2], wind_speed) + w)

    k1 = f(x)
    k2 = f(x + 0.5 * STEP * k1)
    k3 = f(x + 0.5 * STEP * k2)
    k4 = f(x + STEP * k3)
    return x + STEP / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def simulate(exp: Experiment, seed: int) -> dict[str, np.ndarray]:
    """One run: columns t, delta (recorded), r, psi, v, u as the README's steering record (SI, rad; positive
    delta turns to port as in Källström's report), readings lost and late as the experiment says."""
    rng = np.random.default_rng(seed)
    n = int(round(exp.duration_s / STEP))
    psi_set0 = np.radians(140.0)
    x = np.array([0.0, 0.0, psi_set0])
    rudder = cmd = 0.0
    hold = np.radians(1.0)  # course-keeping angle against the wind, updated by the helmsman
    prbs = 1.0
    override = False
    # the process computer's clock: a few seconds late sometimes
    stamps, t_next = [], 0.0
    while t_next <= exp.duration_s:
        stamps.append(t_next)
        t_next += exp.sample_time + (3.0 if rng.random() < 0.15 else 0.0)
    stamps = np.array(stamps)
    sample_at = set(np.round(stamps / STEP).astype(int).tolist())
    switch_at = set(np.round((stamps + exp.prbs_offset_s) / STEP).astype(int).tolist())
    rows = []
    sea = exp.sea * np.array([4e-5, 4e-6])  # prime force/moment per sqrt(prime time)
    mix = np.linalg.cholesky(np.array([[1.0, exp.sea_corr], [exp.sea_corr, 1.0]]))
    for k in range(n + 1):
        t = k * STEP
        psi_set = psi_set0 - (np.radians(20.0) if t >= exp.course_change_s else 0.0)
        err = x[2] - psi_set
        if k in switch_at:  # the operator's manual changes go through the process computer, on its clock
            if abs(err) > np.radians(6.0):
                override = True
            elif abs(err) < np.radians(2.0):
                override = False
            if rng.random() < 0.5:
                prbs = -prbs
            hold += 0.02 * err
            # override: 10 deg towards the set course (positive rudder turns to port)
            cmd = hold + (np.sign(err) * np.radians(10.0) if override else prbs * np.radians(exp.prbs_amplitude_deg))
        if k in sample_at:
            rows.append((t, rudder, cmd, x.copy()))
        rudder += float(np.clip(cmd - rudder, -RUDDER_RATE * STEP, RUDDER_RATE * STEP))
        w = sea * (mix @ rng.normal(size=2)) / np.sqrt(STEP * V / L)
        x = _rk4(x, rudder, w, exp.wind_speed)
    t = np.array([r[0] for r in rows])
    keep = ~((t > exp.missing[0]) & (t < exp.missing[1]))
    rud = np.array([r[2] if exp.record_command else r[1] for r in rows])
    X = np.array([r[3] for r in rows])
    q_rud, q_psi = np.radians(0.6 if not exp.record_command else 0.1), np.radians(1.0 / 6.0)
    out = {
        "t": t,
        "delta": np.round(rud / q_rud) * q_rud,
        "r": X[:, 1] + np.radians(0.004) + rng.normal(0, np.radians(0.005), len(t)),
        "psi": np.round(X[:, 2] / q_psi) * q_psi,
        "v": X[:, 0] + exp.log_x * X[:, 1] + 0.1 * 0.5144 + rng.normal(0, 0.02 * 0.5144, len(t)),
        "u": np.full(len(t), V),
    }
    return {k: v[keep] for k, v in out.items()}


def write_csv(run: dict[str, np.ndarray], path) -> None:
    """The run as a steering CSV (the README's columns)."""
    cols = list(run)
    lines = [",".join(cols)] + [",".join(f"{run[c][i]:.9g}" for c in cols) for i in range(len(run["t"]))]
    from pathlib import Path

    Path(path).write_text("\n".join(lines) + "\n")
