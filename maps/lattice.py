"""The motion set of the state lattice (Ljungberg 2022, section 8.2, (8.3)-(8.8)).

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

from maps.autopilot import helm_for
from maps.headings import heading_table, nearest_heading
from maps.headings import wrap as _wrap
from maps.planoptions import SETTLE_PHASES
from primitives import maneuvers as mv
from primitives.helm import straight as helm_straight
from primitives.library import KNOT, Primitive
from primitives.ship import ShipProfile
from primitives.simulate import simulate
from primitives.stability import require_stable

__all__ = [
    "SETTLE_PHASES",
    "Move",
    "heading_table",
    "nearest_heading",
    "helm_for",
    "run_in_seconds",
    "run_in_inputs",
    "with_run_in",
    "classes",
    "lattice_basic_moves",
    "place",
    "transit_mismatch",
]


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


def _assemble(
    profile: ShipProfile,
    name: str,
    desc: str,
    kind: str,
    head_inputs: np.ndarray | None,
    nu0,
    tail: np.ndarray,
    commands: list[str],
    splits: list[int],
) -> Primitive:
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


def with_run_in(
    prim: Primitive, res: float, n_head: int, psi0: float, run_in: np.ndarray, head_sim=None, settle: str = "settle"
) -> tuple[Primitive, int]:
    """Run-in + primitive + settling leg, started from transit at lattice heading ``psi0``.

    ``run_in`` (:func:`run_in_inputs`) brings the ship to the primitive's entry velocity and holds
    it on a steady course; the primitive's inputs then start at the execute point. Returns the
    whole move (track in the start frame) and the run-in's samples. ``head_sim``: the simulation
    of run-in + primitive from transit (the same for every start heading), if already done.
    ``settle``: the helm's settling phase (a value of :data:`SETTLE_PHASES`)."""
    helm = helm_for(prim.profile, res, n_head)
    nu_t = np.array([helm.uc, 0.0, 0.0])
    head = np.vstack([run_in, prim.inputs])
    sim = head_sim if head_sim is not None else simulate(prim.profile, head, nu0=nu_t)
    x, y, p = sim.eta[0, -1]
    c, s = np.cos(psi0), np.sin(psi0)
    # settle on the lattice heading nearest the primitive's end heading, fixed when it ends: a hull still
    # turning (a VLCC after a zig-zag) would otherwise drift onto the next heading while it settles
    h_end = nearest_heading(psi0 + p, helm.table)
    tail = helm.run(sim.nu[0, -1], (c * x - s * y, s * x + c * y, psi0 + p), [(settle, int(h_end))])
    n_r = len(run_in)
    cmds = list(prim.commands) + (
        [f"then steady at {helm.uc / KNOT:.1f} kn on the nearest lattice course for {len(tail) * helm.ts:.0f} s"]
        if len(tail)
        else []
    )
    if len(tail):  # the tail continues the head's simulation: no need to simulate the head again
        rest = simulate(prim.profile, tail, nu0=sim.nu[0, -1], eta0=sim.eta[0, -1])
        nu, eta = np.vstack([sim.nu[0], rest.nu[0, 1:]]), np.vstack([sim.eta[0], rest.eta[0, 1:]])
    else:
        nu, eta = sim.nu[0], sim.eta[0]
    whole = Primitive(
        prim.name,
        prim.description,
        prim.profile,
        np.vstack([head, tail]) if len(tail) else head,
        nu,
        eta,
        [n_r + k for k in prim.split_points],
        prim.kind,
        cmds,
    )
    return whole, n_r


def classes(n_head: int) -> np.ndarray:
    """Start headings of the heading classes; the others follow by quarter turns."""
    return heading_table(n_head)[: n_head // 4]


def lattice_basic_moves(
    profile: ShipProfile, res: float, n_head: int, spot_turns: bool = True, settle: str = "settle"
) -> list[list[Primitive]]:
    """Basic moves (8.7) at cruise speed, one primitive per heading class: a straight run to the
    next lattice point ahead, turns at speed to the next lattice heading (90 deg with 4
    headings) and, optionally, turns on the spot by 90 deg (stop, turn, speed up again).
    ``settle``: the helm's settling phase that ends the turns (a value of :data:`SETTLE_PHASES`)."""
    require_stable(profile)
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
            phases = [("turn", target), (settle, int(h_to))]
            if n_head == 4:  # a short straight run first makes the turn end on a lattice line
                f0 = helm.run(nu0, (0.0, 0.0, 0.0), [("turn", target)])
                x_end = simulate(profile, f0, nu0=nu0).eta[0, -1, 0] if len(f0) else 0.0
                phases.insert(0, ("run", float((-x_end) % res)))
            f = helm.run(nu0, (0.0, 0.0, psi0), phases)
            per.append(
                _assemble(
                    profile,
                    f"turn_{side}",
                    f"{abs(dpsi):.0f} deg turn to {word}",
                    "basic",
                    None,
                    nu0,
                    f,
                    [f"turn {abs(dpsi):.0f}° to {word} at {uc / KNOT:.1f} kn, steady on the new course"],
                    [],
                )
            )
        out.append(per)
    # a rudder ship cannot turn on the spot, nor can pods aft (they push the stern aside, and a profile fitted
    # at speed has no model at rest): it reverses course by a round turn at speed
    if helm.rudder is not None or helm.arm is not None:
        for side, sgn in (("s", 1.0), ("p", -1.0)):
            word = "starboard" if sgn > 0 else "port"
            per = []
            for ci, psi0 in enumerate(cls):
                # just short of 180 deg so that the helm turns to the side asked for
                f = helm.run(nu0, (0.0, 0.0, psi0), [("turn", psi0 + sgn * (np.pi - 1e-6)), (settle, int(ci + n_head // 2))])
                per.append(
                    _assemble(
                        profile,
                        f"round_turn_{side}",
                        f"turn 180 deg to {word} at speed onto the reciprocal course",
                        "basic",
                        None,
                        nu0,
                        f,
                        [f"turn 180° to {word} at {uc / KNOT:.1f} kn, steady on the reciprocal course"],
                        [],
                    )
                )
            out.append(per)
    elif spot_turns:  # stop, turn on the spot, speed up (azimuth and generalized-force ships)
        for side, sgn in (("s", 1.0), ("p", -1.0)):
            word = "starboard" if sgn > 0 else "port"
            per = []
            for psi0 in cls:
                f = helm.run(nu0, (0.0, 0.0, psi0), [("stop", 0.0), ("turn", psi0 + sgn * np.pi / 2), ("settle", 0.0)])
                per.append(
                    _assemble(
                        profile,
                        f"spot_turn_{side}",
                        f"stop, turn on the spot 90 deg to {word}, speed up",
                        "basic",
                        None,
                        nu0,
                        f,
                        ["stop the ship", f"turn on the spot 90° to {word}", f"regain {uc / KNOT:.1f} kn on the new course"],
                        [],
                    )
                )
            out.append(per)
    return out


def place(
    prims: list[Primitive],
    res: float,
    n_head: int,
    counter: int,
    cost: float,
    source: str = "",
    run_in: tuple[int, ...] = (),
    core: tuple[int, ...] = (),
) -> Move:
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
