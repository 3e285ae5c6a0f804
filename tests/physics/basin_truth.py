"""Independent truth of the basin experiment of Linder et al. (2015), sections 4-5: the 1:24
"Our Lass II" free-running in the MCLab basin, three datasets (nominal, calibration with a known
load, loaded) per Table 2 case, recorded by an Xsens MTi-G and filtered as in section 5.

Written without the project's roll-mass code (``identify.rollmass``): no code is shared. Numbers
shared: the published ones (Table 1, the loads of Table 3, the sample rates and filter of section 5)
and, as nominal values, the hydrodynamic derivatives the paper does not print, which are the roll
profile's own marked choices (Y_vdot, Y_v, Y_r, Y_delta, N_rdot, N_v, N_r, N_delta, K_pdot, K_r, the
IMU position, U): each run draws around them, so a truth ship starts near where the estimator's fit
starts; a family with independently chosen nominal values would be a harder exam. The
dynamics are the 4-DOF (surge optional) rigid-body equations of Fossen (2011, eqs. 7.5-7.10) at
the roll centre, x_G = y_G = 0, with hydrodynamic derivatives; each structural *variant* adds what a
real model ship has and the paper's model (3)-(11) leaves out:

``sway_roll``   sway force from roll rate and roll angle (Y_p, Y_phi), roll moment from sway
                velocity (K_v), yaw moment from roll rate (N_p), unequal couplings Y_pdot != K_vdot.
``restoring``   hydrostatic restoring of the actual displacement of a box-like hull whose KB and BM
                do not follow a wall-sided one (the load's extra buoyancy then acts about 7 mm
                below the waterline, not at it), plus the wall-sided nonlinearity
                GZ = sin(phi) (GM + BM/2 tan^2 phi). Every other variant: a wall-sided hull.
``imu_mount``   the IMU 5-20 cm forward of midship (x_s r' in the accelerometer), misaligned by
                about 1 deg about each axis (yaw rate leaks into the roll gyro, surge
                acceleration into the lateral accelerometer).
``speed_loss``  surge as a state: speed drops in turns (rudder drag, v r), the linear derivatives
                scale with u and the rudder with u^2 (the paper's Fig. 6).
``waves``       a JONSWAP sea (random peak period and heading) with a slow second-order drift,
                instead of the narrow-band reflected-wave model, two to four times stronger.
``combined``    all five at once.

Every variant has the Xsens MTi-G noise (white noise at the data sheet's densities, a constant
bias plus an in-run bias random walk), the sensor's own 2nd-order low-pass, the 100 Hz sampling,
the order-20 equiripple FIR at 0.5 Hz and the decimation to 50 Hz of section 5, and a quantised
rudder encoder, and the surge speed ``u`` from the basin's positioning system (as the paper's Fig. 6
got it: Qualisys positions through a Kalman smoother; 1 % scale and 5 mm/s slow error; not through
the IMU's FIR). The FIR is the paper's post-processing, applied alike to every recorded channel
(``delta``, ``p``, ``a_s``, ``r``, ``phi``), not a sensor's filter: an equiripple design of that order
and transition band (0.5-5 Hz) has a passband ripple of 6.5 %, so its gain is 0.935 at 0 Hz and
0.92-0.93 in the roll band, kept unnormalised on purpose (the paper gives no normalisation; a linear
model sees the gain cancel between input and outputs, a model nonlinear in the recorded ``phi`` does
not). The ``phi`` column is the AHRS's roll angle through that FIR: the true heel plus the IMU's
misalignment about x (``imu_mount``) and an AHRS error at the MTi-G's level (a constant per recording,
a slow drift, white noise; :func:`_ahrs_error`; none with ``quiet``).
Parameters are drawn per run around nominal from the run's seed.

Runs are integrated together (RK4 at 100 Hz, vectorised over runs).

Changed in issue 25 (commit 0468d92): a load's added displacement acts where hydrostatics put it,
at the centroid of the added layer half its sinkage above the waterline, in every variant (a
wall-sided hull: (M + m) GM = M GM + m (T + dT/2 - KG_m)). Before, every variant but ``restoring``
let it act at the roll centre as the paper's (3) does, which no floating hull does (the restoring
of a couple does not depend on the axis the ship rolls about). Figures measured on this module
before that commit were on the older truth and are not comparable with later ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import butter, lfilter, remez

G = 9.81
RHO = 1000.0
FS = 100.0  # Hz, IMU sampling (section 5)
DEC = 2  # to 50 Hz
WARM = int(5 * FS)  # samples at FS of rudder ramped in before the record
VARIANTS = ("sway_roll", "restoring", "imu_mount", "speed_loss", "waves", "combined")
EFFECTS = ("sway_roll", "restoring", "imu_mount", "speed_loss", "waves")
# Table 1 (known to the estimator): displacement, KG, draft, beam, radii of gyration.
M0, KG, DRAFT, BEAM, LPP, LWL = 22.04, 0.146, 0.144, 0.3, 0.8, 0.85
GM0 = 0.018
# Datasets of Table 2 (samples at 50 Hz; the last one's length is not printed) and the loads of Table 3.
DATASETS = {
    "nominal-1": (3277, 0.0, 0.0),
    "0.200kg-2": (1927, 0.2, -0.256),
    "0.200kg-3": (2677, 0.2, -0.256),
    "0.400kg-4": (2400, 0.4, -0.268),
}
CASES = {
    "case1": ("nominal-1", "0.200kg-2", "0.200kg-3"),
    "case2": ("nominal-1", "0.200kg-3", "0.400kg-4"),
    "case3": ("nominal-1", "0.200kg-2", "0.400kg-4"),
}
IMU_Z = -0.09  # nominal IMU mounting height (z down from the waterline) told to the estimator


def _draw(rng: np.random.Generator, n: int, nominal: float, rel: float) -> np.ndarray:
    return nominal * (1 + rel * np.clip(rng.standard_normal(n), -2.5, 2.5))


@dataclass
class Ship:
    """Per-run parameters (arrays over runs). z down, origin at the waterline amidships."""

    z_f: np.ndarray  # offset of the roll centre: z relative to it = zbar + z_f (z_f < 0: it lies below the waterline)
    U0: np.ndarray
    z_imu: np.ndarray  # true IMU z (body frame, z down), also written to the recording
    Ix: np.ndarray
    Iz: np.ndarray
    Yvd: np.ndarray
    Ypd: np.ndarray
    Kvd: np.ndarray
    Kpd: np.ndarray
    Nrd: np.ndarray
    Yv: np.ndarray
    Yr: np.ndarray
    Yp: np.ndarray
    Yphi: np.ndarray
    Kv: np.ndarray
    Kp: np.ndarray
    Kr: np.ndarray
    Nv: np.ndarray
    Nr: np.ndarray
    Np: np.ndarray
    Yd: np.ndarray
    Kd: np.ndarray
    Nd: np.ndarray
    x_imu: np.ndarray
    eps: np.ndarray  # (runs, 3) IMU misalignment about x, y, z [rad]
    Xu: np.ndarray
    Xdd: np.ndarray
    wave_scale: np.ndarray
    Tp: np.ndarray
    beta: np.ndarray


def draw_ships(n: int, variant: str, seed: int) -> Ship:
    """Parameters of ``n`` runs drawn around nominal (10 % on derivatives) from ``seed``."""
    rng = np.random.default_rng(seed)
    on = _effects(variant)
    rel = 0.10
    Ix = M0 * (0.337 * BEAM) ** 2
    Iz = M0 * (0.272 * LPP) ** 2
    # every parameter is drawn in every variant (same stream), then the variant's effects switched on
    d = {
        "z_f": -(0.029 + 0.004 * np.clip(rng.standard_normal(n), -2.5, 2.5)),
        "U0": rng.uniform(0.42, 0.58, n),
        "z_imu": IMU_Z + 0.005 * np.clip(rng.standard_normal(n), -2, 2),
        "Ix": np.full(n, Ix),
        "Iz": np.full(n, Iz),
        "Yvd": _draw(rng, n, -20.0, rel),
        "Kvd": _draw(rng, n, 0.95, rel),
        "Kpd": _draw(rng, n, -0.02, 0.2),
        "Nrd": _draw(rng, n, -0.5, rel),
        "Yv": _draw(rng, n, -15.0, rel),
        "Yr": _draw(rng, n, 2.0, rel),
        "Kp": _draw(rng, n, -0.27, rel),
        "Kr": _draw(rng, n, -1.525, rel),
        "Nv": _draw(rng, n, -1.5, rel),
        "Nr": _draw(rng, n, -2.5, rel),
        "Yd": _draw(rng, n, 2.0, rel),
        "Kd": _draw(rng, n, -0.45, rel),
        "Nd": _draw(rng, n, -0.8, rel),
        "Xu": -_draw(rng, n, 4.5, rel),
        # lateral force centre ~4 cm below the roll centre: Y_p = K_v = -z Y_v (lever of the keel's lift)
        "Yp": _draw(rng, n, 0.6, 0.3),
        "Yphi": _draw(rng, n, -0.5, 0.5),
        "Kv": _draw(rng, n, 0.6, 0.3),
        "Np": _draw(rng, n, 0.05, 0.5),
        "Ypd_ratio": rng.uniform(0.4, 0.7, n),
        "x_imu": rng.uniform(0.05, 0.2, n),
        "eps": np.deg2rad(rng.normal(0, 1.0, (n, 3))),
        "Xdd": -_draw(rng, n, 3.0, 0.2),
        "wave_scale": np.exp(rng.uniform(np.log(2), np.log(4), n)),
        "Tp": rng.uniform(0.6, 1.2, n),
        "beta": rng.uniform(0, 2 * np.pi, n),
    }
    ratio = d.pop("Ypd_ratio")
    d["Ypd"] = d["Kvd"] * (ratio if "sway_roll" in on else 1.0)
    off = {"sway_roll": ("Yp", "Yphi", "Kv", "Np"), "imu_mount": ("x_imu", "eps"), "speed_loss": ("Xdd",)}
    for eff, names in off.items():
        if eff not in on:
            for k in names:
                d[k] = np.zeros_like(d[k])
    return Ship(**d)


def _effects(variant: str) -> tuple[str, ...]:
    if variant not in VARIANTS + ("base",):
        raise ValueError(f"variant must be one of {VARIANTS + ('base',)}")
    return EFFECTS if variant == "combined" else (() if variant == "base" else (variant,))


U_REF = 0.5  # speed at which the drawn derivatives hold; linear terms scale with u, rudder with u^2


def _joystick(n: int, rng: np.random.Generator, runs: int) -> np.ndarray:
    """Joystick steering at 100 Hz: turns of 1-6 s to random sides and depths, straight stretches,
    a servo rate-limited to 50-70 deg/s with a 0.1 s lag. (runs, n) [rad]."""
    out = np.zeros((runs, n))
    for j in range(runs):
        tgt = np.zeros(n)
        i = 0
        while i < n:
            hold = int(rng.uniform(1.0, 6.0) * FS)
            tgt[i : i + hold] = 0.0 if rng.random() < 0.25 else rng.choice([-1, 1]) * np.deg2rad(rng.uniform(8, 28))
            i += hold
        rate = np.deg2rad(rng.uniform(50, 70)) / FS
        cur, lag = 0.0, 0.0
        a = math.exp(-1 / (0.1 * FS))
        for k in range(n):
            cur += min(max(tgt[k] - cur, -rate), rate)
            lag = a * lag + (1 - a) * cur
            out[j, k] = lag
    return out


def _narrowband(n: int, rng: np.random.Generator, runs: int) -> np.ndarray:
    """Base disturbance: reflected bow waves as a damped resonance around 1-1.4 Hz, (runs, n, 3)."""
    out = np.empty((runs, n, 3))
    for j in range(runs):
        f0, zeta = rng.uniform(1.0, 1.4), rng.uniform(0.15, 0.35)
        w0, T = 2 * np.pi * f0, 1 / FS
        r = math.exp(-zeta * w0 * T)
        a = [1.0, -2 * r * math.cos(w0 * T * math.sqrt(1 - zeta**2)), r * r]
        e = rng.standard_normal((n + 400, 4))
        x = lfilter([1.0, -1.0], a, e, axis=0)[400:]
        y = 0.75 * x[:, :1] + 0.65 * x[:, 1:]
        out[j] = y / y.std(axis=0)
    return out * np.array([0.015, 0.002, 0.002])


def _jonswap(n: int, ship: Ship, rng: np.random.Generator) -> np.ndarray:
    """JONSWAP (gamma 3.3) sea at a random heading, 120 components, forces scaled to a roll moment
    2-4x the base disturbance, plus a slow second-order drift in sway and yaw. (runs, n, 3)."""
    runs = len(ship.Tp)
    t = np.arange(n) / FS
    out = np.empty((runs, n, 3))
    for j in range(runs):
        wp = 2 * np.pi / ship.Tp[j]
        w = np.linspace(0.5 * wp, 3.0 * wp, 120)
        sig = np.where(w <= wp, 0.07, 0.09)
        S = w**-5 * np.exp(-1.25 * (wp / w) ** 4) * 3.3 ** np.exp(-((w - wp) ** 2) / (2 * sig**2 * wp**2))
        amp = np.sqrt(2 * S * (w[1] - w[0]))
        ph = rng.uniform(0, 2 * np.pi, len(w))
        b = ship.beta[j]
        k = w**2 / G
        # Froude-Krylov-like: sway and roll follow the wave slope times sin(beta), yaw the slope's
        # gradient along the hull, sin(2 beta); each DOF with its own phase lag
        sway = (amp * k * math.sin(b)) @ np.cos(np.outer(w, t) + ph[:, None])
        roll = (amp * k * math.sin(b) * np.exp(-k * 0.05)) @ np.cos(np.outer(w, t) + ph[:, None] + 0.4)
        yaw = (amp * k * math.sin(2 * b) * np.sinc(k * LPP / (2 * np.pi))) @ np.sin(np.outer(w, t) + ph[:, None])
        f = np.column_stack([sway, roll, yaw])
        f /= np.maximum(f.std(axis=0), 1e-12)
        drift = lfilter([0.002], [1, -0.998], rng.standard_normal((n, 2)), axis=0)
        drift /= np.maximum(drift.std(axis=0), 1e-12)
        s = ship.wave_scale[j]
        out[j] = f * np.array([0.015, 0.002, 0.002]) * s
        out[j, :, 0] += 0.3 * 0.015 * s * drift[:, 0] * abs(math.sin(b))
        out[j, :, 2] += 0.3 * 0.002 * s * drift[:, 1] * abs(math.sin(2 * b))
    return out


def _restoring(ship: Ship, m: float, zm: float, on: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Roll restoring coefficient C [N m/rad] and the wall-sided cubic factor of the loaded ship.

    Without the ``restoring`` effect: a wall-sided hull, the load's weight at its height and the
    displacement it adds at the centroid of the added layer, half its sinkage above the waterline
    ((M + m) GM = M GM + m (T + dT/2 - KG_m); Biran 2003, Ship Hydrostatics, ch. 6). (The paper's
    (3) lets that buoyancy act at the roll centre, m g (z_m + z_f): no hull floats that way; it
    changes the load's restoring by m g z_f, 11 % of it for the 0.4 kg load.)
    With it: (M + m) g GM of the actual draft of a box-like hull whose KB and BM do not follow a
    wall-sided one (the load's buoyancy acts 6-7 mm lower), plus the wall-sided cubic."""
    C_base = M0 * G * GM0  # nominal hydrostatic restoring
    if "restoring" not in on:
        sink = m / (RHO * 0.9 * LWL * BEAM)
        return np.full_like(ship.z_f, C_base + m * G * (zm + 0.5 * sink)), np.zeros_like(ship.z_f)
    # box-like hull fitted to Table 1 (KM = KB + BM = 0.164 m at the nominal draft)
    awp = 0.9 * LWL * BEAM
    T = DRAFT + m / (RHO * awp)
    BM = (0.092 * DRAFT) / T
    KM = 0.5 * T + BM
    KG_t = (M0 * KG + m * (DRAFT - zm)) / (M0 + m)  # keel-referenced CoG of ship plus load
    GM = KM - KG_t
    return (M0 + m) * G * GM, BM / (2 * np.maximum(GM, 1e-3))


def simulate(
    ship: Ship, variant: str, load: tuple[float, float], n_out: int, seed: int, quiet: bool = False
) -> dict[str, np.ndarray]:
    """Integrate one dataset for every run of ``ship``; returns measured channels (runs, n_out)
    at 50 Hz: ``delta, p, a_s, r, phi``, the measured surge speed ``u`` (the recorder's signs: roll
    starboard down, yaw to starboard positive, a_s as (7)) and the mean surge speed ``speed``. ``quiet``: no IMU noise or
    bias (the filters stay), for comparing structures."""
    return simulate_parts(ship, variant, load, n_out, seed, sea=not quiet, sensor=not quiet)


def simulate_parts(
    ship: Ship, variant: str, load: tuple[float, float], n_out: int, seed: int, sea: bool, sensor: bool
) -> dict[str, np.ndarray]:
    """:func:`simulate`'s dataset with the disturbance (``sea``: waves or the narrow-band moment) and the IMU's noise
    and bias (``sensor``) each kept or left out, from the same random stream (every draw is made either way, so the
    parts kept are those of the whole dataset: benchmarks/rollmass_oracle.py splits a recording's error with it)."""
    rng = np.random.default_rng(seed)
    R = len(ship.U0)
    n = n_out * DEC + WARM + 40
    delta = rudder_input(rng, R, n, WARM)
    tau = _jonswap(n, ship, rng) if "waves" in _effects(variant) else _narrowband(n, rng, R)
    if not sea:
        tau *= 0.0
    states = integrate(ship, variant, load, delta, tau)
    return _measure(ship, rng, delta, *states, WARM, n_out, 1.0 if sensor else 0.0, seed)


def rudder_input(rng: np.random.Generator, R: int, n: int, warm: int) -> np.ndarray:
    """The true rudder angle (runs, n) at 100 Hz: the joystick, ramped in over the warm-up."""
    delta = _joystick(n, rng, R)
    delta[:, :warm] *= np.linspace(0, 1, warm)
    return delta


def rhs(ship: Ship, variant: str, load: tuple):
    """The right-hand side f(x, delta, tau) of the rigid-body equations (Fossen 2011, eqs. 7.5-7.10
    at the roll centre) with the load ``(m, z_m)`` aboard; ``m`` and ``z_m`` may be arrays over runs.
    The state x is (v, p, r, phi, u) by runs."""
    on = _effects(variant)
    m, zm = load
    zbar_g = -(KG - DRAFT)
    z_g, z_m = zbar_g + ship.z_f, zm + ship.z_f
    mzg = M0 * z_g + m * z_m
    mt = M0 + m
    Ix = ship.Ix + M0 * z_g**2 + m * z_m**2
    C, cubic = _restoring(ship, m, zm, on)
    # sway-roll mass matrix [[m11, m12], [m21, m22]] (Fossen 7.5-7.10 at the roll centre)
    m11, m12 = mt - ship.Yvd, -(mzg + ship.Ypd)
    m21, m22 = -(mzg + ship.Kvd), Ix - ship.Kpd
    det = m11 * m22 - m12 * m21
    m33 = ship.Iz - ship.Nrd
    m_u = mt + 0.05 * M0
    speed_on = "speed_loss" in on

    def f(x: np.ndarray, d: np.ndarray, tk: np.ndarray) -> np.ndarray:
        v, p, r, phi, u = x
        s = u / U_REF if speed_on else ship.U0 / U_REF
        uu = u if speed_on else ship.U0
        ds = d * s * s
        restore = C * phi * (1 + cubic * phi * phi)
        Y = ship.Yv * s * v + ship.Yp * s * p + ship.Yphi * phi + (ship.Yr * s - mt * uu) * r + ship.Yd * ds + tk[:, 0]
        K = ship.Kv * s * v + ship.Kp * p + (ship.Kr * s + mzg * uu) * r - restore + ship.Kd * ds + tk[:, 1]
        N = ship.Nv * s * v + ship.Np * p + ship.Nr * s * r + ship.Nd * ds + tk[:, 2]
        vd = (m22 * Y - m12 * K) / det
        pd = (m11 * K - m21 * Y) / det
        rd = N / m33
        ud = (ship.Xu * (u - ship.U0) + (mt - 0.3 * ship.Yvd) * v * r + ship.Xdd * d * d) / m_u if speed_on else 0 * u
        return np.array([vd, pd, rd, p, ud])

    return f


def integrate(ship: Ship, variant: str, load: tuple, delta: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, ...]:
    """RK4 at 100 Hz from rest (u = U0) of :func:`rhs` driven by ``delta`` (runs, n) and the
    disturbance ``tau`` (runs, n, 3); returns v, p, r, phi, u and v', p', r', u' (runs, n)."""
    f = rhs(ship, variant, load)
    R, n = delta.shape
    x = np.zeros((5, R))
    x[4] = ship.U0
    X = np.empty((n, 5, R))
    XD = np.empty((n, 5, R))
    h = 1 / FS
    for k in range(n):
        d0, d1 = delta[:, k], delta[:, min(k + 1, n - 1)]
        dm = 0.5 * (d0 + d1)
        t0, t1 = tau[:, k], tau[:, min(k + 1, n - 1)]
        tm = 0.5 * (t0 + t1)
        k1 = f(x, d0, t0)
        X[k], XD[k] = x, k1
        k2 = f(x + 0.5 * h * k1, dm, tm)
        k3 = f(x + 0.5 * h * k2, dm, tm)
        k4 = f(x + h * k3, d1, t1)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    v, p, r, phi, u = (X[:, i, :].T for i in range(5))
    vd, pd, rd, _, ud = (XD[:, i, :].T for i in range(5))
    return v, p, r, phi, u, vd, pd, rd, ud


# The AHRS's roll error (Xsens MTi-G data sheet: static roll accuracy 0.5 deg, dynamic 1 deg RMS):
# per recording a constant (its attitude filter's gravity reference, sd 0.4 deg) and a slow drift
# (first-order Gauss-Markov, sd 0.25 deg, 20 s correlation time: the filter's slow gravity correction
# in a basin without GNSS aiding), plus its output noise (0.02 deg white). Drawn from a stream of its
# own, so every other channel stays the same as before the AHRS error was added.
AHRS_BIAS_SD = np.deg2rad(0.4)
AHRS_DRIFT_SD, AHRS_DRIFT_TAU = np.deg2rad(0.25), 20.0
AHRS_NOISE_SD = np.deg2rad(0.02)


def _ahrs_error(R: int, n: int, seed: int) -> np.ndarray:
    """The AHRS roll angle's error (runs, n) at 100 Hz [rad], from ``seed`` (the recording's own)."""
    rng = np.random.default_rng([seed, 0xA425])
    a = math.exp(-1 / (AHRS_DRIFT_TAU * FS))
    e = rng.standard_normal((R, n))
    e[:, 0] /= math.sqrt(1 - a * a)  # stationary from the first sample
    drift = lfilter([AHRS_DRIFT_SD * math.sqrt(1 - a * a)], [1, -a], e, axis=1)
    return rng.normal(0, AHRS_BIAS_SD, (R, 1)) + drift + AHRS_NOISE_SD * rng.standard_normal((R, n))


def _measure(
    ship: Ship,
    rng: np.random.Generator,
    delta,
    v,
    p,
    r,
    phi,
    u,
    vd,
    pd,
    rd,
    ud,
    warm: int,
    n_out: int,
    noise: float,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """The Xsens MTi-G at the IMU's true position and orientation, its noise and filters, the FIR
    of section 5 and the decimation. Its roll angle ``phi`` is the AHRS's: the true heel, the IMU's
    misalignment about x (a roll angle of the sensor's frame, not the hull's) and the AHRS error of
    :func:`_ahrs_error` (drawn from ``seed``)."""
    R = len(ship.U0)
    zs = (ship.z_imu + ship.z_f)[:, None]
    xs = ship.x_imu[:, None]
    # specific force along the body y axis at the IMU (rigid-body kinematics, theta = 0):
    # f_y = v' + u r + x_s r' - z_s p' - g sin(phi); the recorder's a_s is -f_y, as (7)
    fy = vd + u * r + xs * rd - zs * pd - G * np.sin(phi)
    fx = ud - v * r - xs * r * r
    fz = -G * np.cos(phi)
    ex, ey, ez = (ship.eps[:, i][:, None] for i in range(3))
    fy_s = fy - (ez * fx - ex * fz)
    p_s = p - ey * r
    r_s = r + ey * p
    n = p.shape[1]
    d2r = np.pi / 180
    # MTi-G data sheet: gyro 0.05 deg/s/sqrt(Hz), accelerometer 0.002 m/s^2/sqrt(Hz) (x sqrt(FS/2));
    # bias 1 deg/s and 0.02 m/s^2 per run, in-run random walk
    sg, sa = noise * 0.05 * d2r * math.sqrt(FS / 2), noise * 0.002 * math.sqrt(FS / 2)

    def walk(scale: float) -> np.ndarray:
        return noise * scale * np.cumsum(rng.standard_normal((R, n)), axis=1) / math.sqrt(n)

    gyro_p = p_s + noise * rng.normal(0, 1.0 * d2r, (R, 1)) + walk(0.1 * d2r) + sg * rng.standard_normal((R, n))
    gyro_r = r_s + noise * rng.normal(0, 1.0 * d2r, (R, 1)) + walk(0.1 * d2r) + sg * rng.standard_normal((R, n))
    acc = -fy_s + noise * rng.normal(0, 0.02, (R, 1)) + walk(0.002) + sa * rng.standard_normal((R, n))
    # sensor's own low-pass (2nd order Butterworth, 30 Hz) before its 100 Hz output
    b, a = butter(2, 30.0, fs=FS)
    gyro_p, gyro_r, acc = (lfilter(b, a, s, axis=1) for s in (gyro_p, gyro_r, acc))
    enc = np.round((delta + rng.normal(0, 0.05 * d2r, (R, 1))) / (0.1 * d2r)) * (0.1 * d2r) if noise else delta
    # surge speed as the basin's positioning gives it (Qualisys positions through a Kalman smoother, the
    # paper's Fig. 6): a per-run scale error (1 %) and a slowly varying error (5 mm/s, ~1 s correlation)
    ar1 = math.exp(-1 / FS)
    slow = lfilter([math.sqrt(1 - ar1 * ar1)], [1, -ar1], rng.standard_normal((R, n)), axis=1)
    u_meas = u * (1 + noise * rng.normal(0, 0.01, (R, 1))) + noise * 0.005 * slow
    fir = remez(21, [0, 0.5, 5.0, FS / 2], [1, 0], fs=FS)
    phi_ahrs = phi + ship.eps[:, :1] + noise * _ahrs_error(R, n, seed)
    out = {}
    for name, s in (("delta", enc), ("p", gyro_p), ("a_s", acc), ("r", gyro_r), ("phi", phi_ahrs)):
        out[name] = lfilter(fir, 1.0, s, axis=1)[:, warm::DEC][:, :n_out]
    # the speed comes from the positioning's own smoother, not through the IMU's FIR (whose DC gain,
    # 0.935, cancels between the IMU channels and the rudder but would scale a speed)
    out["u"] = u_meas[:, warm::DEC][:, :n_out]
    out["speed"] = u[:, warm:].mean(axis=1)
    return out


@dataclass
class Recording:
    """One dataset of one run, ready to write."""

    role: str
    name: str
    T: float
    cols: dict[str, np.ndarray]
    meta: dict[str, str]


def simulate_runs(
    variant: str, runs: int, seed: int, length: float = 1.0, quiet: bool = False
) -> tuple[Ship, dict[str, dict[str, np.ndarray]]]:
    """The four datasets of Table 2 for ``runs`` runs of one variant (each run its own ship);
    ``quiet``: no waves and no sensor noise (the structure alone, see :func:`simulate`)."""
    ship = draw_ships(runs, variant, seed)
    data = {}
    for i, (name, (samples, m, zm)) in enumerate(DATASETS.items()):
        data[name] = simulate(ship, variant, (m, zm), int(samples * length), dataset_seed(seed, i), quiet)
    return ship, data


def variant_seed(seed: int, variant: str) -> int:
    """The seed a family's ``variant`` (one of :data:`VARIANTS` or "base") is drawn with from the family's ``seed``: each
    variant its own ships and noise (bench_rollmass_truth's jobs and every bench and test that redraws its recordings)."""
    return seed + 1000 * (VARIANTS + ("base",)).index(variant)


def dataset_seed(seed: int, i: int) -> int:
    """The noise seed of the ``i``-th dataset (:data:`DATASETS` order) of a family drawn with ``seed``."""
    return seed * 7919 + 101 * i + 1


def case_recordings(ship: Ship, data: dict, case: str, run: int) -> list[Recording]:
    """The three recordings of one Table 2 case of one run, with the metadata a recorder writes:
    role, dataset, mean speed, IMU position, and the load where it is known."""
    out = []
    for role, name in zip(("nominal", "calibration", "loaded"), CASES[case]):
        d = data[name]
        _, m, zm = DATASETS[name]
        meta = {
            "ship": "our_lass_ii",
            "role": role,
            "dataset": name,
            "speed_m_s": f"{d['speed'][run]:.4f}",
            "imu_z_m": f"{ship.z_imu[run]:.4f}",
            "imu_x_m": f"{ship.x_imu[run]:.4f}",
            "sample_time": f"{DEC / FS:g}",
        }
        if role != "loaded":
            meta.update({"load_kg": f"{m:g}", "load_z_m": f"{zm:g}"})
        out.append(Recording(role, name, DEC / FS, {k: d[k][run] for k in ("delta", "p", "a_s", "r", "phi", "u")}, meta))
    return out


def write_csv(rec: Recording, path: str | Path, with_u: bool = True) -> Path:
    """Write in the format ``shiptrial mass`` reads: ``# key: value`` lines, then t, delta, p, a_s, r,
    phi and, unless ``with_u`` is false (a log without the positioning system), the surge speed u."""
    path = Path(path)
    n = len(rec.cols["p"])
    cols = ["t", "delta", "p", "a_s", "r", "phi"] + (["u"] if with_u else [])
    arr = np.column_stack([np.arange(n) * rec.T] + [rec.cols[c] for c in cols[1:]])
    head = "".join(f"# {k}: {v}\n" for k, v in rec.meta.items()) + ",".join(cols) + "\n"
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w") as fh:
        fh.write(head)
        np.savetxt(fh, arr, delimiter=",", fmt="%.9g")
    tmp.replace(path)
    return path


def truth_load(case: str) -> tuple[float, float]:
    """The loaded dataset's true load (kg, z m) of a Table 2 case."""
    _, m, zm = DATASETS[CASES[case][2]]
    return m, zm
