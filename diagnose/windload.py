"""Wind loads from the recorded wind for the wind candidate (issue 26): Blendermann's (1994)
closed-form coefficients for a loaded tanker, in excess of the still air's.

W. Blendermann (1994), Parameter identification of wind loads on ships, J. Wind Eng. Ind.
Aerodyn. 51, 339-351 (as given by Fossen 2021, section 10.1.2), relative wind angle
g = -atan2(v_q, u_q) (0 from ahead, positive from port), u_q, v_q the ship's velocity
relative to the air:

    C_X = -C_DlAF(g) cos g / D,  C_Y = C_Dt sin g / D,  C_N = (s_L/L - 0.18 (|g| - pi/2)) C_Y,
    D = 1 - delta/2 (1 - C_Dl/C_Dt) sin^2 2g,  C_Dl = C_DlAF A_F / A_L,

X = q A_F C_X, Y = q A_L C_Y, N = q A_L L C_N, q = rho_a V_q^2 / 2; for a loaded tanker
C_Dt = 0.70, C_DlAF = 0.90 (wind from ahead) / 0.55 (from astern), delta = 0.40.

The areas come from the profile's main particulars: a loaded tanker's above-water profile is
taken as a box of the freeboard's height, 0.45 d (KVLCC2: 9.2 m on 20.8 m), so A_L = 0.45 L d
and A_F = 0.45 B d. The magnitude of each DOF is refitted (the candidate's coefficients), and in
yaw the lateral centroid's arm s_L too (a fourth signal, q A_L L C_Y, whose coefficient is the
arm s_L/L times the yaw scale), so the areas and the air density set only the shape over the
wind angle and the starting scale. The signals are the loads made dimensionless
with the hull's 1/2 rho L^2 d (and L for the moment), so a coefficient is about
T_s / (m' + m'_a), the sample time over the dimensionless mass with added mass.

A wind that was not recorded (:func:`steady_increments`) is the same loads of a steady air
velocity (north, east) over the recording set, its two components the fitted parameters: the
magnitudes cannot all be refitted too (a stronger wind and a larger scale give the same loads),
so each DOF's scale is the ship's own, T_s / (m' + m'_a), with the mass of a loaded tanker's
block (C_B = 0.80) and the added masses of Clarke et al. (1983), the sway load setting the
wind's speed; the surge load's scale (the frontal area: the box leaves out the superstructure,
543 m^2 for KVLCC2 against about 1,130 m^2) and the yaw arm are refitted with it.

The truth the battery tests this with (tests/physics) uses Isherwood's (1972) tables instead.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from primitives.particulars.regressions import Hull, added_mass
from primitives.simulate import body_from_ne


class Particulars(Protocol):
    """What the loads need of a ship: its main particulars (a ``ShipProfile`` has them)."""

    length_m: float
    beam_m: float
    draught_m: float


# exogenous signals of the wind candidate's terms: X, Y, N at the centroid assumed (midship) and
# the moment of Y about a centroid s_L forward per unit s_L/L (C_Y itself): the main particulars
# do not place the superstructure, so its yaw arm is refitted with the magnitudes
SIGNALS = ("wind_X", "wind_Y", "wind_N", "wind_N_arm")
DOF_OF = (0, 1, 2, 2)
RHO_AIR, RHO_WATER = 1.225, 1025.0
TANKER = {"C_Dt": 0.70, "C_DlAF_bow": 0.90, "C_DlAF_stern": 0.55, "delta": 0.40}  # Blendermann (1994), loaded tanker
FREEBOARD_OVER_DRAUGHT = 0.45


def coefficients(gamma: np.ndarray, af_over_al: float, sl_over_l: float = 0.0, c: dict = TANKER) -> tuple[np.ndarray, ...]:
    """Blendermann's (1994) C_X, C_Y, C_N at relative wind angles ``gamma`` (rad, -pi..pi)."""
    g = np.asarray(gamma, float)
    cdl_af = np.where(np.abs(g) <= np.pi / 2, c["C_DlAF_bow"], c["C_DlAF_stern"])
    cdl = cdl_af * af_over_al
    den = 1.0 - 0.5 * c["delta"] * (1.0 - cdl / c["C_Dt"]) * np.sin(2.0 * g) ** 2
    cy = c["C_Dt"] * np.sin(g) / den
    return -cdl_af * np.cos(g) / den, cy, (sl_over_l - 0.18 * (np.abs(g) - np.pi / 2)) * cy


def _loads(profile: Particulars, uq: np.ndarray, vq: np.ndarray) -> np.ndarray:
    """(..., 4) dimensionless X, Y, N and the moment per unit centroid arm (q A_L L C_Y) of the
    air relative to the ship (u_q, v_q body axes). L is the profile's length between
    perpendiculars where Blendermann uses the length overall: harmless, since each DOF's scale
    and the yaw arm are refitted, but the starting scale is that much off."""
    L, B, d = profile.length_m, profile.beam_m, profile.draught_m
    h = FREEBOARD_OVER_DRAUGHT * d
    a_l, a_f = h * L, h * B
    cx, cy, cn = coefficients(-np.arctan2(vq, uq), a_f / a_l)
    q = (RHO_AIR / RHO_WATER) * (uq**2 + vq**2) / (L * L * d)  # 1/2 rho_a V^2 / (1/2 rho L^2 d)
    return np.stack([q * a_f * cx, q * a_l * cy, q * a_l * cn, q * a_l * cy], axis=-1)


def excess_loads(profile: Particulars, y: np.ndarray, wind_body: tuple[np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    """The :data:`SIGNALS` of a recording: wind loads with the recorded air velocity
    ``wind_body`` (body axes) minus those of still air, at the recorded velocities ``y`` (u, v,
    r). The baseline fitted on calm runs holds the still-air drag of the ship's own motion; the
    excess is zero in still air. Recorded, not simulated, velocities: the relative wind is what
    the anemometer measures, and the ship's speed changes its load by little against an 18 m/s wind."""
    return dict(zip(SIGNALS, np.moveaxis(_excess(profile, y, wind_body, still_loads(profile, y)), -1, 0)))


def still_loads(profile: Particulars, y: np.ndarray) -> np.ndarray:
    """(..., 4) loads of still air at the recorded velocities ``y`` (what :func:`excess_loads` subtracts)."""
    return _loads(profile, y[..., 0], y[..., 1])


def _excess(profile: Particulars, y: np.ndarray, wind_body: tuple[np.ndarray, np.ndarray], still: np.ndarray) -> np.ndarray:
    """(..., 4) loads of the air velocity ``wind_body`` less those of still air ``still``
    (:func:`still_loads` of ``y``): elementwise, so each air velocity's the same bits alone or in a batch."""
    return _loads(profile, y[..., 0] - wind_body[0], y[..., 1] - wind_body[1]) - still


# the steady (not recorded) wind's fixed scales: a loaded tanker's block coefficient, as the
# coefficients above are a loaded tanker's, and a radius of gyration of a quarter length
CB_TANKER = 0.80
GYRATION_OVER_L = 0.25


def ship_gains(profile: Particulars, sample_time: float) -> np.ndarray:
    """(3,) increments of u, v (m/s) and r (rad/s) over one sample per unit of the X, Y, N
    signals of :func:`_loads`: T_s / (m' + m'_x), T_s / (m' + m'_y), T_s / ((I'_z + J'_z) L),
    with m' = 2 C_B B / L on 1/2 rho L^2 d, I'_z = m' (0.25)^2 and the added masses of Clarke,
    Gedling & Hine (1983), eqs. (13), (16) (m'_x = 0.05 m')."""
    h = Hull(profile.length_m, profile.beam_m, profile.draught_m, CB_TANKER)
    a = added_mass(h)
    m = h.mass_nd
    iz = m * GYRATION_OVER_L**2
    return sample_time / np.array([m + a["mx"], m + a["my"], (iz + a["Jz"]) * profile.length_m])


def steady_increments(
    profile: Particulars, y: np.ndarray, psi: np.ndarray, wind: np.ndarray, sample_time: float, memo: dict | None = None
) -> np.ndarray:
    """(B, N+1, 3) increments of u, v, r over each sample from a steady wind, ``wind`` (B, 4) its
    air velocity toward north and east (m/s), the lateral centroid's arm s_L/L forward of
    midship and the surge load's scale less one, at the recorded velocities ``y`` (N+1, 3) and
    heading ``psi``: the excess loads of :func:`excess_loads` (Blendermann 1994) in body axes as
    the ship turns, the surge load scaled, the yaw moment about the centroid (``wind_N`` + s_L/L
    ``wind_N_arm``), all scaled by :func:`ship_gains`.

    ``memo``: a dict kept by the caller for one recording (``y``, ``psi``) and one profile, read
    and extended: its still-air loads and the excess loads of the last :data:`MEMO_AIR` distinct
    air velocities, so that a refit's Jacobian at an accepted trial (the same air) and every
    call after the first compute no still-air loads again. The same numbers as without it."""
    w = np.asarray(wind, float)
    memo = {} if memo is None else memo
    if "still" not in memo:
        memo["still"] = still_loads(profile, y)
    # the loads of each distinct air velocity once (a Jacobian's members share one but for the wind's
    # own columns), and the increments of each distinct row of ``wind`` once (all its members but
    # the wind's own columns): elementwise in the members, the same numbers as computed for each.
    # Distinct by their bits: 0.0 and -0.0 (equal as floats) put a following wind's relative angle
    # at pi or -pi (arctan2's sign of zero), and so its loads differ in the last bits
    air = memo.setdefault("air", {})
    keys = [row.tobytes() for row in np.ascontiguousarray(w[:, :2])]
    # this call's loads read from a local dict, never from the memo after it is extended: another
    # caller's eviction (two threads on one recording) cannot take an entry between insert and read
    got = {k: air.get(k) for k in dict.fromkeys(keys)}
    new = [k for k, v in got.items() if v is None]
    if new:
        a = np.frombuffer(b"".join(new), dtype=float).reshape(len(new), 1, 2)
        got.update(zip(new, _excess(profile, y, body_from_ne(a, psi), memo["still"])))  # each (N+1, 4)
        air.update((k, got[k]) for k in new)
        keep = max(1, min(MEMO_AIR, MEMO_BYTES // max(got[new[0]].nbytes, 1)))  # a long recording keeps fewer
        for k in list(air)[: max(len(air) - keep, 0)]:  # the oldest first (dicts keep insertion order)
            air.pop(k, None)
    rows = [row.tobytes() for row in np.ascontiguousarray(w)]
    at = {k: i for i, k in reversed(list(enumerate(rows)))}  # each distinct row's first member
    first = np.array(sorted(at.values()), dtype=int)
    back = np.searchsorted(first, [at[k] for k in rows])
    ex = np.stack([got[keys[i]] for i in first])  # (distinct rows, N+1, 4)
    wd = w[first][:, None, :]
    n = ex[..., 2] + wd[..., 2] * ex[..., 3]
    inc = np.stack([ex[..., 0] * (1.0 + wd[..., 3]), ex[..., 1], n], axis=-1) * ship_gains(profile, sample_time)
    return inc if len(first) == len(w) else inc[back]


MEMO_AIR = 16  # air velocities a recording's memo keeps (a refit's trials and Jacobian need fewer than 8)
# and at most this many bytes of them: 16 of a 3,500-sample run are 1.8 MB, of a 100,000-sample
# run 51 MB a recording (twenty such recordings would hold 1 GB until the diagnosis ends)
MEMO_BYTES = 8 << 20


MEAN_KEYS = ("wind_accel_surge", "wind_accel_sway", "wind_accel_yaw")  # m/s^2, m/s^2, rad/s^2


def mean_acceleration(preps: list, values: np.ndarray, covs: dict[str, np.ndarray]) -> dict[str, float | None]:
    """The fitted wind's mean acceleration of the ship per DOF over the diagnosed runs
    (``preps``, diagnose.model.Prepared with :data:`SIGNALS` in ``wind_loads``): each DOF's
    increment ``sum_k c_k s_k`` (its signals s_k, coefficients ``values`` in the order of
    :data:`SIGNALS`) averaged over every step of every run and divided by the sample time; its
    std ``<key>_std<part>`` from each covariance ``covs[part]`` of the coefficients (same order;
    the mean is linear in them). A quantity of the ship's motion, not of the coefficients'
    parametrisation: what the wind did, whichever published coefficients shaped it (the yaw
    scale and the centroid's arm, which trade off against each other, are summed here)."""
    sums, n = np.zeros(len(SIGNALS)), 0
    for p in preps:
        if p.wind_loads:
            sums += np.array([np.sum(p.wind_loads[k][:-1]) for k in SIGNALS]) / float(p.rec.sample_time)
            n += len(p.wind_loads[SIGNALS[0]]) - 1
    means = sums / max(n, 1)
    out: dict[str, float | None] = {}
    for i, key in enumerate(MEAN_KEYS):
        g = np.where(np.array(DOF_OF) == i, means, 0.0)
        out[key] = float(g @ values) if n else None
        for part, C in covs.items():
            var = float(g @ C @ g)
            out[f"{key}_std{part}"] = float(np.sqrt(var)) if n and np.isfinite(var) and var >= 0 else None
    return out


def steady_mean_acceleration(
    profile: Particulars, preps: list, wind: np.ndarray, covs: dict[str, np.ndarray]
) -> dict[str, float | None]:
    """:func:`mean_acceleration` of a steady wind not recorded (``wind`` (4,) as in
    :func:`steady_increments`): each DOF's increment averaged over every step of the diagnosed
    runs ``preps`` and divided by the sample time; its stds from the covariances ``covs`` of the
    four through the
    central-difference gradient (the mean is not linear in the wind)."""
    w = np.asarray(wind, float)
    h = np.array([max(1e-3, 1e-3 * float(np.hypot(w[0], w[1])))] * 2 + [1e-3] * 2)
    k = len(w)
    rows = np.vstack([w, w + np.diag(h), w - np.diag(h)])  # w, w + h_k e_k, w - h_k e_k
    sums, n = np.zeros((len(rows), 3)), 0
    for p in preps:
        inc = steady_increments(profile, p.y, p.psi, rows, float(p.rec.sample_time))[:, :-1]
        sums += inc.sum(axis=1) / float(p.rec.sample_time)
        n += inc.shape[1]
    means = sums / max(n, 1)
    grad = (means[1 : k + 1] - means[k + 1 :]) / (2.0 * h[:, None])  # (4 parameters, 3 DOFs)
    out: dict[str, float | None] = {}
    for i, key in enumerate(MEAN_KEYS):
        out[key] = float(means[0, i]) if n else None
        for part, C in covs.items():
            var = float(grad[:, i] @ C @ grad[:, i])
            out[f"{key}_std{part}"] = float(np.sqrt(var)) if n and np.isfinite(var) and var >= 0 else None
    return out
