"""Split a record at an operating-point change and cross-validate (Källström 1977, Tables 3.5-3.8).

Each part is identified on its own (OE and ML); then each part's models are simulated with the other part's
rudder, the dynamics and the delay held and only the nuisance parameters (rudder offset, gyro bias, initial
state and, when the models carry it, the heading-dependent wind) fitted by output error, as in Källström's
Table 3.8. The model that generalises best to the other part has the lowest AIC there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.steering.api import ESTIMATORS, first_reading, fit_model, yaw_rate
from identify.steering.estimate import Fit, SteeringData, fit


@dataclass
class CrossRow:
    """One row of the cross-validation table: whose model, on which part's data, its OE fit of the nuisance."""

    data_part: int
    model_part: int
    estimator: str
    fit: Fit | None
    failure: str = ""


def split_record(d: SteeringData, start_s: float, end_s: float | None = None) -> tuple[SteeringData, SteeringData]:
    """Part 1 before ``start_s``, part 2 from ``end_s`` (default ``start_s``): the window between (the course
    change, in Källström's experiment 1: 1158-1732 s) is left out of both."""
    i1, i2 = split_indices(d.t, start_s, start_s if end_s is None else end_s)
    return d.window(0, i1), d.window(i2, len(d.t))


def split_indices(t: np.ndarray, start_s: float, end_s: float) -> tuple[int, int]:
    """The end of part 1 and the start of part 2 in the time stamps ``t``."""
    return int(np.searchsorted(t, start_s)), int(np.searchsorted(t, end_s))


def _nuisance_start(f: Fit, d: SteeringData) -> dict[str, float]:
    p = dict(f.p)
    roles = {q.name: q.role for q in f.structure.params}
    for k in list(p):
        if roles.get(k) == "initial":
            p[k] = 0.0
    p["r_0"] = first_reading(yaw_rate(d))
    if "psi" in d.channels:
        p["psi_0"] = first_reading(d.y[:, d.channels.index("psi")])
    return p


def cross_validate(
    parts: tuple[SteeringData, SteeringData], L: float, V: float, model: str = "nomoto2", wind: bool = False
) -> tuple[dict[tuple[int, str], Fit], list[CrossRow]]:
    """Fits of each part by each estimator, and the four cross rows of Table 3.8. ``wind``: the parts' models
    carry the heading-dependent wind (nomoto2, state-space) and the cross rows refit it with the other nuisance
    parameters: a wind is the other part's weather, not the ship's dynamics (Källström's Table 3.8 refits it)."""
    fits = {(i + 1, e): fit_model(parts[i], L, V, model, e, wind=wind) for i in range(2) for e in ESTIMATORS}
    rows = []
    for data_part, model_part in ((2, 1), (1, 2)):
        d = parts[data_part - 1]
        for e in ESTIMATORS:
            src = fits[(model_part, e)]
            if not src.converged:
                rows.append(CrossRow(data_part, model_part, e, None, "the part's own fit did not converge"))
                continue
            roles = {q.name: q.role for q in src.structure.params}
            held = tuple(k for k, r in roles.items() if r in ("dynamics", "delay", "noise"))
            sub = src.structure.channels
            data = (
                d if d.channels == sub else SteeringData(d.t, d.delta, d.y[:, [d.channels.index(c) for c in sub]], sub, d.source)
            )
            f = fit(src.structure, data, _nuisance_start(src, data), "oe", fixed=held)
            rows.append(CrossRow(data_part, model_part, e, f, "" if f.converged else f"did not converge ({f.message})"))
    return fits, rows
