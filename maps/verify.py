"""Continuous re-simulation of a lattice plan and its clearance check.

The lattice snaps end poses; reality does not. The whole sequence of inputs is simulated in
one go from the start pose with the first move's entry velocity (nominal calm model, no
snapping) and the hull placed at every sample is tested against the obstacles: the smallest
distance between hull and no-go area is the plan's clearance, which must be at least the
safety margin. The re-simulated track must also end near the lattice's end point: a track that
ends kilometres away is not the plan the search found (its counters, goal and clearance were
reckoned on another track), so it is not verified.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from maps.geo import SeaMap
from primitives.footprint import hull_at, hull_outline
from primitives.library import Primitive
from primitives.simulate import simulate


@dataclass
class Verification:
    t: np.ndarray
    track: np.ndarray  # (K, 3)
    nu: np.ndarray  # (K, 3)
    inputs: np.ndarray  # (K, m): input applied from each sample (last row repeats)
    step_of_sample: np.ndarray
    clearances: np.ndarray  # per sample, hull to no-go distance
    min_clearance_m: float
    worst_sample: int
    drift_m: float  # distance between continuous end position and lattice end position
    ok: bool
    reason: str = ""
    max_drift_m: float = float("inf")  # the drift beyond which the plan is not the one searched

    @property
    def drifted(self) -> bool:
        """The re-simulated track ends farther from the lattice's end point than ``max_drift_m``."""
        return self.drift_m > self.max_drift_m


def hull_clearance(sea: SeaMap, length_m: float, beam_m: float, track: np.ndarray, margin: float) -> np.ndarray:
    """Per sample: distance between the hull (and its sweep to the neighbouring samples) and the
    no-go area of the map; inf where nothing is near.

    Exact wherever the sample can hold the smallest clearance; elsewhere a lower bound (distance
    of the hull's reference point less the hull radius and the step to the neighbours), which is
    larger than that smallest clearance: min and argmin are those of the exact per-sample values,
    at a fraction of the polygon distances."""
    outline = hull_outline(length_m, beam_m)
    xmin, ymin = track[:, :2].min(axis=0) - length_m - margin - 500.0
    xmax, ymax = track[:, :2].max(axis=0) + length_m + margin + 500.0
    no_go = shapely.clip_by_rect(sea.no_go(), xmin, ymin, xmax, ymax)
    if no_go.is_empty:
        return np.full(len(track), np.inf)
    shapely.prepare(no_go)
    d_pt = shapely.distance(shapely.points(track[:, :2]), no_go)  # the reference point lies inside the hull
    rho = float(np.max(np.hypot(outline[:, 0], outline[:, 1])))
    step = np.hypot(*np.diff(track[:, :2], axis=0).T) if len(track) > 1 else np.zeros(0)
    reach = np.zeros(len(track))
    if len(step):
        reach[:-1] = step
        reach[1:] = np.maximum(reach[1:], step)
    lower = d_pt - rho - reach
    exact = np.flatnonzero(lower <= float(d_pt.min()))  # an upper bound of the smallest clearance
    clear = lower.copy()
    hulls = hull_at(outline, track[exact])
    clear[exact] = shapely.distance(shapely.polygons(hulls), no_go)
    # consecutive placements are one sample apart: their convex hulls are the sweep
    pair = exact[exact + 1 < len(track)]
    if len(pair):
        both = np.concatenate([hull_at(outline, track[pair]), hull_at(outline, track[pair + 1])], axis=1)
        cs = shapely.distance(shapely.convex_hull(shapely.multipoints(both)), no_go)
        clear[pair] = np.minimum(clear[pair], cs)
        np.minimum.at(clear, pair + 1, cs)
    return clear


def resimulate(
    sea: SeaMap,
    prims: list[Primitive],
    start: tuple[float, float, float],
    margin: float,
    lattice_end: tuple[float, float] | None = None,
    nu0: np.ndarray | None = None,
    sims: list | None = None,
    max_drift: float = float("inf"),
) -> Verification:
    """Simulate the concatenated inputs of ``prims`` (anything with ``inputs``, ``n_samples``,
    ``name``) from ``start`` and check the swept hull against the map with the margin.

    ``sims``: the (nu, eta) (n+1, 3) of each piece already sailed one after the other from
    (``nu0``, ``start``): their concatenation is the continuous simulation, sample for sample.
    ``max_drift``: the largest distance [m] between the track's end and ``lattice_end`` that
    still verifies."""
    profile = prims[0].profile
    inputs = np.vstack([p.inputs for p in prims])
    step = np.concatenate([np.full(p.n_samples, i) for i, p in enumerate(prims)] + [[len(prims) - 1]])
    if sims is not None and all(s is not None for s in sims):
        nu = np.vstack([s[0][:-1] for s in sims] + [sims[-1][0][-1:]])
        track = np.vstack([s[1][:-1] for s in sims] + [sims[-1][1][-1:]])
        t = np.arange(len(track)) * profile.sample_time
    else:
        res = simulate(profile, inputs, nu0=prims[0].nu0 if nu0 is None else nu0, eta0=start)
        track, nu, t = res.eta[0], res.nu[0], res.t
    clear = hull_clearance(sea, profile.length_m, profile.beam_m, track, margin)
    worst = int(np.argmin(clear))
    mc = float(clear[worst])
    drift = float(np.hypot(*(track[-1, :2] - np.asarray(lattice_end)))) if lattice_end is not None else 0.0
    drifted = drift > max_drift
    ok = mc >= margin - 1e-6 and not drifted
    reason = ""
    if drifted:
        reason = (
            f"the re-simulated track ends {drift:.0f} m from the planned end point (at most {max_drift:.0f} m verifies): "
            "the profile's manoeuvres, sailed one after the other, do not end where the lattice placed them; "
            "check the profile's manoeuvres or use a finer --resolution"
        )
    elif not ok:
        reason = (
            f"the re-simulated track comes {mc:.1f} m from an obstacle (margin {margin:g} m) at t = {t[worst]:.0f} s "
            f"in step {int(step[worst]) + 1} ({prims[int(step[worst])].name}): increase --margin or use a finer --resolution"
        )
    ins = np.vstack([inputs, inputs[-1:]])
    return Verification(t, track, nu, ins, step, clear, mc, worst, drift, ok, reason, max_drift)
