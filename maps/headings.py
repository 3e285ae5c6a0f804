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


HEADING_NOTICE_DEG = 0.05  # half the 0.1 deg a heading is given and printed in


def heading_rounding_warning(psi: float, lattice_psi: float) -> str | None:
    """The warning that the start heading ``psi`` (rad) was moved to the lattice heading
    ``lattice_psi`` (rad), or None when they differ by less than HEADING_NOTICE_DEG: the resume
    example's --from 116.6 against the lattice's atan(2) + 90 deg = 116.565 deg warned 'rounded 116.6
    to 116.6 deg', a rounding below any compass's resolution."""
    d = float(np.degrees(abs(wrap(psi - lattice_psi))))
    if d < HEADING_NOTICE_DEG:
        return None
    return (
        f"start heading {np.degrees(psi):.1f} deg rounded to the lattice heading {np.degrees(lattice_psi):.1f} deg ({d:.1f} deg)"
    )
