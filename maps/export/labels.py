"""Where the step numbers go on a map: every label visible, none over another or over the track.

A step number is a circle of radius ``r`` (points). It goes up and right of its step's entry
point when that place is free; otherwise to the nearest free place on rings around the entry
point, and a leader line joins it to the point (as chart makers set names aside in crowded
water). Free: the circle keeps ``gap`` points from every label placed before it, from the
track's polyline, from the map's own marks (:func:`map_marks`: the north arrow and the end
marker) and from the frame. Labels are placed in step order (greedy); a label that
finds no free place within the rings takes the place that is least crowded, never none.
Everything is in page points; the PDF map and the PNG map (through their transforms) use the
same placement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEFAULT_OFFSET = (7.0, 7.0)  # points up and right of the entry point: where an uncrowded label sits
_ANGLES = np.radians(np.arange(45.0, 405.0, 22.5))  # up-right first, round the point


@dataclass(frozen=True)
class Label:
    """A placed step number: text, centre and radius (points), its anchor, whether it was moved."""

    text: str
    x: float
    y: float
    r: float
    anchor: tuple[float, float]
    moved: bool


def segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances from points ``p`` (n, 2) to the nearest of the segments a[i]-b[i] (m, 2): (n,)."""
    if not len(a):
        return np.full(len(p), np.inf)
    # x and y apart: a sum over an axis of length 2 is x + y, so these are the bits of the (n, m, 2)
    # form, without its temporaries (the card's label placement calls this for every step)
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    dd = np.maximum(dx * dx + dy * dy, 1e-12)
    px, py = p[:, 0, None] - a[None, :, 0], p[:, 1, None] - a[None, :, 1]
    t = np.clip((px * dx + py * dy) / dd, 0.0, 1.0)
    ex, ey = p[:, 0, None] - (a[None, :, 0] + t * dx), p[:, 1, None] - (a[None, :, 1] + t * dy)  # p - q, q on the segment
    return np.sqrt(ex * ex + ey * ey).min(axis=1)


def near_segments(anchor: np.ndarray, reach: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Indices of the segments a[i]-b[i] that can be the nearest one to some point within
    ``reach`` of ``anchor`` (2,). The distance to a segment moves by at most as much as the point
    (it is 1-Lipschitz), so a segment farther from the anchor than the nearest one plus twice the
    reach is never the nearest to such a point: :func:`segment_distances` over the rest gives the
    same minimum, bit for bit (each element is computed alike; a minimum is exact). The slack
    covers rounding."""
    if not len(a):
        return np.arange(0)
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    dd = np.maximum(dx * dx + dy * dy, 1e-12)
    px, py = anchor[0] - a[:, 0], anchor[1] - a[:, 1]
    t = np.clip((px * dx + py * dy) / dd, 0.0, 1.0)
    d = np.hypot(px - t * dx, py - t * dy)
    return np.flatnonzero(d <= d.min() + 2.0 * reach + 1e-6 * (1.0 + reach))


def _thin(track: np.ndarray, step: float) -> np.ndarray:
    """The polyline with points closer than ``step`` to the last kept one dropped (ends kept)."""
    if len(track) < 3:
        return track
    # plain floats (a numpy call per point was most of this loop's CPU); math.hypot may differ from numpy's
    # (libm's) in the last bit, so a distance within rounding of ``step`` is taken from numpy: the same points kept
    xs, ys = track[:, 0].tolist(), track[:, 1].tolist()
    keep, lx, ly = [0], xs[0], ys[0]
    tol = 1e-9 * max(step, 1e-300)
    for k in range(1, len(track) - 1):
        dx, dy = xs[k] - lx, ys[k] - ly
        d = math.hypot(dx, dy)
        if abs(d - step) <= tol:
            d = float(np.hypot(np.float64(dx), np.float64(dy)))
        if d >= step:
            keep.append(k)
            lx, ly = xs[k], ys[k]
    keep.append(len(track) - 1)
    return track[keep]


Mark = tuple[tuple[float, float], tuple[float, float], float]  # a segment (ends, points) and its half-width


# the map's own marks, drawn by both maps (mapplot.draw_map, pdfmap.MapWriter) from these figures
NORTH_FS = 9.0  # the north arrow's "N"
NORTH_X, NORTH_Y = 0.95, (0.85, 0.95)  # the arrow in axes fractions: its "N" at the first height, its tip at the second
# where the arrow may go, in this order: top right, top left, bottom left (bottom right holds the scale bar); a
# track ending top right put the "end" square on the arrow (the README's coaster, stop 62's walk-through)
NORTH_PLACES = ((NORTH_X, NORTH_Y), (1.0 - NORTH_X, NORTH_Y), (1.0 - NORTH_X, (1.0 - NORTH_Y[1], 1.0 - NORTH_Y[0])))
NORTH_CLEAR = 0.07  # of the frame: the "N" (9 pt) and the end square (9 pt) on a card's map of some 300 pt a side
END_MARKER_PT = 9.0  # the end marker's size (matplotlib's ms: a square 9 pt a side)


def north_place(track: np.ndarray, frame: tuple[float, float, float, float]) -> tuple[float, tuple[float, float]]:
    """Where both maps draw the north arrow (x, (y of its "N", y of its tip) in fractions of ``frame``): the first
    of :data:`NORTH_PLACES` that the track (k, 2, in the frame's units; its first and last points carry the start
    and end markers) keeps :data:`NORTH_CLEAR` from, else the one it keeps farthest from."""
    x0, y0, x1, y1 = frame
    pts = (np.asarray(track, float).reshape(-1, 2) - (x0, y0)) / (max(x1 - x0, 1e-12), max(y1 - y0, 1e-12))
    if not len(pts):
        return NORTH_PLACES[0]
    clear = [float(segment_distances(pts, np.array([[x, ya]]), np.array([[x, yb]])).min()) for x, (ya, yb) in NORTH_PLACES]
    return next((p for p, c in zip(NORTH_PLACES, clear) if c >= NORTH_CLEAR), NORTH_PLACES[int(np.argmax(clear))])


def map_marks(
    frame: tuple[float, float, float, float], end: tuple[float, float], north: tuple[float, tuple[float, float]] | None = None
) -> list[Mark]:
    """What a label must not cover besides the track: the north arrow (its "N" and shaft from
    y[0] to y[1] of the frame's height at x of its width, ``north`` = (x, y) as :func:`north_place` gives it
    and both maps draw it; default the top right) and the end marker at ``end`` (the square's half-diagonal)."""
    x0, y0, x1, y1 = frame
    nx, ny = north or (NORTH_X, NORTH_Y)
    xn = x0 + nx * (x1 - x0)
    north_mark = ((xn, y0 + ny[0] * (y1 - y0)), (xn, y0 + ny[1] * (y1 - y0)), 0.45 * NORTH_FS)  # half the "N" and a little
    e = (float(end[0]), float(end[1]))
    return [north_mark, (e, e, END_MARKER_PT / np.sqrt(2.0))]


def mark_room(p: np.ndarray, marks: list[Mark]) -> np.ndarray:
    """Distances from points ``p`` (n, 2) to the nearest edge of ``marks``: (n,), inf for none."""
    room = np.full(len(p), np.inf)
    for a, b, half in marks:
        room = np.minimum(room, segment_distances(p, np.array([a], float), np.array([b], float)) - half)
    return room


def place_labels(
    texts: list[str],
    anchors: np.ndarray,
    radii: list[float],
    track: np.ndarray,
    frame: tuple[float, float, float, float],
    gap: float = 1.0,
    marks: list[Mark] | None = None,
) -> list[Label]:
    """Labels for ``texts`` at ``anchors`` (n, 2 points), each of radius ``radii[i]``, clear of
    each other, of ``track`` (k, 2 points, the drawn polyline) and of ``marks`` (default
    :func:`map_marks` with the track's last point as the end), inside ``frame`` (left, bottom,
    right, top)."""
    pts = _thin(np.asarray(track, float).reshape(-1, 2), 1.0)
    anchors = np.asarray(anchors, float).reshape(-1, 2)
    # the track's segments and the entry points themselves (stars and marks sit there)
    a, b = np.vstack([pts[:-1], anchors]), np.vstack([pts[1:], anchors])
    if marks is None:
        marks = map_marks(frame, tuple(pts[-1]), north_place(track, frame)) if len(pts) else []
    placed: list[Label] = []
    for text, (ax, ay), r in zip(texts, anchors, radii):
        rings = [np.array([[ax + DEFAULT_OFFSET[0], ay + DEFAULT_OFFSET[1]]])]
        for k in range(1, 9):
            dist = 2.0 * r + 1.5 * k * r
            rings.append(np.column_stack([ax + dist * np.cos(_ANGLES), ay + dist * np.sin(_ANGLES)]))
        # ring by ring, the usual place first: the first free candidate in that order is the first of all of
        # them (each candidate's room is its own minimum, the same number measured alone or with the others),
        # and most labels take the usual place or a near ring: the outer rings are measured only when needed
        rooms: list[np.ndarray] = []  # measured so far, in candidate order: index i is candidate i of all rings
        for ring in rings:
            rooms.append(_room(ring, (ax, ay), r, a, b, marks, frame, placed, gap))
            free = np.flatnonzero(rooms[-1] >= 0.0)
            if len(free):
                i = sum(map(len, rooms[:-1])) + int(free[0])
                break
        else:  # nowhere free: the least crowded place of all
            i = int(np.argmax(np.concatenate(rooms)))
        cx, cy = np.vstack(rings)[i]
        placed.append(Label(text, float(cx), float(cy), float(r), (float(ax), float(ay)), i != 0))
    return placed


def _room(
    cand: np.ndarray,
    anchor: tuple[float, float],
    r: float,
    a: np.ndarray,
    b: np.ndarray,
    marks: list[Mark],
    frame: tuple[float, float, float, float],
    placed: list[Label],
    gap: float,
) -> np.ndarray:
    """How far each candidate circle (centres ``cand``, radius ``r``, for the label at ``anchor``) is from the
    nearest thing it must not touch: the track's segments a[i]-b[i] and ``marks`` (``gap`` points clear), the
    frame and the labels already ``placed``; free where >= 0. Of the track, only the segments that can be nearest
    to a candidate are measured (:func:`near_segments`: the same minimum at a fraction of the work)."""
    ax, ay = anchor
    x0, y0, x1, y1 = frame
    near = near_segments(np.array([ax, ay]), float(np.hypot(cand[:, 0] - ax, cand[:, 1] - ay).max()), a, b)
    room = np.minimum(segment_distances(cand, a[near], b[near]), mark_room(cand, marks)) - r - gap
    room = np.minimum(room, np.minimum.reduce([cand[:, 0] - x0, x1 - cand[:, 0], cand[:, 1] - y0, y1 - cand[:, 1]]) - r)
    if placed:  # all placed labels at once: per element the same sums as one by one, and a minimum is exact
        px, py, pr = (np.array([getattr(lab, f) for lab in placed]) for f in ("x", "y", "r"))
        clear = np.hypot(cand[:, 0, None] - px[None, :], cand[:, 1, None] - py[None, :]) - r - pr[None, :] - gap
        room = np.minimum(room, clear.min(axis=1))
    return room


def leader(label: Label) -> np.ndarray:
    """The leader line of a moved label: from its anchor to the edge of its circle (2, 2)."""
    ax, ay = label.anchor
    d = np.hypot(label.x - ax, label.y - ay)
    f = max(d - label.r, 0.0) / max(d, 1e-9)
    return np.array([[ax, ay], [ax + f * (label.x - ax), ay + f * (label.y - ay)]])
