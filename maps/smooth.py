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

from maps.autopilot import RUN_IN_TOL, helm_for
from maps.lattice import SETTLE_PHASES, run_in_seconds
from maps.verify import hull_clearance
from primitives.library import KNOT
from primitives.ship import ShipProfile
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
    abort: list[str] = field(default_factory=list)  # the manoeuvre's own abort criteria (speed, heading, yaw rate)
    sim: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)  # (nu, eta) (N+1, 3) as sailed, if known
    # an executed manoeuvre's (u, v, r L) at its execute point less the steady values its design assumed
    entry_off: tuple[float, float, float] | None = None

    def sail(self, nu: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(nu, eta) at the end of the leg sailed from (nu, eta); the track is kept in ``sim``
        (sailing it again from the same state gives the same numbers: the model is deterministic)."""
        if self.sim is None:
            self.sim = _sail(self.profile, self.inputs, nu, eta)
        return self.sim[0][-1].copy(), self.sim[1][-1].copy()

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
        out.append(
            {"t_s": float(getattr(o, "t_s", 0.0)), "text": str(getattr(o, "text", "")), **dict(getattr(o, "values", {}) or {})}
        )
    return out


class Realiser:
    """Sails lattice moves from the ship's actual state: run-ins and settling legs in closed loop
    (so errors do not grow along the plan, which matters for a course-unstable hull), the
    informative primitive itself open loop, exactly as designed."""

    def __init__(self, lat):
        self.lat = lat
        self.helm = helm_for(lat.profile, lat.res, len(lat.table))
        self.run_in_s = run_in_seconds(lat.profile, lat.options.run_in_s)

    def _rel(self, spatial: int, eta: np.ndarray) -> tuple[float, float, float]:
        x0, y0, _ = self.lat.pose(spatial)
        return float(eta[0] - x0), float(eta[1] - y0), float(eta[2])

    def legs(self, mi: int, spatial: int, nu: np.ndarray, eta: np.ndarray, end: int) -> list[Leg]:
        """Legs of move ``mi`` from spatial state ``spatial`` to ``end``, from the actual (nu, eta)."""
        lat, helm = self.lat, self.helm
        x0, y0, _ = lat.pose(spatial)
        x2, y2, p2 = lat.pose(end)
        goal = (x2 - x0, y2 - y0, p2)
        K = len(lat.table)
        m, h = lat.moves[mi], spatial % K
        pr = m.prim(h)
        b = pr.footprint.bounds
        space = (float(b[2] - b[0]), float(b[3] - b[1]))
        if m.counter < 0:
            target = float(lat.table[(h + int(m.dh[h])) % K])
            delta = float(np.angle(np.exp(1j * (target - eta[2]))))
            if m.name.startswith("round_turn"):  # reverse course to the move's own side, as the lattice move does
                sgn = 1.0 if m.name.endswith("_s") else -1.0
                delta = sgn * min(abs(delta if delta * sgn > 0 else delta + sgn * 2 * np.pi), np.pi - 1e-6)
            target = eta[2] + delta
            if m.name == "straight":
                phases = [("settle", goal)]
            elif m.name.startswith("spot_turn"):
                phases = [("stop", 0.0), ("turn", target), ("settle", goal)]
            else:
                phases = [("turn", target), ("settle", goal)]
            ins = helm.run(nu, self._rel(spatial, eta), phases, n_max=20000)
            return [
                Leg(pr.name, pr.name, "basic", "transit", pr.description, pr.profile, ins, list(pr.commands), space, mi, spatial)
            ]
        n_r, core = m.run_in_samples(h), m.core_samples(h)
        src = lat.primitives.get(m.source or m.name)
        legs = []
        entry_off = None
        if n_r:
            u0, v0, r0 = (float(x) for x in pr.nu[n_r])
            hold = (u0, v0, r0, self.run_in_s, float(lat.table[h]), SETTLE_PHASES[lat.options.settle])
            ri = helm.run(nu, self._rel(spatial, eta), [("hold", hold)], n_max=20000)
            u = float(np.hypot(u0, v0))
            course = float(np.degrees(lat.table[h]) % 360)
            hold_s = len(ri) * pr.profile.sample_time
            # a manoeuvre that starts from rest (an acceleration) is approached by stopping, not by a steady run
            moving = u > 0.05 * pr.profile.cruise_speed_mps
            steady = (
                f"steady on course {course:03.0f}° at {u / KNOT:.1f} kn"
                if moving
                else f"stop engine(s) and come to rest, heading {course:03.0f}°"
            )
            text = f"{steady} for {hold_s:.0f} s, then execute"
            what = f"run-in to {m.name}: steady course and speed" if moving else f"stop before {m.name}: come to rest and settle"
            legs.append(
                Leg(
                    f"run-in {m.name}",
                    m.source or m.name,
                    "run-in",
                    "run-in",
                    what,
                    pr.profile,
                    ri,
                    [text],
                    space,
                    mi,
                    spatial,
                    orders=[{"t_s": 0.0, "text": text, "course_deg": course, "speed_kn": u / KNOT}],
                )
            )
            nu, eta = legs[-1].sail(nu, eta)
            entry_off = (float(nu[0] - u0), float(nu[1] - v0), float((nu[2] - r0) * pr.profile.length_m))
        body = pr.inputs[n_r:core]
        b_nu, b_eta = _sail(pr.profile, body, nu, eta)
        tail = helm.run(b_nu[-1], self._rel(spatial, b_eta[-1]), [("settle", goal)], n_max=20000)
        t_nu, t_eta = _sail(pr.profile, tail, b_nu[-1], b_eta[-1])
        orders = _orders(src)
        if len(tail) > 1:  # the helm brings the ship back to the lattice's course and speed: not part of the manoeuvre
            u_c = pr.profile.cruise_speed_mps
            orders.append(
                {
                    "t_s": len(body) * pr.profile.sample_time,
                    "phase": "recovery",
                    "text": f"manoeuvre complete; recovery: come to course {np.degrees(goal[2]) % 360:03.0f}° "
                    f"at {u_c / KNOT:.1f} kn ({len(tail) * pr.profile.sample_time:.0f} s)",
                }
            )
        legs.append(
            Leg(
                m.name,
                m.source or m.name,
                "informative",
                "informative",
                pr.description,
                pr.profile,
                np.vstack([body, tail]),
                list(pr.commands),
                space,
                mi,
                spatial,
                execute=bool(n_r),
                orders=orders,
                abort=[src.abort_criteria()] if hasattr(src, "abort_criteria") else [],
                sim=(np.vstack([b_nu[:-1], t_nu]), np.vstack([b_eta[:-1], t_eta])),
                entry_off=entry_off if n_r else None,
            )
        )
        return legs


def unsteady_executes(legs: list[Leg], tol: tuple[float, float, float] = RUN_IN_TOL) -> list[str]:
    """One line per executed manoeuvre whose (u, v, r L) at the execute point is off the steady values
    its design assumed by more than ``tol`` (the run-in's own tolerance on large water): its
    information is not quite the design's."""
    out = []
    for k, leg in enumerate(legs):
        if leg.entry_off is not None and any(abs(d) > t for d, t in zip(leg.entry_off, tol)):
            du, dv, rl = leg.entry_off
            out.append(
                f"step {k + 1} ({leg.name}) is executed off the steady approach its design assumes: speed "
                f"{du:+.3f} m/s, sway {dv:+.3f} m/s, rate of turn x length {rl:+.4f} m/s (the run-in on large water "
                f"waits for {tol[0]:g}, {tol[1]:g}, {tol[2]:g})"
            )
    return out


def _sail(profile: ShipProfile, inputs: np.ndarray, nu: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nu, eta) (N+1, 3) of ``inputs`` sailed from (nu, eta) on the nominal model."""
    if not len(inputs):
        return np.asarray(nu, float)[None].copy(), np.asarray(eta, float)[None].copy()
    sim = simulate(profile, inputs, nu0=nu, eta0=eta)
    return sim.nu[0], sim.eta[0]


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
        self.helm = helm_for(profile, res, n_head)
        L, B = profile.length_m, profile.beam_m
        self.radius = profile.cruise_speed_mps / self.helm.r_lim  # turning radius at the helm's yaw-rate limit
        self.corridor = 0.5 * B + 0.5 * L + margin
        self.approach = 2.0 * L + 2.0 * self.radius  # straight final leg: the ship settles on the course
        self.no_go = sea.no_go()
        shapely.prepare(self.no_go)

    def free(self, a, b) -> bool:
        return not shapely.intersects(self.no_go, shapely.LineString([a, b]).buffer(self.corridor))

    def legs(self, poses: np.ndarray, nu: np.ndarray, eta: np.ndarray) -> Leg | None:
        """One transit leg from the actual state (nu, eta) to the last lattice pose of the run
        (x, y, psi), or None when the water or the arrival (position, course) does not allow
        one; the caller keeps it only where it is shorter than the lattice moves it replaces."""
        end = poses[-1]
        d_end = np.array([np.cos(end[2]), np.sin(end[2])])
        app = end[:2] - self.approach * d_end
        if not self.free(app, end[:2]):
            return None
        pts = np.vstack([poses[:, :2], app[None, :]])
        pts[-2], pts[-1] = app, end[:2]
        # pulled up to the approach point, which is always kept: the last lattice point is reached
        # along its course (string pulling over it would arrive on the bearing of the last leg)
        keep = [*string_pull(pts[:-1], self.free), len(pts) - 1]
        wps = [tuple(eta[:2])] + [tuple(pts[k]) for k in keep[1:]]
        inputs = self.helm.run(nu, tuple(eta), [("track", (wps, 2.0 * self.p.length_m))], n_max=20000)
        s_nu, tr = _sail(self.p, inputs, nu, eta)
        if np.hypot(*(tr[-1, :2] - end[:2])) > 0.25 * self.helm.res or abs(
            np.angle(np.exp(1j * (tr[-1, 2] - end[2])))
        ) > np.radians(5):
            return None
        if hull_clearance(self.sea, self.p.length_m, self.p.beam_m, tr, self.margin).min() < self.margin + 1.0:
            return None
        n_legs = len(wps) - 1
        dist = float(np.sum(np.hypot(*np.diff(tr[:, :2], axis=0).T)))
        uc = self.helm.uc
        return Leg(
            "transit",
            "transit",
            "basic",
            "transit",
            f"{n_legs} straight leg{'s' if n_legs > 1 else ''}, {dist:.0f} m",
            self.p,
            inputs,
            [f"steer for each waypoint in turn at {uc / KNOT:.1f} kn; {n_legs} leg{'s' if n_legs > 1 else ''}, {dist:.0f} m"],
            (dist, self.corridor * 2),
            sim=(s_nu, tr),
        )
