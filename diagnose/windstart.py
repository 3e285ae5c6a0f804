"""Where the refit of a steady wind that was not recorded starts (issue 26).

Its loads are far from linear in the air velocity: at no wind only the cross term of the ship's
own speed and the wind acts, so the linearised step of the search's screen says little about the
wind's direction, and a refit from it can settle in the wrong quadrant. A coarse grid over the
direction it comes from (every 30 deg) and a few speeds, scored in one batched simulation with
the line start of the screen among them, gives the refit its start.
"""

from __future__ import annotations

import numpy as np

from diagnose.model import AugmentedModel, Prepared, residuals, stack
from diagnose.plausible import froude

GRID_FROM_DEG = np.arange(0.0, 360.0, 30.0)
GRID_SPEED_REF_MPS = (6.0, 12.0, 18.0)  # for the 320 m tanker, Froude-scaled like the plausibility limits


def grid_start(model: AugmentedModel, preps: list[Prepared], w: list, start: np.ndarray, slots: list[int]) -> np.ndarray:
    """``start`` with the steady wind's (north, east) ``slots`` set to the best of the grid and of
    their own values, by the weighted residual of the runs ``preps``."""
    a = np.radians(GRID_FROM_DEG)
    spd = np.asarray(GRID_SPEED_REF_MPS) * froude(model.profile)
    s, g = np.meshgrid(spd, a, indexing="ij")
    toward = np.column_stack([-(s * np.cos(g)).ravel(), -(s * np.sin(g)).ravel()])  # air velocity toward, from "from"
    Pb = np.repeat(start[None], len(toward) + 1, axis=0)
    Pb[1:, slots] = toward
    R = stack(residuals(model, preps, Pb), w)
    return Pb[int(np.argmin(np.einsum("ij,ij->i", R, R)))]
