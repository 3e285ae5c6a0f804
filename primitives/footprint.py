"""Hull outlines and the area a hull sweeps along a track.

Coordinates are (x north, y east) of the frame the track is given in (NED, Fossen 2021, ch. 2);
for primitives that is the start-pose frame, so x is the initial forward direction.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon


def hull_outline(length: float, beam: float) -> np.ndarray:
    """Body-frame hull outline (x forward, y starboard), centred amidships: a box with a bow."""
    half_l, half_b = length / 2.0, beam / 2.0
    bow = half_l - 0.25 * length
    return np.array([[half_l, 0.0], [bow, half_b], [-half_l, half_b], [-half_l, -half_b], [bow, -half_b]])


def hull_at(outline: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Outline placed at poses (K, 3) = (x, y, psi): array (K, n_vertices, 2)."""
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    x = poses[:, 0:1] + c * outline[:, 0] - s * outline[:, 1]
    y = poses[:, 1:2] + s * outline[:, 0] + c * outline[:, 1]
    return np.stack([x, y], axis=-1)


def swept_footprint(track: np.ndarray, length: float, beam: float, margin: float = 0.0) -> Polygon:
    """Area swept by the hull along a track (K, 3), buffered by ``margin``.

    Union of the convex hulls of consecutive hull placements (:func:`swept_hulls`). Between two
    kept poses a hull vertex moves on a curve, not on the chord the convex hull covers; the union
    is grown by a bound on that deviation (rotation sagitta plus translation-rotation coupling)
    so the footprint is conservative, never optimistic.
    """
    hulls, slack = swept_hulls(track, length, beam)
    if len(hulls) == 1:
        geom = Polygon(hulls[0])
    else:
        pairs = np.concatenate([hulls[:-1], hulls[1:]], axis=1)
        # the hull of each pair's ten vertices, from one linestring per pair: made from the coordinate array in one
        # call (a multipoint is made point by point), the same vertices in the same order, so the same hulls
        geom = shapely.union_all(shapely.convex_hull(shapely.linestrings(pairs)))
    if margin + slack > 0:
        geom = geom.buffer(margin + slack, quad_segs=4)
    return geom


def swept_hulls(track: np.ndarray, length: float, beam: float) -> tuple[np.ndarray, float]:
    """The hull placements (kept poses, (K, 5, 2)) whose pairwise convex hulls make the swept
    footprint, and the slack the union is grown by. Poses are thinned so consecutive hulls
    overlap. The footprint's extent in any direction lies between the placements' and the
    placements' plus twice the slack (a cheap bound where the footprint itself is not needed)."""
    track = np.asarray(track, float)
    step = np.hypot(*np.diff(track[:, :2], axis=0).T)
    dpsi = np.abs(np.diff(track[:, 2]))
    # keep a pose whenever the hull moved an eighth of the beam or turned 2 degrees since the last kept
    keep = [0]
    acc_d = acc_a = 0.0
    for i in range(len(step)):
        acc_d += step[i]
        acc_a += dpsi[i]
        if acc_d >= beam / 8 or acc_a >= np.radians(2):
            keep.append(i + 1)
            acc_d = acc_a = 0.0
    if keep[-1] != len(track) - 1:
        keep.append(len(track) - 1)
    outline = hull_outline(length, beam)
    kept = track[keep]
    seg_d = np.hypot(*np.diff(kept[:, :2], axis=0).T) if len(kept) > 1 else np.zeros(1)
    seg_a = np.abs(np.diff(kept[:, 2])) if len(kept) > 1 else np.zeros(1)
    rho = float(np.max(np.hypot(outline[:, 0], outline[:, 1])))
    slack = float(np.max(rho * (1 - np.cos(seg_a / 2)) + seg_d * np.sin(seg_a / 2) / 2, initial=0.0))
    return hull_at(outline, kept), slack


def swept_footprints(tracks: list[np.ndarray], length: float, beam: float) -> list[Polygon]:
    """:func:`swept_footprint` of each of ``tracks`` that begin alike (one manoeuvre's run-in
    and manoeuvre, then settling legs that differ): the union of the hulls they share is formed
    once and each footprint is that union with its own hulls, grown by its own slack. The same
    areas as one by one (the union is associative), with the vertices in another order."""
    parts = [swept_hulls(t, length, beam) for t in tracks]
    first = parts[0][0]
    n = min(len(h) for h, _ in parts)
    same = np.ones(n, bool)
    for h, _ in parts[1:]:
        same &= np.all(h[:n] == first[:n], axis=(1, 2))
    shared = (int(np.argmin(same)) if not same.all() else n) - 1  # pairs of hulls all of them have
    if len(tracks) < 2 or shared < 2:
        return [swept_footprint(t, length, beam) for t in tracks]
    head = shapely.union_all(
        shapely.convex_hull(shapely.linestrings(np.concatenate([first[:shared], first[1 : shared + 1]], axis=1)))
    )
    out = []
    for hulls, slack in parts:
        pairs = np.concatenate([hulls[shared:-1], hulls[shared + 1 :]], axis=1)
        geom = shapely.union_all(np.concatenate([[head], shapely.convex_hull(shapely.linestrings(pairs))]))
        out.append(geom.buffer(slack, quad_segs=4) if slack > 0 else geom)
    return out
