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

from primitives import maneuvers as mv
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

    def prim(self, h: int) -> Primitive:
        return self.prims[h % len(self.prims)]

    def run_in_samples(self, h: int) -> int:
        return self.run_in[h % len(self.run_in)] if self.run_in else 0


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


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


class _Helm:
    """Closed-loop phases on the nominal model: stop, turn to a heading, settle on the lattice."""

    def __init__(self, profile: ShipProfile, res: float, n_head: int):
        self.p, self.res, self.K = profile, res, n_head
        self.table = heading_table(n_head)
        self.uc = profile.cruise_speed_mps
        self.ts = profile.sample_time
        self._ff: dict[tuple[float, float, float], np.ndarray] = {}
        b = _gains(profile)
        self.k = 0.3 / np.where(np.abs(b) > 1e-12, b, 1e-12)
        self.fmax = np.array([
            1.5 * abs(steady_forces(profile, self.uc, 0, 0)[0]),
            2.0 * abs(steady_forces(profile, 0.0, 0.5, 0)[1]),
            2.0 * abs(steady_forces(profile, self.uc, 0, self.uc / (1.5 * profile.length_m))[2]),
        ])

    def feedforward(self, u: float, v: float, r: float) -> np.ndarray:
        """Steady forces, memoised on a fine grid (the P terms absorb the rounding)."""
        key = (round(u, 2), round(v, 3), round(r, 4))
        ff = self._ff.get(key)
        if ff is None:
            ff = self._ff[key] = np.array(steady_forces(self.p, *key))
        return ff

    def forces(self, nu: np.ndarray, u_ref: float, v_ref: float, r_ref: float) -> tuple[float, float, float]:
        ff = self.feedforward(u_ref, v_ref, r_ref)
        f = ff + self.k * (np.array([u_ref, v_ref, r_ref]) - nu)
        lim = np.maximum(self.fmax, 1.2 * np.abs(ff))  # a steady state the ship can hold is always reachable
        f = np.clip(f, -lim, lim)
        return float(f[0]), float(f[1]), float(f[2])

    def run(self, nu0, pose0, phases: list[tuple[str, float]], n_max: int = 3000) -> np.ndarray:
        """Phases: ("run", metres), ("stop", 0), ("turn", target psi), ("settle", 0), ("hold", (u, v, r,
        seconds)), ("track", (waypoints [(x, y), ...], lookahead m)). Returns forces (N, 3)."""
        state = {"pos": np.array(pose0[:2], float), "i": 0, "k0": 0}
        psi0 = float(pose0[2])
        res, uc = self.res, self.uc
        r_lim = uc / (1.5 * self.p.length_m)

        def policy(k, nu, psi_rel, memo):
            psi = psi0 + psi_rel
            if state["i"] >= len(phases):
                return None
            kind, arg = phases[state["i"]]
            pos = state["pos"]
            if kind == "run":  # straight on at cruise speed for ``arg`` metres
                memo["run"] = memo.get("run", 0.0)
                if memo["run"] >= arg - 0.5 * uc * self.ts:
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                memo["run"] += self.ts * nu[0]
                f = self.forces(nu, uc, 0.0, 0.0)
            elif kind == "hold":  # reach the velocity (u, v, r), keep the course, then hold it for ``secs``
                u_t, v_t, r_t, secs = arg
                err = np.abs(np.array([u_t, v_t, r_t]) - nu) * (1.0, 1.0, self.p.length_m)
                if "held" not in memo and np.all(err < 0.02):
                    memo["held"] = k
                if "held" in memo and (k - memo["held"]) * self.ts >= secs:
                    state["i"] += 1
                    return None
                memo.setdefault("course", psi)
                r_fb = 0.0 if r_t else float(np.clip(0.1 * _wrap(memo["course"] - psi), -r_lim, r_lim))
                f = self.forces(nu, u_t, v_t, r_t + r_fb)
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
                r_ref = float(np.clip(1.5 * _wrap(want - psi) * r_lim / np.radians(20), -r_lim, r_lim))
                f = self.forces(nu, uc, 0.0, r_ref)
            elif kind == "stop":
                if abs(nu[0]) < 0.02 and abs(nu[1]) < 0.02:
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                f = self.forces(nu, 0.0, 0.0, 0.0)
            elif kind == "turn":
                err = _wrap(arg - psi)
                moving = abs(nu[0]) > 0.5 * uc
                if abs(err) < np.radians(0.5) and abs(nu[2]) < 0.002:
                    state["i"] += 1
                    return policy(k, nu, psi_rel, memo)
                rl = r_lim if moving else 0.3 * r_lim
                r_ref = float(np.clip(1.5 * err * rl / np.radians(20), -rl, rl))
                f = self.forces(nu, uc if moving else 0.0, 0.0, r_ref)
            else:  # settle on a lattice point at cruise speed and a lattice heading
                target = psi + _wrap(self.table[nearest_heading(psi, self.table)] - psi)
                d = np.array([np.cos(target), np.sin(target)])
                n = np.array([-np.sin(target), np.cos(target)])
                pts = np.round(pos / res)
                near = np.array([pts + [a, b] for a in (-1, 0, 1) for b in (-1, 0, 1)]) * res
                along_line = near[np.argmin(np.abs((near - pos) @ n))]
                c_err = float((along_line - pos) @ n)  # to starboard
                err = _wrap(target - psi)
                settled = abs(err) < np.radians(0.05) and abs(nu[2]) < 5e-4 and abs(c_err) < 0.3 and abs(nu[1]) < 0.01 \
                    and abs(nu[0] - uc) < 0.01
                dist = float(np.min(np.hypot(*(near - pos).T)))
                if settled and dist <= 0.5 * uc * self.ts + 1e-6:
                    state["i"] += 1
                    return None
                r_ref = float(np.clip(0.1 * err, -r_lim, r_lim))
                v_ref = float(np.clip(0.12 * c_err, -0.6, 0.6))
                f = self.forces(nu, uc, v_ref, r_ref)
                _ = d
            c, s = np.cos(psi), np.sin(psi)
            state["pos"] = pos + self.ts * np.array([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]])
            return f

        forces, _ = mv.closed_loop(self.p, policy, n_max, nu0)
        return forces


def _assemble(profile: ShipProfile, name: str, desc: str, kind: str, head_inputs: np.ndarray | None, nu0,
              forces: np.ndarray, commands: list[str], splits: list[int]) -> Primitive:
    parts = [] if head_inputs is None else [head_inputs]
    if len(forces):
        parts.append(profile.allocate(forces[:, 0], forces[:, 1], forces[:, 2]))
    inputs = np.vstack(parts)
    res = simulate(profile, inputs, nu0=nu0)
    return Primitive(name, desc, profile, inputs, res.nu[0], res.eta[0], splits, kind, commands)


def settle(prim: Primitive, res: float, n_head: int, psi0: float = 0.0) -> Primitive:
    """The primitive, started at lattice heading ``psi0``, followed by a settling leg that ends on
    a lattice point at a lattice heading (see module doc). Track stays in the start frame."""
    helm = _Helm(prim.profile, res, n_head)
    c, s = np.cos(psi0), np.sin(psi0)
    x, y, p = prim.track[-1]
    tail = helm.run(prim.nu[-1], (c * x - s * y, s * x + c * y, psi0 + p), [("settle", 0.0)])
    cmds = list(prim.commands) + ([f"then steady at {helm.uc:.1f} m/s on the nearest lattice course for "
                                   f"{len(tail) * helm.ts:.0f} s"] if len(tail) else [])
    return _assemble(prim.profile, prim.name, prim.description, prim.kind, prim.inputs, prim.nu0, tail, cmds,
                     list(prim.split_points))


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
    helm = _Helm(prim.profile, res, n_head)
    u0, v0, r0 = (float(x) for x in prim.nu0)
    nu_t = np.array([helm.uc, 0.0, 0.0])
    near = np.all(np.abs(np.array([u0, v0, r0]) - nu_t) * (1.0, 1.0, prim.profile.length_m) < 0.02)
    f = np.zeros((0, 3)) if near else helm.run(nu_t, (0.0, 0.0, 0.0), [("hold", (u0, v0, r0, 0.0))], n_max=600)
    n_hold = int(round(run_in_s / helm.ts))
    steady = np.tile(helm.feedforward(u0, v0, r0), (n_hold, 1))
    f = np.vstack([f, steady])
    return prim.profile.allocate(*f.T) if len(f) else np.zeros((0, prim.inputs.shape[1]))


def with_run_in(prim: Primitive, res: float, n_head: int, psi0: float, run_in: np.ndarray) -> tuple[Primitive, int]:
    """Run-in + primitive + settling leg, started from transit at lattice heading ``psi0``.

    ``run_in`` (:func:`run_in_inputs`) brings the ship to the primitive's entry velocity and holds
    it on a steady course; the primitive's inputs then start at the execute point. Returns the
    whole move (track in the start frame) and the run-in's samples."""
    helm = _Helm(prim.profile, res, n_head)
    nu_t = np.array([helm.uc, 0.0, 0.0])
    head = np.vstack([run_in, prim.inputs])
    sim = simulate(prim.profile, head, nu0=nu_t)
    x, y, p = sim.eta[0, -1]
    c, s = np.cos(psi0), np.sin(psi0)
    tail = helm.run(sim.nu[0, -1], (c * x - s * y, s * x + c * y, psi0 + p), [("settle", 0.0)])
    n_r = len(run_in)
    cmds = list(prim.commands) + ([f"then steady at {helm.uc:.1f} m/s on the nearest lattice course for "
                                   f"{len(tail) * helm.ts:.0f} s"] if len(tail) else [])
    whole = _assemble(prim.profile, prim.name, prim.description, prim.kind, head, nu_t, tail, cmds,
                      [n_r + k for k in prim.split_points])
    return whole, n_r


def classes(n_head: int) -> np.ndarray:
    """Start headings of the heading classes; the others follow by quarter turns."""
    return heading_table(n_head)[: n_head // 4]


def lattice_basic_moves(profile: ShipProfile, res: float, n_head: int, spot_turns: bool = True) -> list[list[Primitive]]:
    """Basic moves (8.7) at cruise speed, one primitive per heading class: a straight run to the
    next lattice point ahead, turns at speed to the next lattice heading (90 deg with 4
    headings) and, optionally, turns on the spot by 90 deg (stop, turn, speed up again)."""
    helm = _Helm(profile, res, n_head)
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
        g = mv.straight(profile, length)
        straights.append(_assemble(profile, "straight", f"straight run {length:.0f} m", "basic", None, nu0, g.forces, g.commands, []))
    out.append(straights)
    step = n_head // 4 if n_head == 4 else 1
    for side, sgn in (("s", 1), ("p", -1)):
        word = "starboard" if sgn > 0 else "port"
        per = []
        for ci, psi0 in enumerate(cls):
            target = float(table[(ci + sgn * step) % n_head])
            target = psi0 + _wrap(target - psi0)
            dpsi = np.degrees(target - psi0)
            phases = [("turn", target), ("settle", 0.0)]
            if n_head == 4:  # a short straight run first makes the turn end on a lattice line
                f0 = helm.run(nu0, (0.0, 0.0, 0.0), [("turn", target)])
                x_end = simulate(profile, profile.allocate(*f0.T), nu0=nu0).eta[0, -1, 0] if len(f0) else 0.0
                phases.insert(0, ("run", float((-x_end) % res)))
            f = helm.run(nu0, (0.0, 0.0, psi0), phases)
            per.append(_assemble(profile, f"turn_{side}", f"{abs(dpsi):.0f} deg turn to {word}", "basic", None, nu0, f,
                                 [f"at {uc:.1f} m/s turn {abs(dpsi):.0f} deg to {word}, steady on the new course"], []))
        out.append(per)
    if spot_turns:
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
          run_in: tuple[int, ...] = ()) -> Move:
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
    return Move(first.name, first.kind, prims, counter, cost, dcell, dh, snap, herr, source, run_in)


def transit_mismatch(prim: Primitive) -> float:
    """Largest velocity mismatch (m/s or rad/s x L) between the primitive's ends and transit."""
    uc = prim.profile.cruise_speed_mps
    ref = np.array([uc, 0.0, 0.0])
    scale = np.array([1.0, 1.0, prim.profile.length_m])
    return float(max(np.max(np.abs(prim.nu[0] - ref) * scale), np.max(np.abs(prim.nu[-1] - ref) * scale)))
