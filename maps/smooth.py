"""From a lattice path to what the ship sails: legs, run-ins and straightened transits.

The A* path is a sequence of lattice moves. Informative moves become two legs (the run-in to
the execute point, then the manoeuvre with its settling leg). A run of repositioning moves is
replaced, when the water allows, by an any-angle shortcut: string pulling over the lattice
poses of the run (Botea et al. 2004; the "theta*" idea applied after the search), sailed by
line-of-sight guidance on the nominal model from the ship's actual state, so transit is a few
straight legs instead of a staircase. Each shortcut is kept only if its swept hull keeps the
margin (exact check on the simulated track); otherwise the lattice moves are sailed as planned.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from maps.lattice import Move, _Helm
from maps.verify import hull_clearance
from primitives.ship import ProfileError, ShipProfile
from primitives.simulate import simulate


@dataclass
class Leg:
    """A piece of the sailed plan: one step of the Plan.

    ``segment``: "run-in", "informative" or "transit"; ``move``/``spatial``: the lattice move
    index and the spatial state it starts from (-1 for a shortcut that replaced several)."""

    name: str
    source: str
    kind: str
    segment: str
    description: str
    profile: ShipProfile
    inputs: np.ndarray
    commands: list[str]
    space_m: tuple[float, float]
    move: int = -1
    spatial: int = -1
    execute: bool = False
    orders: list[dict[str, Any]] = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        return int(self.inputs.shape[0])

    @property
    def duration_s(self) -> float:
        return self.n_samples * self.profile.sample_time


def _orders(prim: Any) -> list[dict[str, Any]]:
    """Primitive.orders (a list of Order(t_s, text, values)) as plain dicts; [] when absent."""
    out = []
    for o in getattr(prim, "orders", None) or []:
        out.append({"t_s": float(getattr(o, "t_s", 0.0)), "text": str(getattr(o, "text", "")), **dict(getattr(o, "values", {}) or {})})
    return out


def move_legs(move: Move, h: int, mi: int, spatial: int, source_prims: dict[str, Any]) -> list[Leg]:
    """The legs of one lattice move started at heading index h."""
    pr = move.prim(h)
    b = pr.footprint.bounds
    space = (float(b[2] - b[0]), float(b[3] - b[1]))
    if move.counter < 0:
        return [Leg(pr.name, pr.name, "basic", "transit", pr.description, pr.profile, pr.inputs, list(pr.commands), space, mi, spatial)]
    n_r = move.run_in_samples(h)
    src = source_prims.get(move.source or move.name)
    legs = []
    if n_r:
        u = float(np.hypot(*pr.nu[n_r, :2]))
        legs.append(Leg(f"run-in {move.name}", move.source or move.name, "run-in", "run-in",
                        f"run-in to {move.name}: steady course and speed", pr.profile, pr.inputs[:n_r],
                        [f"steady on course at {u:.1f} m/s ({u / 0.514444:.1f} kn) for {n_r * pr.profile.sample_time:.0f} s, "
                         f"then execute {move.name} at the execute point"], space, mi, spatial))
    legs.append(Leg(move.name, move.source or move.name, "informative", "informative", pr.description, pr.profile,
                    pr.inputs[n_r:], list(pr.commands), space, mi, spatial, execute=bool(n_r), orders=_orders(src)))
    return legs


def string_pull(poses: np.ndarray, free) -> list[int]:
    """Indices of the poses kept by string pulling: from each kept pose, the farthest later pose
    reachable by a straight segment for which ``free(a, b)`` holds."""
    keep = [0]
    i, n = 0, len(poses)
    while i < n - 1:
        k = n - 1
        while k > i + 1 and not free(poses[i, :2], poses[k, :2]):
            k -= 1
        keep.append(k)
        i = k
    return keep


class Shortcutter:
    """Replaces runs of repositioning moves by line-of-sight legs where the water allows."""

    def __init__(self, sea, profile: ShipProfile, res: float, n_head: int, margin: float):
        self.sea, self.p, self.margin = sea, profile, margin
        self.helm = _Helm(profile, res, n_head)
        L, B = profile.length_m, profile.beam_m
        self.radius = 1.5 * L  # the helm's yaw-rate limit: r = U / (1.5 L)
        self.corridor = 0.5 * B + 0.5 * L + margin
        self.approach = 2.0 * L + 2.0 * self.radius  # straight final leg: the ship settles on the course
        self.no_go = sea.no_go()
        shapely.prepare(self.no_go)

    def free(self, a, b) -> bool:
        return not shapely.intersects(self.no_go, shapely.LineString([a, b]).buffer(self.corridor))

    def legs(self, poses: np.ndarray, nu: np.ndarray, eta: np.ndarray) -> Leg | None:
        """One transit leg from the actual state (nu, eta) to the last lattice pose of the run
        (x, y, psi), or None when no shortcut shortens it safely."""
        end = poses[-1]
        d_end = np.array([np.cos(end[2]), np.sin(end[2])])
        app = end[:2] - self.approach * d_end
        if not self.free(app, end[:2]):
            return None
        pts = np.vstack([poses[:, :2], app[None, :]])
        pts[-2], pts[-1] = app, end[:2]  # the last lattice point is reached along its course
        keep = string_pull(pts, self.free)
        if len(keep) >= len(poses) + 1:
            return None
        wps = [tuple(eta[:2])] + [tuple(pts[k]) for k in keep[1:]]
        try:
            f = self.helm.run(nu, tuple(eta), [("track", (wps, 2.0 * self.p.length_m))], n_max=20000)
            inputs = self.p.allocate(*f.T)
        except ProfileError:
            return None  # no force allocation for this actuator: sail the lattice moves
        sim = simulate(self.p, inputs, nu0=nu, eta0=tuple(eta))
        tr = sim.eta[0]
        if np.hypot(*(tr[-1, :2] - end[:2])) > 0.25 * self.helm.res or abs(np.angle(np.exp(1j * (tr[-1, 2] - end[2])))) > np.radians(5):
            return None
        if hull_clearance(self.sea, self.p.length_m, self.p.beam_m, tr, self.margin).min() < self.margin + 1.0:
            return None
        n_legs = len(wps) - 1
        dist = float(np.sum(np.hypot(*np.diff(tr[:, :2], axis=0).T)))
        uc = self.helm.uc
        return Leg("transit", "transit", "basic", "transit", f"transit: {n_legs} straight leg(s), {dist:.0f} m",
                   self.p, inputs, [f"at {uc:.1f} m/s ({uc / 0.514444:.1f} kn) steer for the next waypoint; "
                                    f"{n_legs} leg(s), {dist:.0f} m"], (dist, self.corridor * 2))
