"""Physical parameters of a kept candidate, with standard deviations (never NaN: None instead)."""

from __future__ import annotations

import numpy as np

from diagnose.candidates import Candidate, canonical_term, thrust_signal
from diagnose.model import AugmentedModel
from primitives.ship import DOFS


def _sd(cov: np.ndarray, pos: list[int]) -> list[float | None]:
    if not len(cov):
        return [None] * len(pos)
    d = np.diag(cov)[pos]
    return [float(np.sqrt(x)) if np.isfinite(x) and x >= 0 else None for x in d]


def surge_base_index(model: AugmentedModel, term: str) -> int | None:
    """Position of the baseline surge term ``term`` in P (None when the model has none)."""
    return next((k for k, (i, t, *_r) in enumerate(model.base) if i == 0 and t == term), None)


def describe(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, free: list[int]) -> dict:
    """Physical parameters of candidate ``c`` at P (keys fixed by the issue)."""
    idx = model.slot_of[c.key]
    pos = [free.index(j) for j in idx]
    sd = _sd(cov, pos)
    vals = P[idx]
    prof = model.profile
    if c.effect == "current":
        cn, ce = vals
        spd = float(np.hypot(cn, ce))
        out = {"speed_mps": spd, "toward_deg": float(np.degrees(np.arctan2(ce, cn)) % 360.0), "north_mps": float(cn),
               "east_mps": float(ce)}
        if len(cov):
            sub = cov[np.ix_(pos, pos)]
            g_s = np.array([cn, ce]) / max(spd, 1e-12)
            g_d = np.array([-ce, cn]) / max(spd**2, 1e-12)
            if np.all(np.isfinite(sub)):
                out["speed_std"] = float(np.sqrt(max(g_s @ sub @ g_s, 0)))
                out["toward_std_deg"] = float(np.degrees(np.sqrt(max(g_d @ sub @ g_d, 0))))
        return out
    if c.effect == "actuator_delay":
        d = float(vals[0]) + model.half_sample
        return {"delay_s": d, "delay_std": sd[0], "samples": d / prof.sample_time,
                "model_shift_s": float(vals[0]), "half_sample_s": model.half_sample}
    if c.effect == "input_offset":
        name = prof.inputs[c.slots[0].index]
        out = {"input": name, "offset": float(vals[0]), "offset_std": sd[0]}
        if name in ("delta",) or name.startswith("alpha"):
            out["offset_deg"] = float(np.degrees(vals[0]))
        return out
    if c.effect == "sensor_bias":
        return {"signal": "uvr"[c.slots[0].index], "bias": float(vals[0]), "bias_std": sd[0]}
    if c.effect in ("quadratic_damping", "missing_coupling"):
        out = {"term": c.slots[0].term, "value": float(vals[0]), "value_std": sd[0], "dof": DOFS[c.dof]}
        key = canonical_term(c.slots[0].term)  # a change of a term the model has: also relative to it
        j = next((k for k, (i, t, *_r) in enumerate(model.base) if i == c.dof and canonical_term(t) == key), None)
        if j is not None and P[j] != 0:
            out["change_percent"] = 100.0 * float(vals[0] / P[j])
        return out
    if c.slots[0].kind == "thrust":
        f = float(vals[0])
        return {"loss_percent": 100.0 * f, "loss_percent_std": None if sd[0] is None else 100.0 * sd[0],
                "loss_fraction": f, "terms": [model.base[k][1] for k in model.thrust_terms],
                "rudder_terms": [f"{DOFS[model.base[k][0]]}:{model.base[k][1]}" for k in model.rudder_terms],
                "rudder_thrust_share": float(model.thrust_share(P, model.slot_of[c.key][0])[0]),
                "rudder_force_change_percent": -100.0 * float(model.thrust_share(P, model.slot_of[c.key][0])[0]) * f}
    if c.effect in ("resistance_change", "thrust_loss") and c.key != "thrust_loss":
        term = c.slots[0].term
        j = surge_base_index(model, term)
        base = float(P[j]) if j is not None else 0.0
        frac = float(vals[0] / base) if base else None
        out = {"term": term, "coefficient": float(vals[0]), "coefficient_std": sd[0]}
        if c.effect == "thrust_loss":
            out["loss_percent"] = None if frac is None else -100.0 * frac
        else:
            out["resistance_change_pct"] = None if frac is None else 100.0 * frac
        return out
    if c.effect == "thrust_loss":
        tsig = thrust_signal(prof)
        j = surge_base_index(model, tsig)
        out = {"coefficient": float(vals[0]), "coefficient_std": sd[0], "term": c.slots[0].term}
        if j is not None and P[j] != 0 and tsig == "tau_x":
            out["thrust_loss_per_mps"] = float(-vals[0] / P[j])
            out["thrust_change_at_cruise"] = float(vals[0] * prof.cruise_speed_mps / P[j])
        return out
    if c.effect == "inertia_change":
        s = float(vals[0])
        return {"scale": s, "scale_std": sd[0], "inertia_ratio": float(1.0 / (1.0 + s)) if s > -1 else None, "dof": DOFS[c.dof]}
    return {s.name: float(v) for s, v in zip(c.slots, vals)} | {f"{s.name}_std": e for s, e in zip(c.slots, sd)}
