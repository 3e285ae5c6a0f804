"""Test-side physics: a truth family for change detection on the podded naval vessel.

An independent simulator of the 51.5 m multipurpose naval vessel with two azimuthing pods
(Blanke and Christensen 1993; the hull coefficients of Perez 2006 as tabulated in Appendix A of
the change-detection thesis this project follows), written without the product's code: it
imports nothing from ``primitives`` or ``diagnose``. The detector's yaw row (2.17) and the
product's kernel leave out what a real ship has; this simulator puts it in:

- roll-yaw and roll-sway coupling beyond the tabulated terms: yaw and sway moments from the roll
  rate (``N_p``, ``Y_p``), which the yaw row (2.17) lacks (it has no ``p``);
- nonlinear roll restoring ``rho g Delta GZ(phi)``, ``GZ = GM sin phi + gz3 phi^3 + gz5 phi^5``
  (hardening of a wall-sided hull, softening at deck-edge immersion), not ``GM phi + K_phiphiphi phi^3``;
- a different pod force model: propeller thrust ``rho n^2 D^4 K_T(J)`` with a quadratic
  ``K_T`` at the advance ratio of the wake-reduced inflow along the pod axis (MMG style,
  Yasukawa and Yoshimura 2015 eq. 13-16), and a lift on the pod body at its drift angle in the
  partly slipstream-accelerated flow, instead of (2.9)-(2.11);
- pod-hull interaction: wake fraction ``w``, thrust deduction ``t_d``, the hull's share of the
  side force ``a_H`` acting at ``x_H`` (MMG eq. 26-27), the ``-y_pod F_x`` yaw moment of
  unequal thrusts, and (variant ``pod-interaction``) the shadowing of one pod by the other;
- steering-gear dynamics: the azimuth follows its command through a first-order lag with a
  rate limit; the propeller speed follows its command with a lag;
- sensors: a causal first-order low-pass per sensor, after the noise; white Gaussian noise of
  Table 4.1's levels, or (variant ``coloured-noise``) AR(1)-coloured and Student-t (3 degrees of
  freedom) noise of the same standard deviations and a drifting gyro bias.

What a recording carries as the measured pod yaw moment ``tau_n`` is what the pods' load cells
give: ``sum x_pod F_y,pod`` of the pod units' own forces, without the hull's interaction share
(``a_H``) or the ``-y_pod F_x`` term; in variant ``steering-lag`` the drive reports the moment of
its azimuth *setpoint* (and the logger records the setpoint as ``alpha``), while the gear lags.

Variants (``VARIANTS``) are structural; every ship drawn from a variant (``draw_ship``) has its
parameters scattered around the variant's nominal values by its own seed. A changed ship has
``I_z`` larger by a factor (10 % in the thesis, L1591) from a given time on.

Units SI, angles in radians, body axes x forward, y starboard, z down; positive pod angle
points the thrust to starboard (the ship turns to port).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

RHO, G = 1025.0, 9.82
VARIANTS = ("nominal-mmg", "strong-roll", "steering-lag", "coloured-noise", "pod-interaction")
#: Table 4.1 noise standard deviations (measured yaw moment as tau_n)
TABLE_4_1 = {"r": 0.0025, "v_dot": 0.015, "u": 0.15, "v": 0.15, "phi": 0.025, "tau_n": 5e4}
SUBSTEPS = 1  # RK4 steps per sample (roll period ~8 s, gear lag >= 0.6 s: 0.1 s steps resolve both)


@dataclass(frozen=True)
class Ship:
    """All parameters of one simulated ship (SI)."""

    m: float = 359e3
    disp: float = 350.0
    I_x: float = 3.4e6
    I_z: float = 33.7e6
    x_g: float = -3.38
    z_g: float = -1.75
    GM: float = 0.776
    gz3: float = 0.25  # m/rad^3
    gz5: float = -0.9  # m/rad^5
    # added mass (Appendix A)
    X_ud: float = -17400.0
    Y_vd: float = -0.393e6
    Y_pd: float = -0.296e6
    Y_rd: float = -1.4e6
    K_vd: float = 0.296e6
    K_pd: float = -0.774e6
    N_vd: float = 0.538e6
    N_rd: float = -28.7e6
    # damping (Appendix A), scaled per ship by ``hull``
    X_uu: float = -1960.0
    Y_uv: float = -11800.0
    Y_ur: float = 0.131e6
    Y_vv: float = -3700.0
    Y_vr: float = -0.794e6
    Y_rv: float = -0.182e6
    Y_fuv: float = 10800.0
    Y_fur: float = 0.251e6
    Y_fuu: float = -74.0
    K_uv: float = 9260.0
    K_ur: float = -0.102e6
    K_vv: float = 29300.0
    K_vr: float = 0.621e6
    K_rv: float = 0.142e6
    K_fuv: float = -8400.0
    K_fur: float = -0.196e6
    K_fuu: float = -1180.0
    K_pp: float = -0.416e6
    K_p: float = -0.5e6
    K_up: float = -15500.0
    N_uv: float = -92000.0
    N_ur: float = -4.71e6
    N_rr: float = -202e6
    N_rv: float = -15.6e6
    N_fuv: float = -0.214e6
    N_fur: float = -4.98e6
    N_fuu: float = -8000.0
    # couplings the yaw row (2.17) does not have
    N_p: float = -2.0e6  # yaw moment per roll rate, N m s
    Y_p: float = -0.15e6  # sway force per roll rate, N s
    # pods (two, identical)
    x_pod: float = -23.5
    y_pod: float = 1.0
    z_pod: float = 1.2
    D: float = 0.42
    kt0: float = 0.50
    kt1: float = -0.36
    kt2: float = -0.12
    A_pod: float = 2.5
    c_lift: float = 1.8  # lift slope of the pod body, per radian
    c_drag: float = 0.06
    slip_share: float = 0.5  # share of the pod body in the propeller slipstream
    w: float = 0.15  # wake fraction
    t_d: float = 0.12  # thrust deduction
    a_H: float = 0.2  # hull share of the pod side force
    x_H: float = -21.0  # where the hull's share acts
    shadow: float = 0.0  # thrust loss of the pod in the other's wake, times sin^2 of the pod angle
    # steering gear and propeller
    gear_tau: float = 0.6  # s
    gear_rate: float = math.radians(10.0)  # rad/s
    n_tau: float = 1.5  # s
    tau_from_setpoint: bool = False
    # sensors: first-order low-pass time constants (s) and noise
    lp: tuple = (("r", 0.3), ("phi", 0.2), ("p", 0.2), ("u", 0.5), ("v", 0.5), ("v_dot", 0.3), ("tau_n", 0.5))
    coloured: bool = False
    roll_weave: float = 0.0  # amplitude of an azimuth weave near the roll period (rad)


_NOMINAL = {
    "nominal-mmg": {},
    "strong-roll": {"GM": 0.65, "K_p": -0.35e6, "K_pp": -0.3e6, "N_p": -4.0e6, "Y_p": -0.3e6, "roll_weave": math.radians(3.0)},
    "steering-lag": {"gear_tau": 2.0, "gear_rate": math.radians(3.5), "n_tau": 3.0, "tau_from_setpoint": True},
    "coloured-noise": {"coloured": True},
    "pod-interaction": {"w": 0.3, "t_d": 0.25, "a_H": 0.45, "shadow": 0.35, "kt1": -0.45},
}
# parameters scattered per ship (relative sd), the rest kept at the variant's value
_SCATTER = {"hull": 0.10, "mass": 0.03, "pod": 0.06, "interaction": 0.20}
_HULL = tuple(f.name for f in fields(Ship) if f.name[:2] in ("X_", "Y_", "K_", "N_") and not f.name.endswith("d"))
_MASS = ("m", "I_x", "I_z", "GM")
_POD = ("kt0", "kt1", "kt2", "c_lift", "c_drag")
_INTERACTION = ("w", "t_d", "a_H", "N_p", "Y_p")


def nominal_ship(variant: str) -> Ship:
    if variant not in _NOMINAL:
        raise ValueError(f"unknown variant {variant!r}; one of {VARIANTS}")
    return replace(Ship(), **_NOMINAL[variant])


def draw_ship(variant: str, seed: int) -> Ship:
    """A ship of ``variant`` with its parameters scattered around the variant's nominal values."""
    ship = nominal_ship(variant)
    rng = np.random.default_rng([seed, 7])
    change = {}
    for group, names in (("hull", _HULL), ("mass", _MASS), ("pod", _POD), ("interaction", _INTERACTION)):
        for k in names:
            change[k] = getattr(ship, k) * float(np.clip(1 + _SCATTER[group] * rng.standard_normal(), 0.5, 1.5))
    return replace(ship, **change)


def harbour_commands(n: int, dt: float, seed: int, weave: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Propeller speed (rev/s) and azimuth (rad) setpoints of harbour-like manoeuvring: azimuth
    steps of random size (|a| <= 20 deg) and random hold (10-25 s), eased over 2 s; propeller
    speed 55-70 rev/s drifting slowly; ``weave`` adds an azimuth oscillation near the roll period."""
    rng = np.random.default_rng([seed, 11])
    t = np.arange(n) * dt
    a = np.zeros(n)
    i = 0
    while i < n:
        hold = int(rng.uniform(10.0, 25.0) / dt)
        a[i : i + hold] = rng.uniform(-1, 1) * math.radians(20.0)
        i += hold
    k = dt / 2.0
    eased = np.empty(n)
    acc = a[0]
    for j in range(n):
        acc += k * (a[j] - acc)
        eased[j] = acc
    eased += weave * np.sin(2 * np.pi * t / rng.uniform(7.0, 9.0))
    n_cmd = 62.0 + 6.0 * np.sin(2 * np.pi * t / rng.uniform(300.0, 500.0) + rng.uniform(0, 2 * np.pi))
    return n_cmd, eased


def _mass_inverse(s: Ship, i_z: float) -> np.ndarray:
    mz = s.m * s.z_g
    M = np.array(
        [
            [s.m - s.X_ud, 0, 0, 0],
            [0, s.m - s.Y_vd, -(mz + s.Y_pd), s.m * s.x_g - s.Y_rd],
            [0, -(mz + s.K_vd), s.I_x - s.K_pd, 0],
            [0, s.m * s.x_g - s.N_vd, 0, i_z - s.N_rd],
        ]
    )
    return np.linalg.inv(M)


def pod_forces(s: Ship, u, v, p, r, a, n, y_pod: float, other_side: float):
    """Forces of one pod unit (body frame) and its propeller thrust: ``(F_x, F_y, T)``.

    Inflow at the pod (its velocity through the water, pod frame): ``u_a`` along its axis,
    ``v_t`` across. Thrust ``T = rho n^2 D^4 K_T(J)``, ``J = (1 - w) u_a / (n D)`` (MMG eq. 13-16);
    pod body lift ``-1/2 rho A U_e^2 c_L sin(beta) |cos(beta)|`` against the drift angle ``beta``,
    ``U_e^2 = U^2 + share * 8 T / (rho pi D^2)`` (actuator-disc slipstream); drag along the
    flow. ``other_side`` (+1 / -1) is the side the other pod sits on: the pod pointing toward it
    works in its wake (``shadow``)."""
    up = u - y_pod * r
    vp = v + s.x_pod * r - s.z_pod * p
    ca, sa = np.cos(a), np.sin(a)
    ua = up * ca + vp * sa
    vt = -up * sa + vp * ca
    nd = np.maximum(n * s.D, 1e-3)
    J = (1 - s.w) * ua / nd
    kt = s.kt0 + s.kt1 * J + s.kt2 * J * J
    loss = 1.0 - s.shadow * np.where(np.sign(a) == other_side, sa * sa, 0.0)
    T = RHO * n * n * s.D**4 * kt * loss
    U2 = ua * ua + vt * vt
    beta = np.arctan2(vt, np.maximum(np.abs(ua), 1e-6))
    Ue2 = U2 + s.slip_share * 8 * np.maximum(T, 0.0) / (RHO * np.pi * s.D**2)
    lift = -0.5 * RHO * s.A_pod * Ue2 * s.c_lift * np.sin(beta) * np.abs(np.cos(beta))
    Un = np.sqrt(U2)
    fx = T - 0.5 * RHO * s.A_pod * s.c_drag * Un * ua
    fy = lift - 0.5 * RHO * s.A_pod * s.c_drag * Un * vt
    return fx * ca - fy * sa, fx * sa + fy * ca, T


def _derivatives(s: Ship, Minv: np.ndarray, x: np.ndarray, n_cmd, a_cmd):
    """Time derivative of the state ``x`` (runs, 10) = u, v, p, r, phi, psi, X, Y, a1, a2 (n as
    an 11th column), under setpoints ``n_cmd``, ``a_cmd`` (runs,); ``Minv`` (runs, 4, 4)."""
    u, v, p, r, phi, psi, _, _, a1, a2, n = x.T
    au, av, ar_, ap = np.abs(u), np.abs(v), np.abs(r), np.abs(p)
    X = s.X_uu * u * au + s.m * (v * r + s.x_g * r * r - s.z_g * p * r)
    Y = (
        s.Y_uv * au * v
        + s.Y_ur * u * r
        + s.Y_vv * v * av
        + s.Y_vr * v * ar_
        + s.Y_rv * r * av
        + s.Y_fuv * phi * np.abs(u * v)
        + s.Y_fur * phi * np.abs(u * r)
        + s.Y_fuu * phi * u * u
        + s.Y_p * p
        - s.m * u * r
    )
    gz = s.GM * np.sin(phi) + s.gz3 * phi**3 + s.gz5 * phi**5
    K = (
        s.K_uv * au * v
        + s.K_ur * u * r
        + s.K_vv * v * av
        + s.K_vr * v * ar_
        + s.K_rv * r * av
        + s.K_fuv * phi * np.abs(u * v)
        + s.K_fur * phi * np.abs(u * r)
        + s.K_fuu * phi * u * u
        + s.K_pp * p * ap
        + s.K_p * p
        + s.K_up * au * p
        - RHO * G * s.disp * gz
        + s.m * s.z_g * u * r
    )
    N = (
        s.N_uv * au * v
        + s.N_ur * au * r
        + s.N_rr * r * ar_
        + s.N_rv * r * av
        + s.N_fuv * phi * np.abs(u * v)
        + s.N_fur * phi * u * ar_
        + s.N_fuu * phi * u * au
        + s.N_p * p
        - s.m * s.x_g * u * r
    )
    for a, yp, other in ((a1, -s.y_pod, 1.0), (a2, s.y_pod, -1.0)):
        fx, fy, T = pod_forces(s, u, v, p, r, a, n, yp, other)
        X = X + fx - s.t_d * T * np.cos(a)
        Y = Y + (1 + s.a_H) * fy
        K = K - s.z_pod * fy
        N = N + (s.x_pod + s.a_H * s.x_H) * fy - yp * fx
    acc = np.einsum("rij,rj->ri", Minv, np.stack([X, Y, K, N], axis=1))
    cpsi, spsi, cphi = np.cos(psi), np.sin(psi), np.cos(phi)

    def gear(a):
        return np.clip((a_cmd - a) / s.gear_tau, -s.gear_rate, s.gear_rate)

    return np.column_stack(
        [acc, p, r * cphi, u * cpsi - v * cphi * spsi, u * spsi + v * cphi * cpsi, gear(a1), gear(a2), (n_cmd - n) / s.n_tau]
    )


def measured_moment(s: Ship, u, v, p, r, a1, a2, n) -> np.ndarray:
    """The pods' load-cell yaw moment ``sum x_pod F_y`` (no hull share, no ``-y_pod F_x``)."""
    return sum(s.x_pod * pod_forces(s, u, v, p, r, a, n, yp, o)[1] for a, yp, o in ((a1, -s.y_pod, 1.0), (a2, s.y_pod, -1.0)))


def simulate(
    ship: Ship,
    n_cmd: np.ndarray,
    a_cmd: np.ndarray,
    dt: float,
    change_at_s: np.ndarray | None = None,
    iz_factor: float = 1.1,
    lead_in_s: float = 150.0,
) -> dict[str, np.ndarray]:
    """Noise-free signals (n, runs) for setpoints ``n_cmd``, ``a_cmd`` (n, runs); ``change_at_s``
    (runs,) the time from which each run's ``I_z`` is ``iz_factor`` times larger (NaN: never).
    A straight lead-in at the first setpoints brings the ship to speed first (dropped)."""
    n, runs = a_cmd.shape
    h = dt / SUBSTEPS
    change = np.full(runs, np.nan) if change_at_s is None else np.asarray(change_at_s, float)
    M0, M1 = _mass_inverse(ship, ship.I_z), _mass_inverse(ship, iz_factor * ship.I_z)
    x = np.zeros((runs, 11))
    x[:, 0] = 5.0
    x[:, 10] = n_cmd[0]
    lead = int(round(lead_in_s / dt))
    out = np.empty((n, runs, 11))
    deriv = np.empty((n, runs, 11))
    for k in range(-lead, n):
        nc, ac = (n_cmd[0], np.zeros(runs)) if k < 0 else (n_cmd[k], a_cmd[k])
        t = max(k, 0) * dt
        Minv = np.where((t >= change)[:, None, None], M1[None], M0[None])
        if k >= 0:
            out[k] = x
            deriv[k] = _derivatives(ship, Minv, x, nc, ac)
        for _ in range(SUBSTEPS):
            k1 = _derivatives(ship, Minv, x, nc, ac)
            k2 = _derivatives(ship, Minv, x + 0.5 * h * k1, nc, ac)
            k3 = _derivatives(ship, Minv, x + 0.5 * h * k2, nc, ac)
            k4 = _derivatives(ship, Minv, x + h * k3, nc, ac)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(x)):
            raise FloatingPointError("the truth simulation diverged")
    u, v, p, r, phi, psi, X, Y, a1, a2, nn = np.moveaxis(out, 2, 0)
    if ship.tau_from_setpoint:
        tau = measured_moment(ship, u, v, p, r, a_cmd, a_cmd, nn)
        alpha = a_cmd
    else:
        tau = measured_moment(ship, u, v, p, r, a1, a2, nn)
        alpha = a1
    return {
        "u": u,
        "v": v,
        "p": p,
        "r": r,
        "phi": phi,
        "psi": psi,
        "x": X - X[0],
        "y": Y - Y[0],
        "v_dot": deriv[:, :, 1],
        "tau_n": tau,
        "alpha1": alpha,
        "alpha2": a2 if not ship.tau_from_setpoint else alpha,
        "n1": nn,
        "n2": nn,
    }


def _lowpass(x: np.ndarray, tau: float, dt: float) -> np.ndarray:
    """Causal first-order low-pass along axis 0 (a sensor's own filter), started at the first sample."""
    from scipy.signal import lfilter, lfilter_zi

    a = math.exp(-dt / tau)
    zi = lfilter_zi([1 - a], [1, -a])[:, None] * x[:1]
    return lfilter([1 - a], [1, -a], x, axis=0, zi=zi)[0]


def _noise(shape: tuple, sd: float, coloured: bool, rng: np.random.Generator, dt: float) -> np.ndarray:
    if not coloured:
        return sd * rng.standard_normal(shape)
    e = rng.standard_t(3, size=shape) / math.sqrt(3.0)  # unit variance, heavy tails
    a = math.exp(-dt / 1.5)  # AR(1), 1.5 s correlation time
    from scipy.signal import lfilter

    return sd * lfilter([math.sqrt(1 - a * a)], [1, -a], e, axis=0)


def measure(ship: Ship, tr: dict[str, np.ndarray], dt: float, seed: int, noise_scale: float = 1.0) -> dict[str, np.ndarray]:
    """Recorded columns (n, runs): truth plus noise (Table 4.1 levels; roll rate 0.01 rad/s, pod
    angle 0.005 rad, propeller 0.2 rev/s), each through its sensor's low-pass; a drifting gyro
    bias in the coloured-noise variant."""
    rng = np.random.default_rng([seed, 13])
    lp = dict(ship.lp)
    sds = TABLE_4_1 | {"p": 0.01, "alpha1": 0.005, "alpha2": 0.005, "n1": 0.2, "n2": 0.2}
    out = {}
    for k in ("u", "v", "r", "phi", "p", "v_dot", "tau_n", "alpha1", "alpha2", "n1", "n2"):
        x = tr[k] + _noise(tr[k].shape, noise_scale * sds[k], ship.coloured, rng, dt)
        if k == "r" and ship.coloured:  # gyro bias: random walk, about 0.0005 rad/s after 500 s
            x = x + np.cumsum(2.2e-5 * math.sqrt(dt) * rng.standard_normal(x.shape), axis=0)
        out[k] = _lowpass(x, lp[k], dt) if k in lp else x
    out.update({k: tr[k] for k in ("x", "y", "psi")})
    return out


def recordings(
    variant: str,
    ship_seed: int,
    run_seeds: list[int],
    duration_s: float = 500.0,
    dt: float = 0.1,
    change_at_s: list[float | None] | None = None,
    noise_scale: float = 1.0,
    ship: Ship | None = None,
    lead_in_s: float = 150.0,
) -> list[dict[str, np.ndarray]]:
    """Recorded columns of one ship (``draw_ship(variant, ship_seed)`` unless ``ship`` is given)
    on the manoeuvres ``run_seeds``, one dict of (n,) columns per run, ``change_at_s`` per run
    (None: unchanged; else +10 % I_z from that time)."""
    ship = ship or draw_ship(variant, ship_seed)
    n = int(round(duration_s / dt))
    cmds = [harbour_commands(n, dt, s, ship.roll_weave) for s in run_seeds]
    n_cmd = np.stack([c[0] for c in cmds], axis=1)
    a_cmd = np.stack([c[1] for c in cmds], axis=1)
    change = [np.nan if c is None else c for c in (change_at_s or [None] * len(run_seeds))]
    tr = simulate(ship, n_cmd, a_cmd, dt, np.array(change), lead_in_s=lead_in_s)
    meas = measure(ship, tr, dt, seed=run_seeds[0] * 7919 + ship_seed, noise_scale=noise_scale)
    t = np.arange(n) * dt
    return [{"t": t} | {k: x[:, j] for k, x in meas.items()} for j in range(len(run_seeds))]


def write_csv(
    cols: dict[str, np.ndarray],
    path: str | Path,
    sample_time: float = 0.1,
    rename: dict[str, str] | None = None,
    drop: tuple[str, ...] = (),
) -> Path:
    """The recording CSV the product reads: ``# sample_time`` metadata line, a header, one row per
    sample. ``rename`` and ``drop`` make the header of a different logger."""
    rename = rename or {}
    names = [k for k in cols if k not in drop]
    path = Path(path)
    with path.open("w", newline="") as f:
        f.write(f"# sample_time: {sample_time:g}\n")
        w = csv.writer(f)
        w.writerow([rename.get(k, k) for k in names])
        arr = np.column_stack([cols[k] for k in names])
        w.writerows([[f"{x:.9g}" for x in row] for row in arr])
    return path
