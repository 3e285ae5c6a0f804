"""A current measured, not inferred: the ship's velocity over ground (track, GNSS) against its
velocity through the water (a log: columns ``u_water`` and, from a two-axis log, ``v_water``).

Their difference is the current in body axes (the README's conventions: u_r = u - u_c); a
current constant in the earth frame, (c_n, c_e), gives

    u - u_water = cos(psi) c_n + sin(psi) c_e,   v - v_water = -sin(psi) c_n + cos(psi) c_e,

solved by least squares over every sample of every run (a longitudinal log alone needs the
heading to turn). Its std is the least-squares one with the residuals' scatter, the sample
count cut to an effective one by their lag-one correlation (Bartlett 1946): a log's error is
slow. Without a speed through the water the current is only a misfit that rotates with the
heading, which a model error can mimic: :func:`from_track_alone` says when that is all there is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MeasuredCurrent:
    """A current from the track and the speed through the water (earth frame, toward)."""

    north: float  # m/s
    east: float  # m/s
    std: float  # m/s, of each component
    samples: int
    runs: list[str]

    @property
    def speed(self) -> float:
        return float(np.hypot(self.north, self.east))

    @property
    def toward_deg(self) -> float:
        return float(np.degrees(np.arctan2(self.east, self.north)) % 360.0)

    def text(self) -> str:
        return (
            f"current measured from the track against the speed through the water ({', '.join(self.runs)}): "
            f"{self.speed:.2f} +- {self.std:.2f} m/s toward {self.toward_deg:.0f} deg"
        )


def _effective(res: np.ndarray) -> float:
    """The number of independent samples in a residual series (lag-one correlation rho): n (1 - rho) / (1 + rho)."""
    r = res - res.mean()
    den = float(r @ r)
    rho = float(np.clip(r[1:] @ r[:-1] / den, 0.0, 0.99)) if den > 0 else 0.0
    return len(r) * (1.0 - rho) / (1.0 + rho)


def measure(recordings: list) -> MeasuredCurrent | None:
    """The current of the recordings that hold ``u_water`` (module docstring); None without one,
    or when the heading does not turn enough to tell north from east with a longitudinal log."""
    rows, rhs, runs = [], [], []
    for rec in recordings:
        uw = rec.channels.get("u_water")
        if uw is None:
            continue
        c, s = np.cos(rec.psi), np.sin(rec.psi)
        parts = [(np.stack([c, s], -1), rec.y[:, 0] - uw)]
        vw = rec.channels.get("v_water")
        if vw is not None:
            parts.append((np.stack([-s, c], -1), rec.y[:, 1] - vw))
        for A, b in parts:
            ok = np.isfinite(b)
            rows.append(A[ok])
            rhs.append(b[ok])
        runs.append(rec.source)
    if not rows:
        return None
    A, b = np.concatenate(rows), np.concatenate(rhs)
    G = A.T @ A
    if np.linalg.cond(G) > 1e6:
        return None
    x = np.linalg.solve(G, A.T @ b)
    res = b - A @ x
    n_eff = sum(_effective(bb - aa @ x) for aa, bb in zip(rows, rhs))
    var = float(res @ res) / max(len(res) - 2, 1) * len(res) / max(n_eff, 1.0)
    std = float(np.sqrt(var * np.max(np.diag(np.linalg.inv(G)))))
    return MeasuredCurrent(float(x[0]), float(x[1]), std, len(b), runs)


def from_track_alone(recordings: list) -> bool:
    """Every run's u, v were derived from its track (no u, v columns: header-less GNSS logs, model
    tests' carriage tracks) and none records a speed through the water: a current is then a misfit
    rotating with the heading, which a model error can mimic, and cannot be told from one."""
    return bool(recordings) and all(
        r.meta.get("velocities") == "derived from the track" and "u_water" not in r.channels for r in recordings
    )
