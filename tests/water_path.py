"""The shortest path through water between two points, computed independently of the planner:
Dijkstra (networkx) on the visibility graph of the two points and the no-go polygons' vertices,
shapely for the line-of-sight tests. A point path: a lower bound of any hull's path."""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely


def shortest_water_path(no_go, extent: tuple[float, float, float, float], a, b) -> float:
    """Length (m) of the shortest path from a to b (x, y) inside ``extent`` that keeps out of ``no_go``."""
    x0, y0, x1, y1 = extent
    water = shapely.box(x0, y0, x1, y1).difference(no_go).buffer(1e-3)
    shapely.prepare(water)
    nodes = [tuple(map(float, a[:2])), tuple(map(float, b[:2]))]
    for poly in getattr(no_go, "geoms", [no_go]):
        for ring in [poly.exterior, *poly.interiors] if hasattr(poly, "exterior") else []:
            nodes += [tuple(c) for c in np.asarray(ring.coords)[:-1]]
    g = nx.Graph()
    g.add_nodes_from(range(len(nodes)))
    for i, p in enumerate(nodes):
        for j in range(i + 1, len(nodes)):
            q = nodes[j]
            if water.contains(shapely.LineString([p, q])):
                g.add_edge(i, j, weight=float(np.hypot(q[0] - p[0], q[1] - p[1])))
    return float(nx.shortest_path_length(g, 0, 1, weight="weight"))


def transit_lengths(plan, sea, length_m: float) -> list[tuple[int, float, float, float]]:
    """(step index, length sailed, shortest path through water, the issue 28 bound: 1.3 x the
    shortest path + one full turn 2 pi x 1.5 L + two ship lengths) of every transit step of ``plan``."""
    doc = plan.to_dict()
    s, steps = doc["samples"], doc["steps"]
    x, y, step = np.array(s["x"]), np.array(s["y"]), np.array(s["step"])
    no_go = sea.no_go()
    out = []
    for i, st in enumerate(steps):
        if st["segment"] != "transit":
            continue
        sel = step == st["index"]
        xs, ys = x[sel], y[sel]
        if i + 1 < len(steps):  # to the next step's entry point
            xs, ys = np.r_[xs, steps[i + 1]["entry_x"]], np.r_[ys, steps[i + 1]["entry_y"]]
        sailed = float(np.hypot(np.diff(xs), np.diff(ys)).sum())
        path = shortest_water_path(no_go, sea.extent, (xs[0], ys[0]), (xs[-1], ys[-1]))
        out.append((int(st["index"]), sailed, path, 1.3 * path + 2 * np.pi * 1.5 * length_m + 2 * length_m))
    return out
