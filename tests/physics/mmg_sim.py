"""Free-running manoeuvres of the MMG KVLCC2 (:mod:`tests.physics.mmg_kvlcc2`), integrated with
classical RK4 at a fine step (Ts/5) and sampled at the recording rate.

Every run starts on a straight approach under a heading-hold autopilot (so a rudder offset,
a wind or a thrust loss is in steady state when the manoeuvre begins), then performs a
standard manoeuvre of IMO MSC.137(76) / ITTC 7.5-04-02-01: a delta/psi zig-zag or a turning
circle, to either side. The steering gear moves at most ``ship.rudder_rate``; what the ship
feels can lag the recorded rudder angle (an actuator delay) and be offset from it.

Runs are integrated together as one batch (vectorised over the leading axis).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tests.physics.mmg_kvlcc2 import Environment, MMGShip, derivative, propeller, to_recorded_delta

SUBSTEPS = 5  # RK4 steps per recording sample


@dataclass(frozen=True)
class Manoeuvre:
    """A standard manoeuvre. Angles in degrees; ``side`` +1 first rudder to starboard, -1 port;
    ``duration_s`` at full scale (Froude-scaled for a model)."""

    kind: str  # "zigzag", "turn" or "straight"
    delta_deg: float = 0.0
    psi_deg: float = 0.0
    side: int = 1
    duration_s: float = 600.0

    @property
    def label(self) -> str:
        s = "stbd" if self.side > 0 else "port"
        if self.kind == "zigzag":
            return f"zz{self.delta_deg:g}-{self.psi_deg:g}-{s}"
        if self.kind == "turn":
            return f"tc{self.delta_deg:g}-{s}"
        return "straight"


@dataclass
class Run:
    """Noise-free samples of one run (MMG sign convention for the rudder kept in ``delta_mmg``)."""

    manoeuvre: Manoeuvre
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    u: np.ndarray  # over ground, body axes
    v: np.ndarray
    r: np.ndarray
    delta_mmg: np.ndarray  # steering-gear angle (what a rudder indicator shows)
    n: np.ndarray
    wind_gain: np.ndarray | None = None  # the gusts: wind speed / its mean at each sample (None: steady)
    wind_turn: np.ndarray | None = None  # direction gusts: the wind's turn from its mean, rad (None: steady)

    def wind_ne(self, mean_ne: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """The air velocity (north, east) at each sample for the mean wind ``mean_ne``, gusts included."""
        k = len(self.t)
        g = np.ones(k) if self.wind_gain is None else self.wind_gain
        a = np.zeros(k) if self.wind_turn is None else self.wind_turn
        c, s = np.cos(a), np.sin(a)
        return g * (c * mean_ne[0] - s * mean_ne[1]), g * (s * mean_ne[0] + c * mean_ne[1])

    @property
    def delta(self) -> np.ndarray:
        """The recorded rudder angle in the shiptrial / MARIN convention (positive turns to port)."""
        return to_recorded_delta(self.delta_mmg)


def straight_speed(ship: MMGShip, n: float) -> float:
    """Steady speed straight ahead at ``n`` rps in still air (X_H + X_P + X_air = 0)."""
    from scipy.optimize import brentq

    from tests.physics.mmg_kvlcc2 import hull_forces, wind_forces

    def xsum(u: float) -> float:
        air = wind_forces(ship, np.array([u]), np.zeros(1), np.zeros(1), np.zeros(2))[0][0]
        return float(hull_forces(ship, u, 0.0, 0.0)[0] + propeller(ship, u, 0.0, 0.0, n)[3] + air)

    return float(brentq(xsum, 1e-3 * ship.U0, 3.0 * ship.U0, xtol=1e-12))


def _commands(
    mans: list[Manoeuvre], psi_dev: np.ndarray, r: np.ndarray, cmd: np.ndarray, started: bool, ship: MMGShip
) -> np.ndarray:
    """Rudder commands (MMG convention) of each run for its heading deviation from the course."""
    out = cmd.copy()
    if not started:  # heading-hold autopilot on the approach; gains scaled with the ship's time
        kd = 40.0 * ship.time_scale
        return np.clip(-2.0 * psi_dev - kd * r, -np.radians(10.0), np.radians(10.0))
    for i, m in enumerate(mans):
        a = np.radians(m.delta_deg) * m.side
        if m.kind == "turn":
            out[i] = a
        elif m.kind == "zigzag":
            if abs(abs(cmd[i]) - abs(a)) > 1e-12:  # first step of the manoeuvre: the autopilot hands over
                out[i] = a
            elif np.sign(cmd[i]) * psi_dev[i] >= np.radians(m.psi_deg):
                out[i] = -cmd[i]  # heading reached the switching angle on this side: reverse the rudder
        else:
            out[i] = np.clip(-2.0 * psi_dev[i] - 40.0 * ship.time_scale * r[i], -0.17, 0.17)
    return out


def simulate_runs(
    ship: MMGShip,
    mans: list[Manoeuvre],
    n_rps: float,
    *,
    env: Environment = Environment(),
    delay_s: float = 0.0,
    offset_rad: float = 0.0,
    sample_time: float | None = None,
    lead_in_s: float = 300.0,
    pre_s: float = 30.0,
    psi0: float = 0.0,
) -> list[Run]:
    """Integrate the runs (one batch) and sample them every ``sample_time`` s.

    ``delay_s`` and ``offset_rad`` are this ship's seconds and the offset in the recorded
    convention (the ship acts on recorded delta - offset). Durations and lead-in are given at
    full scale and Froude-scaled here. The recording starts ``pre_s`` before the manoeuvre.
    """
    ts_scale = ship.time_scale
    Ts = sample_time if sample_time is not None else 1.0 * ts_scale
    h = Ts / SUBSTEPS
    B = len(mans)
    lead = lead_in_s * ts_scale
    t_end = lead + max(m.duration_s for m in mans) * ts_scale
    n_steps = int(round(t_end / h))
    rec_from = int(round((lead - pre_s * ts_scale) / h))
    Minv = np.linalg.inv(ship.mass_matrix())
    u0 = straight_speed(ship, n_rps)
    cn, ce = env.current_ne
    s = np.zeros((B, 6))
    s[:, 2] = psi0
    s[:, 3] = u0  # steady through the water (a current only adds to the speed over ground)
    gear = np.zeros(B)
    cmd = np.zeros(B)
    n_delay = delay_s / h
    hist = np.zeros((int(np.ceil(n_delay)) + 3, B))  # past gear angles, newest first
    n_arr = np.full(B, n_rps)
    rows = []
    psi_ref = np.full(B, psi0)
    started = False
    max_step = ship.rudder_rate * h

    def felt(lag: float) -> np.ndarray:
        """Gear angle ``lag`` sub-steps ago (linear interpolation in the history) + the offset."""
        k = int(np.floor(lag))
        f = lag - k
        return (1 - f) * hist[k] + f * hist[k + 1] + offset_rad  # recorded - offset, in MMG sign

    gains = _gusts(env, B, n_steps + 1, h, ts_scale)

    for k in range(n_steps + 1):
        t = k * h
        env_k = env if gains is None else replace(env, wind_ne=_gusty(env.wind_ne, gains[0][k], gains[1][k]))
        if not started and t >= lead - 1e-9:
            started = True
            psi_ref = s[:, 2].copy()
        dev = s[:, 2] - psi_ref
        cmd = _commands(mans, dev, s[:, 5], cmd, started, ship)
        if k >= rec_from and (k - rec_from) % SUBSTEPS == 0:
            g_k = (np.ones(B), np.zeros(B)) if gains is None else (gains[0][k], gains[1][k])
            rows.append(np.column_stack([np.full(B, t), s, gear, *g_k]))
        if k == n_steps:
            break
        new_gear = gear + np.clip(cmd - gear, -max_step, max_step)
        new_gear = np.clip(new_gear, -ship.rudder_max, ship.rudder_max)
        hist = np.vstack([new_gear[None], hist[:-1]]) if len(hist) > 1 else new_gear[None]
        # the gear moves linearly over the step: stage inputs at t, t + h/2, t + h
        d0, d1, d2 = felt(n_delay + 1.0), felt(n_delay + 0.5), felt(n_delay)
        k1 = derivative(ship, Minv, s, d0, n_arr, env_k)  # the gust held over the step
        k2 = derivative(ship, Minv, s + 0.5 * h * k1, d1, n_arr, env_k)
        k3 = derivative(ship, Minv, s + 0.5 * h * k2, d1, n_arr, env_k)
        k4 = derivative(ship, Minv, s + h * k3, d2, n_arr, env_k)
        s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        gear = new_gear
    a = np.stack(rows, axis=1)  # (B, N, 10)
    out = []
    for i, m in enumerate(mans):
        t = a[i, :, 0] - a[i, 0, 0]
        x, y, psi, ur, vr, r, g = (a[i, :, j] for j in range(1, 8))
        u = ur + np.cos(psi) * cn + np.sin(psi) * ce
        v = vr - np.sin(psi) * cn + np.cos(psi) * ce
        n_keep = int(round((pre_s + m.duration_s) * ts_scale / Ts)) + 1
        out.append(
            Run(
                m,
                t[:n_keep],
                x[:n_keep],
                y[:n_keep],
                psi[:n_keep],
                u[:n_keep],
                v[:n_keep],
                r[:n_keep],
                g[:n_keep],
                np.full(n_keep, n_rps),
                None if gains is None else a[i, :n_keep, 8],
                None if gains is None else a[i, :n_keep, 9],
            )
        )
    return out


def _gusty(mean_ne: tuple[float, float], gain: np.ndarray, turn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean wind scaled by ``gain`` and turned by ``turn`` (rad)."""
    c, s = np.cos(turn), np.sin(turn)
    return gain * (c * mean_ne[0] - s * mean_ne[1]), gain * (s * mean_ne[0] + c * mean_ne[1])


def _gusts(env: Environment, B: int, n: int, h: float, ts_scale: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Gust factors 1 + g and turns a (n, B each) on the integration grid, or None for a steady
    wind: g and a first-order Gauss-Markov with std ``env.gust`` and ``env.gust_dir`` and time
    constant ``env.gust_time_s`` (Froude-scaled), stationary from the first step, seeded by
    ``env.gust_seed`` (each run its own gusts; the speed draws come first, as before direction
    gusts were added)."""
    if env.wind_ne is None or env.gust <= 0.0:
        return None
    rng = np.random.default_rng([env.gust_seed, 26])
    a = float(np.exp(-h / (env.gust_time_s * ts_scale)))
    out = []
    for std in (env.gust, env.gust_dir):
        g = np.empty((n, B))
        g[0] = std * rng.standard_normal(B)
        w = std * np.sqrt(1.0 - a * a) * rng.standard_normal((n, B))
        for k in range(1, n):
            g[k] = a * g[k - 1] + w[k]
        out.append(g)
    return 1.0 + out[0], out[1]


def tactical_diameter(run: Run) -> float:
    """Transfer (distance normal to the approach course) when the heading has changed by 180 deg."""
    dpsi = np.abs(run.psi - run.psi[0])
    i = int(np.argmax(dpsi >= np.pi))
    if dpsi[i] < np.pi:
        return float("nan")
    f = (np.pi - dpsi[i - 1]) / (dpsi[i] - dpsi[i - 1])
    c, s_ = np.cos(run.psi[0]), np.sin(run.psi[0])
    lat = -s_ * (run.x - run.x[0]) + c * (run.y - run.y[0])
    return float(abs(lat[i - 1] + f * (lat[i] - lat[i - 1])))


def advance(run: Run) -> float:
    """Distance along the approach course when the heading has changed by 90 deg."""
    dpsi = np.abs(run.psi - run.psi[0])
    i = int(np.argmax(dpsi >= np.pi / 2))
    c, s_ = np.cos(run.psi[0]), np.sin(run.psi[0])
    return float(c * (run.x[i] - run.x[0]) + s_ * (run.y[i] - run.y[0]))


def overshoots_deg(psi: np.ndarray, delta: np.ndarray, psi_switch_deg: float) -> list[float]:
    """Zig-zag overshoot angles (deg): how far the heading swings beyond the switching angle
    after each rudder reversal (either rudder sign convention: reversals are read from delta)."""
    d = np.asarray(delta)
    big = np.abs(d) > 0.5 * np.max(np.abs(d))
    sgn = np.where(big, np.sign(d), 0.0)
    for i in range(1, len(sgn)):  # hold the last large rudder side
        if sgn[i] == 0:
            sgn[i] = sgn[i - 1]
    rev = [i for i in range(1, len(sgn)) if sgn[i - 1] != 0 and sgn[i] != sgn[i - 1]]
    dev = np.degrees(psi - psi[0])
    out = []
    for a, b in zip(rev, rev[1:] + [len(d)]):
        seg = dev[a:b]
        ext = seg.max() if abs(seg.max()) > abs(seg.min()) else seg.min()
        if b < len(d) or abs(ext) > psi_switch_deg:
            out.append(float(abs(ext) - psi_switch_deg))
    return out
