"""Lattice headings (Ljungberg 2022, section 8.2): the table of headings a lattice state can have and
the nearest one to a course."""

from __future__ import annotations

import numpy as np


def heading_table(n_head: int) -> np.ndarray:
    """Lattice headings (rad, clockwise from north). 4: every 90 deg; 8: every 45 deg; 16: the
    directions of the grid vectors (1,0), (2,1), (1,1), (1,2), ... (non-uniform, as Nav2's state
    lattice does) so that straight runs end on lattice points."""
    if n_head not in (4, 8, 16):
        raise ValueError(f"headings must be 4, 8 or 16, got {n_head}")
    first = {4: [0.0], 8: [0.0, np.pi / 4], 16: [0.0, np.arctan2(1, 2), np.pi / 4, np.arctan2(2, 1)]}[n_head]
    return np.array([a + q * np.pi / 2 for q in range(4) for a in first])


def nearest_heading(psi: float, table: np.ndarray) -> int:
    """Index of the heading of ``table`` closest to ``psi`` (radians, across the wrap)."""
    return int(np.argmin(np.abs((table - psi + np.pi) % (2 * np.pi) - np.pi)))


def wrap(a: float) -> float:
    """An angle wrapped to [-pi, pi)."""
    return float((a + np.pi) % (2 * np.pi) - np.pi)
