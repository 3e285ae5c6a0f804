"""Open-water curves of a Wageningen B-series propeller.

K_T and K_Q are the polynomials of Oosterveld & van Oossanen (1975), "Further computer-analyzed
data of the Wageningen B-screw series", Int. Shipbuilding Progress 22 (251), Table 1 (Re = 2e6):
K = sum C (J)^s (P/D)^t (A_E/A_0)^u Z^v. Rows here: (C, s, t, u, v).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KT_TERMS = np.array(
    [
        (0.00880496, 0, 0, 0, 0), (-0.204554, 1, 0, 0, 0), (0.166351, 0, 1, 0, 0), (0.158114, 0, 2, 0, 0),
        (-0.147581, 2, 0, 1, 0), (-0.481497, 1, 1, 1, 0), (0.415437, 0, 2, 1, 0), (0.0144043, 0, 0, 0, 1),
        (-0.0530054, 2, 0, 0, 1), (0.0143481, 0, 1, 0, 1), (0.0606826, 1, 1, 0, 1), (-0.0125894, 0, 0, 1, 1),
        (0.0109689, 1, 0, 1, 1), (-0.133698, 0, 3, 0, 0), (0.00638407, 0, 6, 0, 0), (-0.00132718, 2, 6, 0, 0),
        (0.168496, 3, 0, 1, 0), (-0.0507214, 0, 0, 2, 0), (0.0854559, 2, 0, 2, 0), (-0.0504475, 3, 0, 2, 0),
        (0.010465, 1, 6, 2, 0), (-0.00648272, 2, 6, 2, 0), (-0.00841728, 0, 3, 0, 1), (0.0168424, 1, 3, 0, 1),
        (-0.00102296, 3, 3, 0, 1), (-0.0317791, 0, 3, 1, 1), (0.018604, 1, 0, 2, 1), (-0.00410798, 0, 2, 2, 1),
        (-0.000606848, 0, 0, 0, 2), (-0.0049819, 1, 0, 0, 2), (0.0025983, 2, 0, 0, 2), (-0.000560528, 3, 0, 0, 2),
        (-0.00163652, 1, 2, 0, 2), (-0.000328787, 1, 6, 0, 2), (0.000116502, 2, 6, 0, 2), (0.000690904, 0, 0, 1, 2),
        (0.00421749, 0, 3, 1, 2), (0.0000565229, 3, 6, 1, 2), (-0.00146564, 0, 3, 2, 2),
    ]
)  # fmt: skip
KQ_TERMS = np.array(
    [
        (0.00379368, 0, 0, 0, 0), (0.00886523, 2, 0, 0, 0), (-0.032241, 1, 1, 0, 0), (0.00344778, 0, 2, 0, 0),
        (-0.0408811, 0, 1, 1, 0), (-0.108009, 1, 1, 1, 0), (-0.0885381, 2, 1, 1, 0), (0.188561, 0, 2, 1, 0),
        (-0.00370871, 1, 0, 0, 1), (0.00513696, 0, 1, 0, 1), (0.0209449, 1, 1, 0, 1), (0.00474319, 2, 1, 0, 1),
        (-0.00723408, 2, 0, 1, 1), (0.00438388, 1, 1, 1, 1), (-0.0269403, 0, 2, 1, 1), (0.0558082, 3, 0, 1, 0),
        (0.0161886, 0, 3, 1, 0), (0.00318086, 1, 3, 1, 0), (0.015896, 0, 0, 2, 0), (0.0471729, 1, 0, 2, 0),
        (0.0196283, 3, 0, 2, 0), (-0.0502782, 0, 1, 2, 0), (-0.030055, 3, 1, 2, 0), (0.0417122, 2, 2, 2, 0),
        (-0.0397722, 0, 3, 2, 0), (-0.00350024, 0, 6, 2, 0), (-0.0106854, 3, 0, 0, 1), (0.00110903, 3, 3, 0, 1),
        (-0.000313912, 0, 6, 0, 1), (0.0035985, 3, 0, 1, 1), (-0.00142121, 0, 6, 1, 1), (-0.00383637, 1, 0, 2, 1),
        (0.0126803, 0, 2, 2, 1), (-0.00318278, 2, 3, 2, 1), (0.00334268, 0, 6, 2, 1), (-0.00183491, 1, 1, 0, 2),
        (0.000112451, 3, 2, 0, 2), (-0.0000297228, 3, 6, 0, 2), (0.000269551, 1, 0, 1, 2), (0.00083265, 2, 0, 1, 2),
        (0.00155334, 0, 2, 1, 2), (0.000302683, 0, 6, 1, 2), (-0.0001843, 0, 0, 2, 2), (-0.000425399, 0, 3, 2, 2),
        (0.0000869243, 3, 3, 2, 2), (-0.0004659, 0, 6, 2, 2), (0.0000554194, 1, 6, 2, 2),
    ]
)  # fmt: skip


@dataclass(frozen=True)
class BSeries:
    """A B-series screw: pitch ratio P/D, expanded area ratio A_E/A_0, blade count Z."""

    pitch_ratio: float = 0.75
    area_ratio: float = 0.55
    blades: int = 4

    def _poly(self, terms: np.ndarray, j: np.ndarray | float) -> np.ndarray:
        j = np.asarray(j, float)[..., None]
        c, s, t, u, v = terms.T
        return np.sum(c * j**s * self.pitch_ratio**t * self.area_ratio**u * float(self.blades) ** v, axis=-1)

    def kt(self, j: np.ndarray | float) -> np.ndarray:
        """Thrust coefficient K_T(J) = T / (rho n^2 D^4)."""
        return self._poly(KT_TERMS, j)

    def kq(self, j: np.ndarray | float) -> np.ndarray:
        """Torque coefficient K_Q(J) = Q / (rho n^2 D^5)."""
        return self._poly(KQ_TERMS, j)

    def quadratic_fit(self, j_max: float | None = None) -> tuple[float, float, float]:
        """(k0, k1, k2) of K_T ~ k0 + k1 J + k2 J^2 over 0 <= J <= 0.9 x the zero-thrust J: the form
        the MMG propeller model takes (Yasukawa & Yoshimura 2015, eq. 15)."""
        j0 = self.zero_thrust_j() if j_max is None else j_max
        j = np.linspace(0.0, 0.9 * j0, 40)
        k2, k1, k0 = np.polyfit(j, self.kt(j), 2)
        return float(k0), float(k1), float(k2)

    def zero_thrust_j(self) -> float:
        lo, hi = 0.0, 2.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.kt(mid) > 0 else (lo, mid)
        return 0.5 * (lo + hi)
