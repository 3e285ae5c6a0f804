"""What fits: the memory a lattice would need (refused up front, issue 12) and the primitives
too large for the navigable water in every heading (left out before any move is built)."""

from __future__ import annotations

import math
from decimal import Decimal
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from maps.collision import Window
from maps.geo import MapError, SeaMap
from primitives.footprint import swept_hulls
from primitives.library import Primitive
from primitives.ship import ShipProfile

if TYPE_CHECKING:
    from maps.chain import PlanOptions

BYTES_PER_EDGE = 120  # a successor tuple in a Python list (measured order of magnitude)
BYTES_PER_STATE = 260  # an A* state: g-cost and parent dict entries, closed-set entry, heap entry


def estimate_memory(lat_ni: int, lat_nj: int, n_head: int, n_moves: int, targets: list[int]) -> tuple[float, int]:
    """(bytes, states): memory of the tables every search builds (successors of every move at
    every lattice point, the relaxed cost-to-go graph with edges x (D + 1)) and the number of
    counter-augmented states (8.5). A* visits only part of the states; it is stopped when the
    states it holds reach the rest of the memory budget (``BYTES_PER_STATE`` each).

    Exact Python integers throughout: numpy's int64 wraps around (to a negative state count) for
    the counts of a very long trial; bytes past the float range are ``inf``."""
    spatial = int(lat_ni) * int(lat_nj) * int(n_head)
    states = spatial * math.prod(int(d) + 1 for d in targets)
    edges = spatial * int(n_moves)
    D = sum(int(d) for d in targets)
    need = edges * BYTES_PER_EDGE + edges * (D + 1) * 40 + spatial * (D + 1) * 8 * 3
    return (float(need) if need.bit_length() < 1000 else math.inf), states


def _count(n: float, fmt: str) -> str:
    """``n`` as ``fmt`` (e.g. ",.1f"), or in scientific notation from 1e15 on (an int of any size)."""
    return format(n, fmt) if n < 1e15 else f"{Decimal(n):.2e}"


def refuse_too_large(
    win: Window, K: int, prims: list[Primitive], counts: dict[str, int], profile: ShipProfile, o: PlanOptions
) -> None:
    """MapError, with the estimate, when the lattice would need more than ``max_memory_gib``."""
    n_moves = len(prims) + (5 if o.spot_turns or profile.actuator == "rudder_propeller" else 3)
    need, states = estimate_memory(win.ni, win.nj, K, n_moves, [counts[p.name] for p in prims])
    if need > o.max_memory_gib * 2**30:
        raise MapError(
            f"the lattice would not fit: {win.ni} x {win.nj} points x {K} headings x counters = {_count(states, ',')} states, "
            f"an estimated {_count(need / 2**30, ',.1f')} GiB (limit {o.max_memory_gib:g} GiB): use a coarser --resolution, "
            f"fewer --headings, a shorter --trial-length or raise --max-memory"
        )


def too_big_for_water(
    sea: SeaMap, win: Window, prims: list[Primitive], table: np.ndarray, margin: float
) -> dict[str, tuple[float, float]]:
    """Primitives whose footprint (grown by the margin) is larger than the bounding box of the
    navigable water of the window in every lattice heading: they fit nowhere (a certain, cheap
    test; the collision grid decides for the others)."""
    water = shapely.box(*win.bounds).difference(sea.no_go())
    if water.is_empty:
        return {p.name: needs(p, margin) for p in prims}
    wx0, wy0, wx1, wy1 = water.bounds
    room = (wx1 - wx0, wy1 - wy0)
    out = {}
    for p in prims:
        parts = None if "footprint" in p.__dict__ else swept_hulls(p.track, p.profile.length_m, p.profile.beam_m)
        if not any(_fits_box(p, parts, float(psi), room, margin) for psi in table):
            out[p.name] = needs(p, margin)
    return out


def _fits_box(p: Primitive, parts: tuple[np.ndarray, float] | None, psi: float, room: tuple[float, float], margin: float) -> bool:
    """Whether ``p``'s footprint turned by ``psi``, with ``margin`` on both sides, has an extent
    within ``room`` (north, east).

    Decided from ``parts`` (:func:`primitives.footprint.swept_hulls` of ``p``, or None), the
    hull placements the footprint is the union of, when their extent, and that extent
    plus twice the footprint's slack, fall on the same side of ``room`` (by more than a
    micrometre of rounding): the footprint itself (a union of hundreds of hulls) is made only
    when they straddle it. The same answers as the footprint's bounds."""
    from shapely import affinity

    if parts is not None:
        hulls, slack = parts
        v = hulls.reshape(-1, 2)
        c, s = np.cos(psi), np.sin(psi)
        x, y = v[:, 0] * c - v[:, 1] * s, v[:, 0] * s + v[:, 1] * c
        ext = np.array([x.max() - x.min(), y.max() - y.min()])
        tol = 1e-6 * (1.0 + float(np.abs(v).max()))
        if np.all(ext + 2 * slack + tol + 2 * margin <= room):
            return True
        if np.any(ext - tol + 2 * margin > room):
            return False
    b = affinity.rotate(p.footprint, psi, origin=(0, 0), use_radians=True).bounds
    return bool(b[2] - b[0] + 2 * margin <= room[0] and b[3] - b[1] + 2 * margin <= room[1])


class Needs(tuple):
    """(along, cross) metres a manoeuvre that fits nowhere takes, ``margin`` included on both sides
    (a plain pair to every reader), and why it fits nowhere: ``reach`` False when its footprint is
    larger than the navigable water in every heading (the water it needs at least); True when the
    water's extent would hold it but no collision-free placement of its move (run-in, manoeuvre
    and the autopilot's settling leg) is reachable from the start with the goal reachable after it
    (then the pair is the move's extent, and the water it needs is more than that). ``apart`` True
    (with ``reach``): the design's check found a placement (reachable by any moves, the other
    designed manoeuvres included: :meth:`maps.chain.Lattice.fits_nowhere`), but no path start to goal
    sails it with the rest of the designed mix (:mod:`maps.sailable`); it may not fit alone either."""

    reach: bool
    apart: bool

    def __new__(cls, along: float, cross: float, reach: bool = False, apart: bool = False) -> Needs:
        obj = super().__new__(cls, (float(along), float(cross)))
        obj.reach = bool(reach or apart)
        obj.apart = bool(apart)
        return obj

    def __getnewargs__(self) -> tuple[float, float, bool, bool]:  # pickles with its reason
        return (self[0], self[1], self.reach, self.apart)

    def record(self) -> dict[str, Any]:
        """The reason's keys in a plan's record: ``unreachable`` and ``apart`` (only when true)."""
        return ({"unreachable": True} if self.reach else {}) | ({"apart": True} if self.apart else {})


def needs(p: Primitive, margin: float, reach: bool = False, apart: bool = False) -> Needs:
    """(along, cross) metres of open water ``p`` takes: its footprint's extent plus ``margin`` on both
    sides (``reach``, ``apart``: see :class:`Needs`)."""
    b = p.footprint.bounds
    return Needs(b[2] - b[0] + 2 * margin, b[3] - b[1] + 2 * margin, reach, apart)


def km(m: float) -> str:
    """A length for a message: '6.2 km', or '530 m' below a kilometre."""
    return f"{m / 1000:.1f} km" if m >= 1000 else f"{m:.0f} m"


def row_text(row: dict[str, Any]) -> str:
    """:func:`water_text` of a plan's record row ({primitive, needs_m, unreachable?, apart?})."""
    need = Needs(*row["needs_m"], bool(row.get("unreachable")), bool(row.get("apart")))
    return water_text(row["primitive"], need)


def water_text(name: str, need: tuple[float, float]) -> str:
    """What ``name`` that fits nowhere takes, truthfully for either reason (:class:`Needs`):
    'stopping needs 10.6 km x 98 m of open water', or
    'pull_out_20_s (6.7 km x 5.4 km with run-in and settling leg) has no reachable placement' (none
    reachable from the start with the goal reachable after it; one line with the others stays short)."""
    a, c = float(need[0]), float(need[1])
    if getattr(need, "apart", False):
        return f"{name} ({km(a)} x {km(c)} with run-in and settling leg) cannot be sailed after the rest of the mix"
    if getattr(need, "reach", False):
        return f"{name} ({km(a)} x {km(c)} with run-in and settling leg) has no reachable placement"
    return f"{name} needs {km(a)} x {km(c)} of open water"
