"""Simulated basin experiment of Linder et al. (2015) section 4-5 with the 1:24 Our Lass II model.

Truth is a surge-decoupled sway-roll-yaw model, linear but for the wall-sided restoring of
:mod:`identify.rollmass.restoring` and the accelerometer's ``g sin phi``, whose roll row is eq. (3) with the load's
added buoyancy at ``Known.zbar_b`` (the waterline, :func:`model.load_restoring`; the paper puts it
at the roll centre, so ``ls``, ``paper-iv`` and ``improved``, which keep (3)-(12), are off by
``m g z_f`` in the restoring here) and whose mass matrix is symmetric (``Y_pdot = K_vdot``), driven by a joystick-like rudder and a wave-like
disturbance acting coherently on sway, roll and yaw (so the regressors of (11) correlate with the
disturbance, the paper's "closed-loop-like" situation). The IMU (6)-(8) adds constant biases and
white noise at 100 Hz; every channel is then FIR-filtered (equiripple, order 20, 0.5 Hz) and
down-sampled to 50 Hz, as in section 5.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from identify.rollmass.model import Load, RollProfile, load_restoring
from identify.rollmass.restoring import heel_gain, heel_signal


@dataclass
class RollRecording:
    """One dataset as the estimator sees it (IMU convention of (6), yaw rate in ship sign)."""

    name: str
    T: float
    delta: np.ndarray  # rad, measured rudder
    p: np.ndarray  # rad/s, roll-rate gyro y1 (6a)
    a_s: np.ndarray  # m/s^2, tangential accelerometer y2 (6b), (7)
    r: np.ndarray  # rad/s, yaw-rate gyro -y3 (6c), ship sign
    load: Load | None = None  # known load (nominal, calibration) or None (loaded, unknown)
    phi: np.ndarray | None = None  # rad, roll angle (column phi); oe's wall-sided restoring input when every run has it
    notes: list[str] = field(default_factory=list)  # what the reader noticed (unknown columns)
    U: float | None = None  # m/s, this run's forward speed (header speed_m_s); None: the profile's
    u: np.ndarray | None = None  # m/s, measured surge speed per sample (column u); None: U held through the run

    @property
    def n(self) -> int:
        return len(self.p)


@dataclass(frozen=True)
class Noise:
    """IMU noise: white-noise densities and constant-bias sigmas. ``scale`` multiplies all of them."""

    gyro_density: float  # rad/s/sqrt(Hz)
    acc_density: float  # m/s^2/sqrt(Hz)
    gyro_bias: float  # rad/s
    acc_bias: float  # m/s^2
    rudder_sd: float  # rad

    @classmethod
    def from_profile(cls, prof: RollProfile, scale: float = 1.0) -> Noise:
        imu = prof.raw["imu"]
        d2r = np.pi / 180
        return cls(
            scale * imu["gyro_density_deg"] * d2r,
            scale * imu["acc_density"],
            scale * imu["gyro_bias_deg"] * d2r,
            scale * imu["acc_bias"],
            scale * imu["rudder_sd_deg"] * d2r,
        )


def state_space(prof: RollProfile, load: Load) -> tuple[np.ndarray, np.ndarray]:
    """``x' = A x + B [delta, tau_v, tau_p, tau_r]`` for ``x = [v, p, r, phi]`` (3) with sway and yaw rows."""
    kn, th, sy = prof.known, prof.truth, prof.raw["sway_yaw"]
    m = load.m
    z_g, z_m = kn.zbar_g + th.z_f, load.zbar + th.z_f
    c = th.K_vdot + kn.M * z_g + m * z_m
    A1 = th.A_x + kn.M * z_g**2 + m * z_m**2  # (4)
    C = th.k + kn.M * kn.g * z_g + load_restoring(kn, load)  # restoring, (3) with (5a), the load's buoyancy at zbar_b
    Mm = np.array(
        [
            [kn.M + m - sy["Y_vdot"], -c, 0.0],
            [-c, A1, 0.0],
            [0.0, 0.0, kn.M * (prof.raw["ship"]["kzz_over_L"] * prof.raw["ship"]["L_pp"]) ** 2 - sy["N_rdot"]],
        ]
    )
    U = kn.U
    # rows: sway, roll, yaw; columns v, p, r, phi
    F = np.array(
        [
            [sy["Y_v"], 0.0, sy["Y_r"] - (kn.M + m) * U, 0.0],
            [0.0, -th.d, (prof.K_ur + kn.M * z_g + m * z_m) * U, -C],
            [sy["N_v"], 0.0, sy["N_r"], 0.0],
        ]
    )
    G = np.array([[sy["Y_delta"], 1, 0, 0], [th.K_delta, 0, 1, 0], [sy["N_delta"], 0, 0, 1]], dtype=float)
    Minv = np.linalg.inv(Mm)
    A = np.vstack([Minv @ F, [0, 1, 0, 0]])
    B = np.vstack([Minv @ G, [0, 0, 0, 0]])
    return A, B


def joystick_rudder(n: int, fs: float, exp: dict, rng: np.random.Generator) -> np.ndarray:
    """Manual joystick steering: random levels held 1-5 s, servo rate limited (rad)."""
    lo, hi = exp["hold_s"]
    dmax = np.deg2rad(exp["rudder_max_deg"])
    target = np.empty(n)
    i = 0
    while i < n:
        hold = int(rng.uniform(lo, hi) * fs)
        level = 0.0 if rng.random() < 0.2 else rng.choice([-1, 1]) * rng.uniform(0.3, 1.0) * dmax
        target[i : i + hold] = level
        i += hold
    rate = np.deg2rad(exp["rudder_rate_deg"]) / fs
    out = np.empty(n)
    cur = 0.0
    for k in range(n):
        cur += np.clip(target[k] - cur, -rate, rate)
        out[k] = cur
    return out


def wave_disturbance(n: int, fs: float, exp: dict, rng: np.random.Generator) -> np.ndarray:
    """Narrow-band 'reflected bow wave' forces [tau_v, tau_p, tau_r], coherent across the DOFs, (n, 3)."""
    from scipy.signal import lfilter  # here: for mass-sim only (its import: 2 s of CPU)

    w0, z = 2 * np.pi * exp["wave_freq_hz"], exp["wave_damping"]
    T = 1 / fs
    # Tustin-discretised 2nd-order band-pass s / (s^2 + 2 z w0 s + w0^2)
    a = np.array([4 + 4 * z * w0 * T + (w0 * T) ** 2, 2 * (w0 * T) ** 2 - 8, 4 - 4 * z * w0 * T + (w0 * T) ** 2])
    b = np.array([2 * T, 0.0, -2 * T])
    common = lfilter(b, a, rng.standard_normal(n + 500))[500:]
    own = lfilter(b, a, rng.standard_normal((n + 500, 3)), axis=0)[500:]
    x = 0.8 * common[:, None] + 0.6 * own  # mostly coherent
    x /= x.std(axis=0)
    return x * np.array([exp["wave_sway_sd"], exp["wave_roll_sd"], exp["wave_yaw_sd"]])


def fir_lowpass(exp: dict) -> np.ndarray:
    """Equiripple FIR of section 5 (order 20, passband 0.5 Hz at 100 Hz)."""
    from scipy.signal import remez  # here: for mass-sim only (its import: 2 s of CPU)

    return remez(exp["fir_order"] + 1, [0, exp["fir_cutoff"], exp["fir_stop"], exp["fs_raw"] / 2], [1, 0], fs=exp["fs_raw"])


def simulate_dataset(
    prof: RollProfile, load: Load, samples: int, noise: Noise, seed: int, name: str = "", known_load: bool = True
) -> RollRecording:
    """One free-running basin run with ``samples`` samples after decimation (seeded, reproducible)."""
    from scipy.signal import lfilter  # here: for mass-sim only (its import: 2 s of CPU)

    exp = prof.raw["experiment"]
    rng = np.random.default_rng(seed)
    fs, dec = exp["fs_raw"], int(exp["decimate"])
    warm = int(5 * fs)
    n = samples * dec + warm
    T = 1 / fs
    A, B = state_space(prof, load)
    Ad = expm(np.block([[A, B], [np.zeros((4, 8))]]) * T)
    Phi, Gam = Ad[:4, :4], Ad[:4, 4:]
    delta = joystick_rudder(n, fs, exp, rng)
    delta[:warm] *= np.linspace(0, 1, warm)
    u = np.column_stack([delta, wave_disturbance(n, fs, exp, rng)])
    x = np.zeros((n, 4))
    kn = prof.known
    kappa = heel_gain(kn)
    for k in range(n - 1):
        # the wall-sided restoring beyond C phi (identify.rollmass.restoring), a roll moment held over the step
        u[k, 2] -= kappa * heel_signal(x[k, 3], kn)
        x[k + 1] = Phi @ x[k] + Gam @ u[k]
    u[-1, 2] -= kappa * heel_signal(x[-1, 3], kn)
    xdot = x @ A.T + u @ B.T
    v_dot, p_dot = xdot[:, 0], xdot[:, 1]
    _, p, r, phi = x.T
    z_s = kn.zbar_s + prof.truth.z_f
    a_s = z_s * p_dot + kn.g * np.sin(phi) - (v_dot + kn.U * r)  # (7)-(8), gravity's component not linearised
    sq = np.sqrt(fs)  # white noise of density q sampled at fs has sigma q sqrt(fs/2)... per channel
    sig_g, sig_a = noise.gyro_density * sq / np.sqrt(2), noise.acc_density * sq / np.sqrt(2)
    meas = np.column_stack(
        [
            p + rng.normal(0, noise.gyro_bias) + sig_g * rng.standard_normal(n),
            a_s + rng.normal(0, noise.acc_bias) + sig_a * rng.standard_normal(n),
            r + rng.normal(0, noise.gyro_bias) + sig_g * rng.standard_normal(n),
            delta + noise.rudder_sd * rng.standard_normal(n),
            phi,
        ]
    )
    filt = lfilter(fir_lowpass(exp), 1.0, meas, axis=0)[warm::dec][:samples]
    return RollRecording(
        name=name,
        T=dec / fs,
        delta=filt[:, 3],
        p=filt[:, 0],
        a_s=filt[:, 1],
        r=filt[:, 2],
        load=load if known_load else None,
        phi=filt[:, 4],
    )


def simulate_case(prof: RollProfile, case: str, noise: Noise, seed: int, length_factor: float = 1.0) -> list[RollRecording]:
    """The three datasets (nominal, calibration, loaded) of one Table 2 case, each with its own seed."""
    specs = {d["name"]: d for d in prof.raw["dataset"]}
    names = prof.raw["cases"][case]
    out = []
    for i, nm in enumerate(names):
        d = specs[nm]
        # dataset names are shared across cases (nominal-1 is the same run): seed by name, not role
        ds_seed = seed * 1000 + sorted(specs).index(nm)
        out.append(
            simulate_dataset(
                prof,
                Load(d["load_kg"], d["load_height"]),
                int(d["samples"] * length_factor),
                noise,
                ds_seed,
                name=nm,
                known_load=(i < 2),
            )
        )
    return out
