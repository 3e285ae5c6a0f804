"""The motion set of the state lattice (seed 001 section 8.2, (8.3)-(8.8)).

Every move starts and ends at the lattice's transit state: cruise speed, no sway, no yaw rate,
a lattice heading, on a lattice point. Informative primitives get a short *settling leg*
appended (closed-loop on the nominal model: hold speed, steer to the nearest lattice heading,
sway onto the nearest lattice line, stop on a lattice point). Basic moves (straight run of one
cell, 90 deg turns at speed, turns on the spot that stop, turn and accelerate again) are built
the same way. Concatenating moves is then consistent and the continuous re-simulation stays
close to the lattice plan; what snapping is left (at most about half a sample of travel) is
recorded per move and heading and added to the collision margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from primitives import maneuvers as mv
from primitives.helm import straight as helm_straight
from primitives.library import Primitive
from primitives.ship import ShipProfile
from primitives.simulate import model_signals, simulate, steady_forces


@dataclass
class Move:
    """A primitive placed on the lattice. ``dcell[h]``: (di north, dj east) cells when started at
    heading index h; ``dh[h]``: heading steps; ``snap_m[h]``: distance between the simulated end
    position and the lattice point it is snapped to; ``counter``: index q of the informative
    counter it advances (-1 for basic moves); ``cost``: (8.8)."""

    name: str
    kind: str
    prims: list[Primitive]  # one per heading class (heading h uses prims[h % (K // 4)])
    counter: int
    cost: float
    dcell: np.ndarray  # (K, 2) int
    dh: np.ndarray  # (K,) int
    snap_m: np.ndarray  # (K,)
    heading_err: float
    source: str = ""
    run_in: tuple[int, ...] = ()  # samples of the run-in that opens the move, per heading class
    core: tuple[int, ...] = ()  # samples of run-in + primitive (the settling leg follows), per heading class

    def prim(self, h: int) -> Primitive:
        return self.prims[h % len(self.prims)]

    def run_in_samples(self, h: int) -> int:
        return self.run_in[h % len(self.run_in)] if self.run_in else 0

    def core_samples(self, h: int) -> int:
        return self.core[h % len(self.core)] if self.core else self.prim(h).n_samples


def heading_table(n_head: int) -> np.ndarray:
    """Lattice headings (rad, clockwise from north). 4: every 90 deg; 8: every 45 deg; 16: the
    directions of the grid vectors (1,0), (2,1), (1,1), (1,2), ... (non-uniform, as Nav2's state
    lattice does) so that straight runs end on lattice points."""
    if n_head not in (4, 8, 16):
        raise ValueError(f"headings must be 4, 8 or 16, got {n_head}")
    first = {4: [0.0], 8: [0.0, np.pi / 4], 16: [0.0, np.arctan2(1, 2), np.pi / 4, np.arctan2(2, 1)]}[n_head]
    return np.array([a + q * np.pi / 2 for q in range(4) for a in first])


def nearest_heading(psi: float, table: np.ndarray) -> int:
    return int(np.argmin(np.abs((table - psi + np.pi) % (2 * np.pi) - np.pi)))


def _gains(profile: ShipProfile) -> np.ndarray:
    """Per-DOF sensitivity d(increment)/d(tau) of the nominal model at cruise (for P gains)."""
    terms, th = profile.model, profile.params(None)
    u = profile.cruise_speed_mps
    base = None
    out = np.zeros(3)
    for i in range(4):
        tau = np.zeros(3) if i == 0 else np.eye(3)[i - 1]
        sig = model_signals(profile, np.array([u, 0.0, 0.0]), np.array(0.0), {"tau_x": tau[0], "tau_y": tau[1], "tau_n": tau[2]})
        inc = np.array([float(np.asarray(x)) for x in terms.increments(sig, th)])
        if i == 0:
            base = inc
        else:
            out[i - 1] = inc[i - 1] - base[i - 1]
    return out


def _clamp(x: float, lo: float, hi: float) -> float:
    """np.clip for one float, without numpy's per-call overhead (the helm's inner loop)."""
    return float(min(max(x, lo), hi))


_DEG8, _DEG20, _DEG05, _DEG02, _DEG005 = (float(np.radians(a)) for a in (8.0, 20.0, 0.5, 0.2, 0.05))
_NEIGHBOURS = np.array([[a, b] for a in (-1, 0, 1) for b in (-1, 0, 1)], float)  # a lattice point and its 8 neighbours


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


class _Rudder:
    """Helm and engine for a rudder/propeller ship: yaw-rate and speed references -> rudder angle
    and shaft speed, moved at the profile's rudder and shaft rates ([helm], [engine]).

    Yaw rate by PI on the rudder (gains from the model's rudder sensitivity at cruise: a course-
    unstable hull such as a VLCC has no useful steady-turn feed-forward); the yaw-rate limit is
    60 % of the steady rate at full rudder and at most U / (3 L), so the helm always has rudder in hand."""

    def __init__(self, profile: ShipProfile):
        from primitives.helm import steady_rps

        self.p, self.th = profile, profile.params()
        self.uc = profile.cruise_speed_mps
        self._rps: dict[float, float] = {}
        self.steady_rps = steady_rps
        self.n_c = self.rps(self.uc)
        self.max_deg = float(profile.helm.max_rudder_deg)
        one = float(profile.helm.delta_rad(1.0))
        self.ts = profile.sample_time
        # linearised per-sample model in (v, r, heading error) with the rudder in degrees
        J = np.zeros((2, 3))
        eps = np.array([1e-3, 1e-4, 1e-3])
        for j in range(3):
            d = np.zeros(3)
            d[j] = eps[j]
            J[:, j] = (self._inc(*d)[1:] - self._inc(*-d)[1:]) / (2 * eps[j])
        A = np.eye(3)
        A[:2, :2] += J[:, :2]
        A[2, 1] = self.ts
        B = np.array([[J[0, 2] * one], [J[1, 2] * one], [0.0]])
        L = profile.length_m
        Q = np.diag([0.0, (L / self.uc) ** 2 / np.radians(1.0) ** 2 * 0.1, 1.0 / np.radians(1.0) ** 2])
        R = np.array([[1.0 / 2.0**2]])
        P = solve_discrete_are(A, B, Q, R)
        self.K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)[0]  # rudder deg = -K x (LQR autopilot)
        full = np.tile([float(profile.helm.delta_rad(self.max_deg)), self.n_c], (int(900 / self.ts), 1))
        r_full = abs(float(simulate(profile, full, nu0=(self.uc, 0.0, 0.0)).nu[0, -1, 2]))
        self.r_lim = min(0.6 * r_full, self.uc / (3.0 * profile.length_m))  # turns of radius >= 3 L

    def _inc(self, v: float, r: float, delta: float) -> np.ndarray:
        sig = model_signals(self.p, np.array([self.uc, v, r]), np.array(0.0), {"delta": delta, "n": self.n_c})
        return np.array([float(np.asarray(x)) for x in self.p.model.increments(sig, self.th)])

    def rps(self, u: float) -> float:
        key = round(u, 2)
        if key not in self._rps:
            self._rps[key] = float(self.steady_rps(self.p, max(key, 0.0)))
        return self._rps[key]

    def command(self, nu: np.ndarray, u_ref: float, r_ref: float, err: float) -> tuple[float, float]:
        """(rudder degrees, rev/s) ordered for the references; the heading error is limited so
        that the autopilot turns at about ``r_lim``."""
        e = _clamp(err, -_DEG8, _DEG8)
        rudder = -float(self.K @ np.array([nu[1], nu[2] - r_ref, -e]))
        lo, hi = self.p.engine.rps_limits
        n = self.rps(u_ref) + 0.5 * self.n_c * (u_ref - nu[0]) / max(self.uc, 1e-6)
        return _clamp(rudder, -self.max_deg, self.max_deg), _clamp(n, lo, hi)

    def loop(self, policy, n_max: int, nu0) -> np.ndarray:
        """Run ``policy(k, nu, psi, memo) -> (rudder_deg, rps, 0) or None``; inputs (N, 2) out."""
        nu, psi, memo = np.array(nu0, float), 0.0, {}
        rud, shaft = 0.0, self.rps(float(nu[0]))
        dr = self.p.helm.rudder_rate_deg_s * self.ts
        dn = np.inf if self.p.engine.rps_rate is None else self.p.engine.rps_rate * self.ts
        rows = []
        for k in range(n_max):
            c = policy(k, nu, psi, memo)
            if c is None:
                break
            rud += min(max(c[0] - rud, -dr), dr)
            shaft += min(max(c[1] - shaft, -dn), dn)
            row = (float(self.p.helm.delta_rad(rud)), shaft)
            nu, psi = mv.model_step(self.p, self.th, nu, psi, {"delta": row[0], "n": row[1]})
            rows.append(row)
        return np.array(rows, float).reshape(-1, 2)


class _Helm:
    """Closed-loop phases on the nominal model: stop, turn to a heading, settle on the lattice.
    Velocity references become generalized forces (allocated to azimuths) or, for a
    rudder/propeller ship, helm and engine orders (:class:`_Rudder`); sway is then not
    commanded: cross-track errors are steered out by line of sight."""

    def __init__(self, profile: ShipProfile, res: float, n_head: int):
        self.p, self.res, self.K = profile, res, n_head
        self.table = heading_table(n_head)
        self.uc = profile.cruise_speed_mps
        self.ts = profile.sample_time
        self._ff: dict[tuple[float, float, float], np.ndarray] = {}
        self.rudder = _Rudder(profile) if profile.actuator == "rudder_propeller" else None
        if self.rudder is not None:
            self.r_lim = self.rudder.r_lim
            return
        self.r_lim = self.uc / (1.5 * profile.length_m)
        b = _gains(profile)
        self.k = 0.3 / np.where(np.abs(b) > 1e-12, b, 1e-12)
        self.fmax = np.array([
            1.5 * abs(steady_forces(profile, self.uc, 0, 0)[0]),
            2.0 * abs(steady_forces(profile, 0.0, 0.5, 0)[1]),
            2.0 * abs(steady_forces(profile, self.uc, 0, self.uc / (1.5 * profile.length_m))[2]),
        ])
        self.k_f, self.fmax_f = self.k.tolist(), self.fmax.tolist()

    def feedforward(self, u: float, v: float, r: float) -> np.ndarray:
        """Steady forces, memoised on a fine grid (the P terms absorb the rounding)."""
        key = (round(u, 2), round(v, 3), round(r, 4))
        ff = self._ff.get(key)
        if ff is None:
            ff = self._ff[key] = np.array(steady_forces(self.p, *key))
        return ff

    def forces(self, nu: np.ndarray, u_ref: float, v_ref: float, r_ref: float, err: float = 0.0) -> tuple[float, float, float]:
        """Generalized forces, or (rudder deg, rev/s, 0) for a rudder ship (``v_ref`` ignored;
        ``err``: heading error, rad, that its autopilot steers out)."""
        if self.rudder is not None:
            return (*self.rudder.command(nu, u_ref, r_ref, err), 0.0)
        ff = self.feedforward(u_ref, v_ref, r_ref).tolist()
        out = []
        # per DOF on floats (a closed-loop step's hot path): the elementwise arithmetic of
        # clip(ff + k (ref - nu), -lim, lim) with lim = max(fmax, 1.2 |ff|), the same bits
        for f0, k, ref, x, fmax in zip(ff, self.k_f, (u_ref, v_ref, r_ref), nu.tolist(), self.fmax_f):
            lim = max(fmax, 1.2 * abs(f0))  # a steady state the ship can hold is always reachable
            out.append(min(max(f0 + k * (ref - x), -lim), lim))
        return float(out[0]), float(out[1]), float(out[2])

    def run(self, nu0, pose0, phases: list[tuple[str, float]], n_max: int = 3000) -> np.ndarray:
        """Phases: ("run", metres), ("stop", 0), ("turn", target psi), ("settle", 0.0 | heading index), ("hold", (u, v, r,
        seconds)), ("track", (waypoints [(x, y), ...], lookahead m)). Returns the inputs (N, m)."""
        state = {"pos": np.array(pose0[:2], float), "i": 0, "k0": 0}
        psi0 = float(pose0[2])
        res, uc = self.res, self.uc
        r_lim = self.r_lim
        rudder = self.rudder is not None

        def policy(k, nu, psi_rel, memo):
            psi = psi0 + psi_rel
            if state["i"] >= len(phases):
                return None
            kind, arg = phases[state["i"]]
            pos = state["pos"]
            if kind == "run":  # straight on at cruise speed for ``arg`` metres
                memo["run"] = memo.get("run", 0.0)
                if memo["run"] >= arg - 0.5 * uc * self.ts:
                    memo.pop("course", None)
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                memo["run"] += self.ts * nu[0]
                memo.setdefault("course", psi)
                f = self.forces(nu, uc, 0.0, 0.0, _wrap(memo["course"] - psi))
            elif kind == "hold":  # reach the velocity (u, v, r), keep the course, then hold it for ``secs``
                u_t, v_t, r_t, secs = arg[:4]
                if len(arg) > 4:  # the course to keep (default: the course at the start of the phase)
                    memo.setdefault("course", psi + _wrap(arg[4] - psi))
                err = np.abs(np.array([u_t, v_t, r_t]) - nu) * (1.0, 1.0, self.p.length_m)
                tol = np.array([0.02, 0.01, 0.005]) if rudder else 0.02
                if "held" not in memo and np.all(err < tol):
                    memo["held"] = k
                if "held" in memo and (k - memo["held"]) * self.ts >= secs:
                    state["i"] += 1
                    return None
                memo.setdefault("course", psi)
                r_fb = 0.0 if r_t else _clamp(0.1 * _wrap(memo["course"] - psi), -r_lim, r_lim)
                f = self.forces(nu, u_t, v_t, r_t + r_fb, _wrap(memo["course"] - psi))
            elif kind == "track":  # line-of-sight guidance along waypoints, stop abreast the last one
                wps, lookahead = arg
                leg = memo.setdefault("leg", 0)
                a, b = np.asarray(wps[leg], float), np.asarray(wps[leg + 1], float)
                d = (b - a) / max(np.hypot(*(b - a)), 1e-9)
                along = float((pos - a) @ d)
                cross = float((pos - a) @ np.array([-d[1], d[0]]))
                last = leg + 2 == len(wps)
                remaining = float(np.hypot(*(b - a))) - along
                if last and remaining <= 0.5 * uc * self.ts:
                    state["i"] += 1
                    return None
                if not last and remaining <= lookahead:
                    memo["leg"] = leg + 1
                    return policy(k, nu, psi_rel, memo)
                want = float(np.arctan2(d[1], d[0]) - np.arctan2(cross, lookahead))
                r_ref = _clamp(1.5 * _wrap(want - psi) * r_lim / _DEG20, -r_lim, r_lim)
                f = self.forces(nu, uc, 0.0, r_ref, _wrap(want - psi))
            elif kind == "stop":
                if abs(nu[0]) < 0.02 and abs(nu[1]) < 0.02:
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                f = self.forces(nu, 0.0, 0.0, 0.0)
            elif kind == "turn":
                err = _wrap(arg - psi)
                moving = abs(nu[0]) > 0.5 * uc
                if abs(err) < _DEG05 and abs(nu[2]) < 0.002:
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                rl = r_lim if moving else 0.3 * r_lim
                r_ref = _clamp(1.5 * err * rl / _DEG20, -rl, rl)
                f = self.forces(nu, uc if moving else 0.0, 0.0, r_ref, err)
            else:  # settle on a lattice point (``arg``: (x, y, psi) of a given one) at cruise speed
                given = isinstance(arg, tuple)
                # an int: the lattice heading index to settle on (a turn must not settle on the heading its overshoot nears)
                h_to = arg if isinstance(arg, int) else nearest_heading(psi, self.table)
                target = psi + _wrap((arg[2] if given else self.table[h_to]) - psi)
                d = np.array([np.cos(target), np.sin(target)])
                n = np.array([-np.sin(target), np.cos(target)])
                if given:
                    near = np.array([arg[:2]], float)
                    along_line = near[0]
                else:
                    near = (np.round(pos / res) + _NEIGHBOURS) * res
                    along_line = near[np.argmin(np.abs((near - pos) @ n))]
                c_err = float((along_line - pos) @ n)  # to starboard
                err = _wrap(target - psi)
                if rudder:  # no sway control: steer the cross-track error out by line of sight
                    L = self.p.length_m
                    # tight on yaw rate and sway: a course-unstable hull amplifies them over a long open-loop manoeuvre
                    settled = abs(err) < _DEG02 and abs(nu[2]) * L < 0.005 and abs(c_err) < 0.01 * L \
                        and abs(nu[1]) < 0.01 and abs(nu[0] - uc) < 0.05
                else:
                    settled = abs(err) < _DEG005 and abs(nu[2]) < 5e-4 and abs(c_err) < 0.3 and abs(nu[1]) < 0.01 \
                        and abs(nu[0] - uc) < 0.01
                dist = float(np.min(np.hypot(*(near - pos).T)))
                if given and float((near[0] - pos) @ d) <= 0.5 * uc * self.ts:  # abreast the given point: stop
                    state["i"] += 1
                    return None
                if settled and dist <= 0.5 * uc * self.ts + 1e-6:
                    state["i"] += 1
                    return None
                if rudder:
                    los = err + float(np.arctan2(c_err, 3.0 * self.p.length_m))
                    r_ref = _clamp(1.5 * los * r_lim / _DEG20, -r_lim, r_lim)
                    f = self.forces(nu, uc, 0.0, r_ref, los)
                else:
                    r_ref = _clamp(0.1 * err, -r_lim, r_lim)
                    v_ref = _clamp(0.12 * c_err, -0.6, 0.6)
                    f = self.forces(nu, uc, v_ref, r_ref)
            c, s = np.cos(psi), np.sin(psi)
            state["pos"] = pos + self.ts * np.array([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]])
            return f

        if rudder:
            return self.rudder.loop(policy, n_max, nu0)
        forces, _ = mv.closed_loop(self.p, policy, n_max, nu0)
        return self.p.allocate(*forces.T) if len(forces) else np.zeros((0, len(self.p.inputs)))


_HELMS: dict[tuple[int, float, int], tuple[ShipProfile, _Helm]] = {}


def helm_for(profile: ShipProfile, res: float, n_head: int) -> _Helm:
    """The helm of a profile, built once (a rudder ship's autopilot design simulates and solves a
    Riccati equation); the cache holds the profile itself so an id is never reused wrongly."""
    key = (id(profile), float(res), int(n_head))
    hit = _HELMS.get(key)
    if hit is None or hit[0] is not profile:
        if len(_HELMS) > 32:
            _HELMS.clear()
        hit = _HELMS[key] = (profile, _Helm(profile, res, n_head))
    return hit[1]


def _assemble(profile: ShipProfile, name: str, desc: str, kind: str, head_inputs: np.ndarray | None, nu0,
              tail: np.ndarray, commands: list[str], splits: list[int]) -> Primitive:
    parts = [] if head_inputs is None else [head_inputs]
    if len(tail):
        parts.append(tail)
    inputs = np.vstack(parts)
    res = simulate(profile, inputs, nu0=nu0)
    return Primitive(name, desc, profile, inputs, res.nu[0], res.eta[0], splits, kind, commands)


def run_in_seconds(profile: ShipProfile, run_in_s: float | None = None) -> float:
    """Time on steady course and speed before an execute point: ``run_in_s`` or, by default, the
    longer of one minute and two ship lengths at cruise speed. ITTC 7.5-04-02-01 and IMO
    MSC.137(76) ask for a steady approach at the test speed without fixing its length; this
    default is our choice (the nominal model settles well within it)."""
    if run_in_s is not None:
        return float(run_in_s)
    return float(max(60.0, 2.0 * profile.length_m / max(profile.cruise_speed_mps, 1e-6)))


def run_in_inputs(prim: Primitive, res: float, n_head: int, run_in_s: float) -> np.ndarray:
    """Inputs of the run-in: from the transit state to the primitive's entry velocity (closed
    loop on the nominal model), then held steady for ``run_in_s`` seconds. Body-frame only, so
    the same for every start heading."""
    helm = helm_for(prim.profile, res, n_head)
    u0, v0, r0 = (float(x) for x in prim.nu0)
    nu_t = np.array([helm.uc, 0.0, 0.0])
    near = np.all(np.abs(np.array([u0, v0, r0]) - nu_t) * (1.0, 1.0, prim.profile.length_m) < 0.02)
    m = prim.inputs.shape[1]
    reach = np.zeros((0, m)) if near else helm.run(nu_t, (0.0, 0.0, 0.0), [("hold", (u0, v0, r0, 0.0))], n_max=20000)
    n_hold = int(round(run_in_s / helm.ts))
    if helm.rudder is not None:  # steady: rudder for the entry yaw rate, shaft for the entry speed
        row = np.array([0.0, helm.rudder.rps(u0)])  # rudder ships start their manoeuvres steady on a straight course
    else:
        row = prim.profile.allocate(*(np.array([x]) for x in helm.feedforward(u0, v0, r0)))[0]
    return np.vstack([reach, np.tile(row, (n_hold, 1))]) if n_hold + len(reach) else np.zeros((0, m))


def with_run_in(prim: Primitive, res: float, n_head: int, psi0: float, run_in: np.ndarray, head_sim=None) -> tuple[Primitive, int]:
    """Run-in + primitive + settling leg, started from transit at lattice heading ``psi0``.

    ``run_in`` (:func:`run_in_inputs`) brings the ship to the primitive's entry velocity and holds
    it on a steady course; the primitive's inputs then start at the execute point. Returns the
    whole move (track in the start frame) and the run-in's samples. ``head_sim``: the simulation
    of run-in + primitive from transit (the same for every start heading), if already done."""
    helm = helm_for(prim.profile, res, n_head)
    nu_t = np.array([helm.uc, 0.0, 0.0])
    head = np.vstack([run_in, prim.inputs])
    sim = head_sim if head_sim is not None else simulate(prim.profile, head, nu0=nu_t)
    x, y, p = sim.eta[0, -1]
    c, s = np.cos(psi0), np.sin(psi0)
    # settle on the lattice heading nearest the primitive's end heading, fixed when it ends: a hull still
    # turning (a VLCC after a zig-zag) would otherwise drift onto the next heading while it settles
    h_end = nearest_heading(psi0 + p, helm.table)
    tail = helm.run(sim.nu[0, -1], (c * x - s * y, s * x + c * y, psi0 + p), [("settle", int(h_end))])
    n_r = len(run_in)
    cmds = list(prim.commands) + ([f"then steady at {helm.uc:.1f} m/s on the nearest lattice course for "
                                   f"{len(tail) * helm.ts:.0f} s"] if len(tail) else [])
    if len(tail):  # the tail continues the head's simulation: no need to simulate the head again
        rest = simulate(prim.profile, tail, nu0=sim.nu[0, -1], eta0=sim.eta[0, -1])
        nu, eta = np.vstack([sim.nu[0], rest.nu[0, 1:]]), np.vstack([sim.eta[0], rest.eta[0, 1:]])
    else:
        nu, eta = sim.nu[0], sim.eta[0]
    whole = Primitive(prim.name, prim.description, prim.profile, np.vstack([head, tail]) if len(tail) else head, nu, eta,
                      [n_r + k for k in prim.split_points], prim.kind, cmds)
    return whole, n_r


def classes(n_head: int) -> np.ndarray:
    """Start headings of the heading classes; the others follow by quarter turns."""
    return heading_table(n_head)[: n_head // 4]


def lattice_basic_moves(profile: ShipProfile, res: float, n_head: int, spot_turns: bool = True) -> list[list[Primitive]]:
    """Basic moves (8.7) at cruise speed, one primitive per heading class: a straight run to the
    next lattice point ahead, turns at speed to the next lattice heading (90 deg with 4
    headings) and, optionally, turns on the spot by 90 deg (stop, turn, speed up again)."""
    helm = helm_for(profile, res, n_head)
    uc = helm.uc
    nu0 = (uc, 0.0, 0.0)
    table = heading_table(n_head)
    cls = classes(n_head)
    vec = {0.0: (1, 0), float(np.pi / 4): (1, 1), float(np.arctan2(1, 2)): (2, 1), float(np.arctan2(2, 1)): (1, 2)}
    out: list[list[Primitive]] = []
    straights = []
    for psi0 in cls:
        a, b = vec[min(vec, key=lambda k: abs(k - psi0))]
        length = res * float(np.hypot(a, b))
        g = mv.straight(profile, length) if helm.rudder is None else helm_straight(profile, length)
        ins = g.inputs if g.inputs is not None else profile.allocate(*g.forces.T)
        straights.append(_assemble(profile, "straight", f"straight run {length:.0f} m", "basic", None, nu0, ins, g.commands, []))
    out.append(straights)
    step = n_head // 4 if n_head == 4 else 1
    for side, sgn in (("s", 1), ("p", -1)):
        word = "starboard" if sgn > 0 else "port"
        per = []
        for ci, psi0 in enumerate(cls):
            h_to = (ci + sgn * step) % n_head
            target = psi0 + _wrap(float(table[h_to]) - psi0)
            dpsi = np.degrees(target - psi0)
            phases = [("turn", target), ("settle", int(h_to))]
            if n_head == 4:  # a short straight run first makes the turn end on a lattice line
                f0 = helm.run(nu0, (0.0, 0.0, 0.0), [("turn", target)])
                x_end = simulate(profile, f0, nu0=nu0).eta[0, -1, 0] if len(f0) else 0.0
                phases.insert(0, ("run", float((-x_end) % res)))
            f = helm.run(nu0, (0.0, 0.0, psi0), phases)
            per.append(_assemble(profile, f"turn_{side}", f"{abs(dpsi):.0f} deg turn to {word}", "basic", None, nu0, f,
                                 [f"at {uc:.1f} m/s turn {abs(dpsi):.0f} deg to {word}, steady on the new course"], []))
        out.append(per)
    if helm.rudder is not None:  # a rudder ship cannot turn on the spot: it reverses course by a round turn at speed
        for side, sgn in (("s", 1.0), ("p", -1.0)):
            word = "starboard" if sgn > 0 else "port"
            per = []
            for ci, psi0 in enumerate(cls):
                # just short of 180 deg so that the helm turns to the side asked for
                f = helm.run(nu0, (0.0, 0.0, psi0), [("turn", psi0 + sgn * (np.pi - 1e-6)), ("settle", int(ci + n_head // 2))])
                per.append(_assemble(profile, f"round_turn_{side}", f"turn 180 deg to {word} at speed onto the reciprocal course",
                                     "basic", None, nu0, f, [f"at {uc:.1f} m/s turn 180 deg to {word}, steady on the reciprocal course"], []))
            out.append(per)
    elif spot_turns:  # stop, turn on the spot, speed up (azimuth and generalized-force ships)
        for side, sgn in (("s", 1.0), ("p", -1.0)):
            word = "starboard" if sgn > 0 else "port"
            per = []
            for psi0 in cls:
                f = helm.run(nu0, (0.0, 0.0, psi0), [("stop", 0.0), ("turn", psi0 + sgn * np.pi / 2), ("settle", 0.0)])
                per.append(_assemble(profile, f"spot_turn_{side}", f"stop, turn on the spot 90 deg to {word}, speed up", "basic",
                                     None, nu0, f, ["stop the ship", f"turn on the spot 90 deg to {word}",
                                                    f"accelerate to {uc:.1f} m/s on the new course"], []))
            out.append(per)
    return out


def place(prims: list[Primitive], res: float, n_head: int, counter: int, cost: float, source: str = "",
          run_in: tuple[int, ...] = (), core: tuple[int, ...] = ()) -> Move:
    """Snap the end poses of a move (one primitive per heading class) to the lattice for every
    start heading: cells moved, heading steps and the snapping error."""
    table = heading_table(n_head)
    nc = n_head // 4
    dcell = np.zeros((n_head, 2), int)
    dh = np.zeros(n_head, int)
    snap = np.zeros(n_head)
    herr = 0.0
    for h in range(n_head):
        pr = prims[h % nc]
        dx, dy, dpsi = pr.end_pose
        psi = table[h]
        c, s = np.cos(psi), np.sin(psi)
        w = np.array([c * dx - s * dy, s * dx + c * dy])
        cell = np.round(w / res).astype(int)
        dcell[h] = cell
        snap[h] = float(np.hypot(*(w - cell * res)))
        h2 = nearest_heading(psi + dpsi, table)
        dh[h] = (h2 - h) % n_head
        herr = max(herr, abs(_wrap(psi + dpsi - table[h2])))
    first = prims[0]
    return Move(first.name, first.kind, prims, counter, cost, dcell, dh, snap, herr, source, run_in, core)


def transit_mismatch(prim: Primitive) -> float:
    """Largest velocity mismatch (m/s or rad/s x L) between the primitive's ends and transit."""
    uc = prim.profile.cruise_speed_mps
    ref = np.array([uc, 0.0, 0.0])
    scale = np.array([1.0, 1.0, prim.profile.length_m])
    return float(max(np.max(np.abs(prim.nu[0] - ref) * scale), np.max(np.abs(prim.nu[-1] - ref) * scale)))
