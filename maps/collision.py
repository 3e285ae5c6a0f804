"""Conservative collision checking of swept footprints on a rasterised obstacle grid (8.1e).

The collision grid has cells of size ``c = resolution / sub``; lattice points sit on cell
centres. A cell counts as *occupied by a footprint* when the footprint touches it and as
*blocked* when an obstacle touches it; both are found by testing the cell centre against the
geometry buffered by the half cell diagonal, which covers every touched cell. If a footprint
and an obstacle share a point, that point's cell is in both sets, so "no occupied cell is
blocked" implies "no intersection": the test is exact or conservative, never optimistic.

Footprints are rasterised once per (move, heading) as row intervals of cell offsets; the
validity of a move at every lattice point at once is a handful of prefix-sum look-ups.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry.base import BaseGeometry

from maps.geo import SeaMap


@dataclass
class Window:
    """The lattice: ``ni`` x ``nj`` points, point (i, j) at (x0 + i res, y0 + j res) (x north)."""

    x0: float
    y0: float
    res: float
    ni: int
    nj: int

    def point(self, i: int, j: int) -> tuple[float, float]:
        return self.x0 + i * self.res, self.y0 + j * self.res

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        return int(round((x - self.x0) / self.res)), int(round((y - self.y0) / self.res))

    def contains(self, i: int, j: int) -> bool:
        return 0 <= i < self.ni and 0 <= j < self.nj

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """Area the ship may use: the lattice's bounding box grown by half a cell."""
        h = self.res / 2
        return (self.x0 - h, self.y0 - h, self.x0 + (self.ni - 1) * self.res + h, self.y0 + (self.nj - 1) * self.res + h)


def rasterise(geom: BaseGeometry, c: float, origin: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (a, b) of the grid cells (centres origin + (a c, b c)) touched by ``geom``."""
    g = geom.buffer(c * np.sqrt(0.5) + 1e-6 * c)
    xmin, ymin, xmax, ymax = g.bounds
    a = np.arange(np.floor((xmin - origin[0]) / c), np.ceil((xmax - origin[0]) / c) + 1).astype(int)
    b = np.arange(np.floor((ymin - origin[1]) / c), np.ceil((ymax - origin[1]) / c) + 1).astype(int)
    aa, bb = np.meshgrid(a, b, indexing="ij")
    shapely.prepare(g)
    inside = shapely.contains_xy(g, origin[0] + aa * c, origin[1] + bb * c)
    return aa[inside], bb[inside]


def row_intervals(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cell offsets as (row, first, last) runs: rows of contiguous columns."""
    if len(a) == 0:
        return np.zeros((0, 3), int)
    order = np.lexsort((b, a))
    a, b = a[order], b[order]
    brk = np.flatnonzero((np.diff(a) != 0) | (np.diff(b) != 1)) + 1
    starts = np.concatenate([[0], brk])
    ends = np.concatenate([brk, [len(a)]]) - 1
    return np.column_stack([a[starts], b[starts], b[ends]])


def quarter_turns(rows: np.ndarray, k: int) -> np.ndarray:
    """Row intervals (:func:`row_intervals`) of the cells turned ``k`` quarter turns about the
    origin cell, the way ``affinity.rotate`` turns a geometry by ``k`` pi/2: (a, b) -> (-b, a).
    The cell grid is its own image under the turn, so the cells a geometry touches, turned, are
    the cells the turned geometry touches."""
    k %= 4
    if k == 0 or len(rows) == 0:
        return rows
    n = rows[:, 2] - rows[:, 1] + 1
    a = np.repeat(rows[:, 0], n)
    b = np.repeat(rows[:, 1] - np.cumsum(n) + n, n) + np.arange(int(n.sum()))
    for _ in range(k):
        a, b = -b, a
    return row_intervals(a, b)


class CollisionGrid:
    """Blocked cells of the window (obstacles and everything outside the window), padded."""

    def __init__(self, sea: SeaMap, window: Window, margin: float, sub: int, pad_m: float, blocked: np.ndarray | None = None):
        """``blocked``: the cells this constructor blocks for the same map and arguments, made before (read back from
        :mod:`maps.mapcache`: the same array); not given, they are made from the map (the cost measured there, in
        :mod:`maps.mapcache`'s docstring)."""
        self.window, self.sub = window, sub
        self.c = window.res / sub
        self.pad = int(np.ceil(pad_m / self.c)) + 2
        c, p = self.c, self.pad
        na = (window.ni - 1) * sub + 1 + 2 * p
        nb = (window.nj - 1) * sub + 1 + 2 * p
        self.origin = (window.x0 - p * c, window.y0 - p * c)
        if blocked is None or blocked.shape != (na, nb) or blocked.dtype != bool:
            blocked = self._blocked(sea, margin, na, nb)
        self.blocked = blocked
        # per cell: the column of the first blocked cell at or east of it in its row (nb if none), so
        # that whether a row interval [b0, b1] touches a blocked cell is one look-up: first[b0] <= b1
        cols = np.where(blocked, np.arange(nb, dtype=np.int32)[None, :], np.int32(nb))
        self.first = np.ascontiguousarray(np.minimum.accumulate(cols[:, ::-1], axis=1)[:, ::-1])

    def _blocked(self, sea: SeaMap, margin: float, na: int, nb: int) -> np.ndarray:
        """(na, nb) bool: the cells an obstacle grown by ``margin`` and half a cell's diagonal covers, and those
        reaching outside the window."""
        c, window = self.c, self.window
        xs = self.origin[0] + np.arange(na) * c
        ys = self.origin[1] + np.arange(nb) * c
        hd = c * np.sqrt(0.5) + 1e-6 * c
        # a cell whose centre is within hd of the window edge may reach outside: block it too
        xmin, ymin, xmax, ymax = window.bounds
        outside = (xs[:, None] < xmin + hd) | (xs[:, None] > xmax - hd) | (ys[None, :] < ymin + hd) | (ys[None, :] > ymax - hd)
        box = (xs[0] - hd - margin, ys[0] - hd - margin, xs[-1] + hd + margin, ys[-1] + hd + margin)
        obst = shapely.clip_by_rect(sea.no_go(), *box)
        blocked = outside.copy()
        if not obst.is_empty:
            g = obst.buffer(hd)
            shapely.prepare(g)
            sel = ~outside
            xx, yy = np.meshgrid(xs, ys, indexing="ij")
            blocked[sel] = shapely.contains_xy(g, xx[sel], yy[sel])
        return blocked

    def footprint_rows(self, footprint: BaseGeometry, psi: float, grow: float) -> np.ndarray:
        """Row intervals of cells a footprint (start-pose frame) touches when started at heading psi."""
        g = affinity.rotate(footprint, psi, origin=(0, 0), use_radians=True)
        if grow > 0:
            g = g.buffer(grow)
        a, b = rasterise(g, self.c)
        return row_intervals(a, b)

    def valid_everywhere(self, rows: np.ndarray) -> np.ndarray:
        """(ni, nj) bool: the move's footprint touches no blocked cell from each lattice point."""
        w, s, p = self.window, self.sub, self.pad
        nb = self.first.shape[1]
        if len(rows) and (rows[:, 0].min() < -p or rows[:, 0].max() >= p or rows[:, 1].min() < -p or rows[:, 2].max() >= p):
            raise ValueError("footprint larger than the collision grid padding")
        ii, jj = np.divmod(np.arange(w.ni * w.nj), w.nj)
        cell = (p + ii * s) * nb + p + jj * s  # flat index of each lattice point's cell
        col = p + jj * s
        flat = self.first.ravel()
        alive = np.arange(w.ni * w.nj)  # lattice points not yet found blocked: only those are looked up further
        rows = rows.astype(np.int64)
        for k in range(0, len(rows), 64):
            if not len(alive):
                break
            a, b0, b1 = (rows[k : k + 64, i : i + 1] for i in range(3))
            hit = (flat[cell[alive][None, :] + (a * nb + b0)] <= col[alive][None, :] + b1).any(axis=0)
            alive = alive[~hit]
        ok = np.zeros(w.ni * w.nj, bool)
        ok[alive] = True
        return ok.reshape(w.ni, w.nj)
