"""Linearised roll model of Linder et al. (2015), eqs. (3)-(19), and its profile.

Vertical positions are body-frame values ``zbar`` (z down) plus the centre-of-rotation offset
``z_f`` (12): ``z = zbar + z_f``. The roll equation after eliminating the unmeasured sway
acceleration through the IMU's tangential accelerometer is (11)::

    A2 phi'' = -(k - K_vdot g) phi - d phi' - c a_s + K_r r + K_delta delta + tau
    A2 = A_x + M z_g (z_g - z_s) + m z_m (z_m - z_s) - K_vdot z_s          (10)
    c  = K_vdot + M z_g + m z_m

Only ``A2`` and ``c`` depend on the load ``(m, z_m)``. The equation is homogeneous, so one
dataset fixes only ratios; with ``A_x``, ``k`` and ``K_vdot`` free, a common scale ``lambda`` of
(11) together with ``z_f -> lambda z_f + (lambda - 1) zbar_c`` leaves every dataset's ratios
unchanged (see :func:`flat_direction`): the scale and ``z_f`` are not separable.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from primitives.io import read_input_text
from primitives.profile_tables import read_vessel
from primitives.ship import ProfileError

RHO_WATER = 1000.0  # kg/m^3, the basin's fresh water
DEFAULT_PROFILE = Path(__file__).with_name("our_lass_ii.toml")

# Shared physical parameters of (20) that are estimated, in the order of the paper's Table 3.
SHIP_PARAMS = ("k", "A_x", "d", "K_r", "K_vdot", "K_delta", "z_f")


@dataclass(frozen=True)
class Known:
    """What the estimator is told (section 3.4): nominal mass and CoG, IMU position, gravity."""

    M: float
    zbar_g: float
    zbar_s: float
    g: float = 9.81
    # IMU x forward of midship [m]: its accelerometer then reads the yaw acceleration x_s r' as well
    xbar_s: float = 0.0
    U: float = 0.5
    z_f_prior: float = -0.03
    z_f_prior_sd: float = 0.015
    # body-frame z [m] (z down from the unloaded waterline) where a load's added buoyancy acts: the
    # centroid of the extra layer of displacement it sinks the hull by. For a wall-sided hull (waterplane
    # inertia independent of draft) d((M + m) g GM)/dm = g (zbar_m - zbar_b) with zbar_b = -dT/2, half the
    # sinkage dT = m / (rho A_wp) above the unloaded waterline (Biran 2003, Ship Hydrostatics, ch. 6);
    # 0 drops that half sinkage (0.9 mm for 0.4 kg on Our Lass II, 0.3 % of its restoring). The
    # paper's (3) lets it act at the roll centre, zbar_b = -z_f (the load's restoring m g z_m about the CR).
    # A flared hull (A_wp and its inertia growing with draft) moves it further; nothing here models that.
    zbar_b: float = 0.0
    # the hull's transverse metacentric radius BM = I_T / V [m] at displacement M (profile [ship] BM_T) and
    # the nominal GM [m] (GM_T): the wall-sided restoring beyond the linear term (identify.rollmass.restoring);
    # BM = 0 keeps the restoring linear in phi
    BM: float = 0.0
    GM: float = 0.0


@dataclass(frozen=True)
class RollParams:
    """Shared roll parameters of (11)-(12): k (5a), A_x = I_x - K_pdot (4), d (5b), K_r, K_vdot, K_delta, z_f."""

    k: float
    A_x: float
    d: float
    K_r: float
    K_vdot: float
    K_delta: float
    z_f: float

    def vector(self) -> np.ndarray:
        return np.array([getattr(self, f.name) for f in fields(self)])

    @classmethod
    def from_vector(cls, x: np.ndarray) -> RollParams:
        return cls(*map(float, x))


@dataclass(frozen=True)
class Load:
    """A load ``m`` [kg] at body-frame height ``zbar`` [m, z down]; ``Load(0, 0)`` is the nominal ship."""

    m: float
    zbar: float


@dataclass(frozen=True)
class RollProfile:
    """The Our Lass II profile: known quantities, true roll parameters, and the raw TOML tables."""

    name: str
    known: Known
    truth: RollParams
    K_ur: float
    raw: dict
    vessel: str = ""  # [ship] vessel: the ship it models, as '# ship:' headers name it (primitives.profile_tables)


def load_moments(p: RollParams, kn: Known, load: Load) -> tuple[float, float]:
    """The two load moments the roll data see: ``m z_m`` (in c) and ``m z_m (zbar_m - zbar_s)`` (in A2)."""
    mz = load.m * (load.zbar + p.z_f)
    return mz, mz * (load.zbar - kn.zbar_s)


def load_from_moments(p: RollParams, kn: Known, mz: float, mzs: float) -> Load:
    """Invert :func:`load_moments`: ``zbar_m = zbar_s + mzs / mz``, ``m = mz / (zbar_m + z_f)``."""
    zbar = kn.zbar_s + mzs / mz if mz != 0 else float("nan")
    return Load(mz / (zbar + p.z_f), zbar)


def load_restoring(kn: Known, load: Load) -> float:
    """Roll restoring a load adds [N m/rad]: its weight at ``zbar_m`` less its added buoyancy at
    ``zbar_b`` (both body frame, z down), ``m g (zbar_m - zbar_b)``; independent of the roll centre."""
    return load.m * kn.g * (load.zbar - kn.zbar_b)


def continuous_coefficients(p: RollParams, kn: Known, load: Load | tuple[float, float]) -> np.ndarray:
    """``[A2, d, k - K_vdot g, c, K_r, K_delta]`` of (11) for one loading condition, (10)-(12).

    ``load`` is a :class:`Load` or its moments ``(m z_m, m z_m (zbar_m - zbar_s))``, in which (10)
    and ``c`` are linear.
    """
    z_g, z_s = kn.zbar_g + p.z_f, kn.zbar_s + p.z_f
    mz, mzs = load_moments(p, kn, load) if isinstance(load, Load) else load
    A2 = p.A_x + kn.M * z_g * (z_g - z_s) + mzs - p.K_vdot * z_s
    c = p.K_vdot + kn.M * z_g + mz
    return np.array([A2, p.d, p.k - p.K_vdot * kn.g, c, p.K_r, p.K_delta])


def discrete_coefficients(cc: np.ndarray, T: float) -> np.ndarray:
    """``g = [alpha1, alpha2, beta0, kappa0, gamma0]`` of (15)/(17): Tustin discretisation of (11).

    The output is the roll rate, ``y = G_d(q) (a_s + F_r r + F_delta delta)`` with
    ``G_d = beta0 (1 - q^-2) / (1 + alpha1 q^-1 + alpha2 q^-2)`` (13)-(14).
    """
    A2, d, kp, c, K_r, K_delta = cc
    A2cal = 2 * d * T + kp * T**2 + 4 * A2
    return np.array(
        [
            (2 * kp * T**2 - 8 * A2) / A2cal,
            (-2 * d * T + kp * T**2 + 4 * A2) / A2cal,
            -2 * T * c / A2cal,
            2 * T * K_r / A2cal,
            2 * T * K_delta / A2cal,
        ]
    )


def ratios_from_discrete(gd: np.ndarray, T: float) -> np.ndarray:
    """Invert (15): ``[d, k', c, K_r, K_delta] / A2`` from one dataset's ``g`` (scale-free)."""
    a1, a2, b0, k0, g0 = gd
    # With A2 = 1: A2cal (1 + a1 + a2) = 4 k' T^2 ; A2cal (1 - a2) = 4 d T ; A2cal (1 - a1 + a2) = 16.
    A2cal = 16.0 / (1 - a1 + a2)
    kp = A2cal * (1 + a1 + a2) / (4 * T**2)
    d = A2cal * (1 - a2) / (4 * T)
    return np.array([d, kp, -b0 * A2cal / (2 * T), k0 * A2cal / (2 * T), g0 * A2cal / (2 * T)])


def flat_direction(p: RollParams, kn: Known, cal: Load) -> np.ndarray:
    """Tangent of the exact invariance of the multi-dataset model (d/dlambda at lambda = 1).

    Scaling (11) by ``lambda`` while moving ``z_f -> lambda z_f + (lambda - 1) zbar_c`` and
    adjusting ``K_vdot``, ``A_x``, ``k`` keeps ``c_c - c_n = m_c z_c`` and every dataset's ratios
    fixed. Along it ``zbar_m`` is invariant and ``m`` is invariant only when ``zbar_m = zbar_c``.
    Returned in the order of :data:`SHIP_PARAMS` (then ``m``, ``zbar_m`` are 0 to first order
    only when the loaded height equals the calibration height; see :func:`load_along_flat`).
    """
    dzf = p.z_f + cal.zbar
    z_g, z_s = kn.zbar_g + p.z_f, kn.zbar_s + p.z_f
    c_n = p.K_vdot + kn.M * z_g
    dKv = c_n - kn.M * dzf
    A2n = p.A_x + kn.M * z_g * (z_g - z_s) - p.K_vdot * z_s
    # d/dlambda of M z_g (z_g - z_s) - K_vdot z_s, with z_g - z_s fixed:
    dA_x = A2n - (kn.M * dzf * (z_g - z_s) - dKv * z_s - p.K_vdot * dzf)
    dk = (p.k - p.K_vdot * kn.g) + kn.g * dKv
    return np.array([dk, dA_x, p.d, p.K_r, dKv, p.K_delta, dzf])


def metacentric_radius(ship: dict) -> float:
    """The hull's transverse metacentric radius ``BM = I_T / V`` [m] at the displacement ``M``: the
    profile's ``[ship] BM_T`` when given (0: restoring linear in roll), else (when the profile has ``draft``, ``L_w`` and ``KG``; otherwise 0) ``KM - KB`` from Table 1's
    ``KG + GM_T`` with the centre of buoyancy by Morrish's formula ``KB = T/3 (5/2 - C_B / C_wp)``, the
    block coefficient ``C_B = (M / rho) / (L_w B T)`` and the waterplane coefficient
    ``C_wp = (1 + 2 C_B) / 3`` (Schneekluth & Bertram 1998, Ship Design for Efficiency and Economy,
    ch. 2). Our Lass II: C_B 0.60, KB 0.081 m, BM 0.083 m (0.092 m for a box, KB = T/2)."""
    if "BM_T" in ship:
        return float(ship["BM_T"])
    if not all(k in ship for k in ("draft", "L_w", "KG")):
        return 0.0
    T = float(ship["draft"])
    c_b = float(ship["M"]) / RHO_WATER / (float(ship["L_w"]) * float(ship["B"]) * T)
    kb = T / 3.0 * (2.5 - c_b / ((1.0 + 2.0 * c_b) / 3.0))
    return float(ship["KG"]) + float(ship["GM_T"]) - kb


def load_profile(path: str | Path | None = None) -> RollProfile:
    """Read a roll profile TOML (default: Our Lass II). k follows from Table 1's GM_T."""
    path = Path(path) if path is not None else DEFAULT_PROFILE
    try:
        raw = tomllib.loads(read_input_text(path, ProfileError, f"a roll profile TOML like {DEFAULT_PROFILE.name}"))
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{path}: not valid TOML ({exc}); give a roll profile TOML like {DEFAULT_PROFILE.name}") from exc
    try:
        ship, kn_t, roll = raw["ship"], raw["known"], raw["roll"]
        hull = {"BM": metacentric_radius(ship), "GM": float(ship["GM_T"])}
        kn = Known(M=float(ship["M"]), **hull, **{k: float(v) for k, v in kn_t.items()})
        if not (0.0 <= kn.BM < 10.0 * ship["B"]):
            raise ValueError(
                f"[ship] BM_T = {kn.BM:g} m ({'given' if 'BM_T' in ship else 'KG + GM_T - KB'}): give the transverse "
                "metacentric radius I_T / V in metres (0: linear restoring)"
            )
        I_x = kn.M * (ship["kxx_over_B"] * ship["B"]) ** 2
        z_g = kn.zbar_g + roll["z_f"]
        k = kn.M * kn.g * ship["GM_T"] - kn.M * kn.g * z_g
        truth = RollParams(
            k=k,
            A_x=I_x - roll["K_pdot"],
            d=roll["d"],
            K_r=(roll["K_ur"] - roll["K_vdot"]) * kn.U,
            K_vdot=roll["K_vdot"],
            K_delta=roll["K_delta"],
            z_f=roll["z_f"],
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ProfileError(f"{path}: missing or malformed field {exc}; see {DEFAULT_PROFILE.name}") from exc
    vessel = read_vessel(ship, f"{path} [ship]")
    name = str(ship.get("name", path.stem))
    return RollProfile(name=name, known=kn, truth=truth, K_ur=float(roll["K_ur"]), raw=raw, vessel=vessel)
