"""The smallest steering record: a first-order Nomoto response to a square-wave rudder, for the steering command's
input checks (tests/test_bad_input.py, tests/test_steering_cli.py), not for its accuracy (tests/physics/sea_splendour.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def square_wave_record(duration_s: float = 600.0, dt: float = 2.0) -> dict[str, np.ndarray]:
    """t, delta (+-10 deg, period 200 s), r and psi of Nomoto's first-order model T dr/dt + r = K delta (K = -0.05
    1/s, T = 60 s), stepped by forward Euler at ``dt``, and psi its integral from 0."""
    t = np.arange(0.0, duration_s, dt)
    delta = np.radians(10.0) * np.sign(np.sin(2 * np.pi * t / 200.0) + 1e-9)
    r = np.zeros_like(t)
    for k in range(1, len(t)):
        r[k] = r[k - 1] + dt * (-0.05 * delta[k - 1] - r[k - 1]) / 60.0
    psi = np.concatenate([[0.0], np.cumsum(dt * r[:-1])])
    return {"t": t, "delta": delta, "r": r, "psi": psi}


def write_record(path: Path, cols: dict[str, np.ndarray]) -> Path:
    """``cols`` as a steering CSV (a header of the column names, 9 significant digits)."""
    n = len(next(iter(cols.values())))
    path.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{cols[k][i]:.9g}" for k in cols) for i in range(n)) + "\n")
    return path
