"""Orders a crew can follow: helm, engine, azimuth and generalized-force orders of a primitive.

An :class:`Order` is one instruction at ``t_s`` seconds after the execute point, in the ship's
own terms (``text``) and machine-readable (``values``). The order list of a primitive is a
faithful description of its input sequence: :func:`inputs_from_orders` rebuilds the inputs
from the orders and the profile's limits (rudder rate, engine rate), and the tests check that
this reproduces every primitive of every bundled profile.

Value keys (all optional; an order carries the ones it changes):

- ``rudder_deg``: ordered rudder angle, + starboard, - port (sailor's sign, not the model's);
  the rudder moves there at the profile's rudder rate.
- ``n_rps``, ``n_rpm``, ``mcr_pct``: ordered propeller speed (and % MCR when the profile knows
  the MCR rpm); the shaft follows at the profile's engine rate when it has one.
- azimuth ships: ``n<i>_rps``, ``n<i>_rpm`` and ``alpha<i>_deg`` per thruster i (thrust
  direction, + toward starboard, 0 = ahead).
- generalized-force ships: the profile's inputs by name (``tau_x``, ``tau_y``, ``tau_n``).
- ``ramp_s``: change the values steadily from the present ones to the ordered ones over this
  many seconds (0 or absent: at once).
- ``at_heading_change_deg``: the order is given when the heading has changed by this much from
  the initial course (+ starboard); ``t_s`` is when that happens on the nominal model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from primitives.ship import ShipProfile


@dataclass(frozen=True)
class Order:
    """One order: seconds after the execute point, the sailor's words, machine-readable values."""

    t_s: float
    text: str
    values: dict[str, float] = field(default_factory=dict, hash=False)  # hashable by (t_s, text)

    def to_dict(self) -> dict[str, Any]:
        """``{"t_s", "text", **values}`` (the form plan steps and exports carry)."""
        return {"t_s": self.t_s, "text": self.text, **self.values}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Order:
        return cls(float(d["t_s"]), str(d["text"]), {k: float(v) for k, v in d.items() if k not in ("t_s", "text")})


def on_course(order: Order, heading0_deg: float) -> Order:
    """The order with its heading condition in absolute terms for an execute heading
    ``heading0_deg``: 'Port 20 at heading 20° to starboard of the initial course' on course 350°
    becomes 'Port 20 at heading 010°'. Orders without a heading condition come back unchanged."""
    change = order.values.get("at_heading_change_deg")
    if change is None:
        return order
    phrase = f" at {heading_words(change)}"
    absolute = f" at heading {(heading0_deg + change) % 360:03.0f}°"
    return Order(order.t_s, order.text.replace(phrase, absolute), dict(order.values))


def orders_to_dicts(orders: list[Order]) -> list[dict[str, Any]]:
    return [o.to_dict() for o in orders]


def render(orders: list[Order]) -> list[str]:
    """One-line summaries ``"t+12 s: Port 20"`` (what ``Primitive.commands`` shows)."""
    return [f"t+{o.t_s:.0f} s: {o.text}" for o in orders]


# -- words -------------------------------------------------------------------------------------


def rudder_text(rudder_deg: float, max_deg: float | None = None) -> str:
    """'Starboard 20', 'Port 10', 'Midships', 'Hard a-starboard (35°)'."""
    a = abs(rudder_deg)
    if a < 0.05:
        return "Midships"
    side = "starboard" if rudder_deg > 0 else "port"
    if max_deg is not None and a >= max_deg - 0.05:
        return f"Hard a-{side} ({a:.0f}°)"
    return f"{side.capitalize()} {a:.3g}"


def heading_words(change_deg: float) -> str:
    """'heading 10° to starboard of the initial course'."""
    if abs(change_deg) < 0.05:
        return "on the initial course"
    side = "starboard" if change_deg > 0 else "port"
    return f"heading {abs(change_deg):.0f}° to {side} of the initial course"


def engine_values(profile: ShipProfile, n_rps: float) -> dict[str, float]:
    vals = {"n_rps": float(n_rps), "n_rpm": float(60.0 * n_rps)}
    if profile.engine.mcr_rpm:
        vals["mcr_pct"] = float(100.0 * (abs(60.0 * n_rps) / profile.engine.mcr_rpm) ** 3)
    return vals


def engine_text(profile: ShipProfile, n_rps: float) -> str:
    """'Engine 116 rpm', 'Engine 60 rpm (75 % MCR)', 'Stop engine', 'Engine astern 40 rpm'."""
    rpm = 60.0 * n_rps
    if abs(rpm) < 0.5:
        return "Stop engine"
    words = f"Engine {rpm:.0f} rpm" if rpm > 0 else f"Engine astern {-rpm:.0f} rpm"
    if profile.engine.mcr_rpm:
        words += f" ({engine_values(profile, n_rps)['mcr_pct']:.0f} % MCR)"
    return words


def _azimuth_words(profile: ShipProfile, row: np.ndarray) -> tuple[str, dict[str, float]]:
    parts, vals = [], {}
    for i, th in enumerate(profile.thrusters, start=1):
        n, a = float(row[2 * i - 2]), float(row[2 * i - 1])
        deg = float(np.degrees(a))
        vals.update({f"n{i}_rps": n, f"n{i}_rpm": 60.0 * n, f"alpha{i}_deg": deg})
        if abs(n) < 1e-9:
            parts.append(f"Azimuth {i} ({th.name}): stop")
            continue
        side = "ahead" if abs(deg) < 0.5 else (f"{abs(deg):.0f}° stbd" if deg > 0 else f"{abs(deg):.0f}° port")
        parts.append(f"Azimuth {i} ({th.name}): {side}, {60.0 * n:.0f} rpm")
    return "; ".join(parts), vals


_FORCE_WORDS = {
    "tau_x": ("thrust", "ahead", "astern"),
    "tau_y": ("side force", "to starboard", "to port"),
    "tau_n": ("turning moment", "to starboard", "to port"),
}


def _generalized_words(profile: ShipProfile, row: np.ndarray) -> tuple[str, dict[str, float]]:
    parts, vals = [], {}
    for name, x in zip(profile.inputs, row):
        vals[name] = float(x)
        label, pos, neg = _FORCE_WORDS.get(name, (name, "+", "-"))
        lo, hi = profile.input_limits.get(name, (-np.inf, np.inf))
        lim = hi if x >= 0 else -lo
        if abs(x) <= 1e-9 * max(abs(lo), abs(hi), 1.0):
            parts.append(f"{label} 0")
        elif np.isfinite(lim) and lim > 0:
            parts.append(f"{label} {100 * abs(x) / lim:.0f} % of max {pos if x > 0 else neg}")
        else:
            parts.append(f"{label} {abs(x):.4g} {pos if x > 0 else neg}")
    return "; ".join(parts).capitalize(), vals


def setting_order(profile: ShipProfile, t_s: float, row: np.ndarray, ramp_s: float = 0.0) -> Order:
    """The order that sets every input to ``row`` (azimuth and generalized-force ships)."""
    if profile.actuator == "azimuth":
        text, vals = _azimuth_words(profile, row)
    else:
        text, vals = _generalized_words(profile, row)
    if ramp_s > 0:
        vals["ramp_s"] = float(ramp_s)
        text = f"Over {ramp_s:.0f} s change steadily to: {text}"
    return Order(float(t_s), text, vals)


# -- orders <-> inputs ------------------------------------------------------------------------


def input_tolerance(profile: ShipProfile, inputs: np.ndarray) -> np.ndarray:
    """Per-input tolerance of an order description: 0.5 % of the input's range (its limits, else
    its data), and at most 5 % of how much the input moves in this manoeuvre, so a small helm
    excursion is still described."""
    tol = []
    for i, name in enumerate(profile.inputs):
        moved = float(np.ptp(inputs[:, i])) if len(inputs) else 0.0
        lo, hi = profile.input_limits.get(name, (np.nan, np.nan))
        span = hi - lo if np.isfinite(hi - lo) else moved
        tol.append(max(min(5e-3 * span, 0.05 * moved), 1e-9 * max(span, 1.0)))
    return np.array(tol)


def _segments(x: np.ndarray, tol: np.ndarray) -> list[int]:
    """Breakpoints b0 = 0 < ... < N-1 such that x is linear between neighbours within tol."""
    n = len(x)
    cuts, b = [0], 0
    while b < n - 1:
        e = b + 1
        while e + 1 < n:
            k = np.arange(b, e + 2)
            line = x[b] + (x[e + 1] - x[b]) * ((k - b) / (e + 1 - b))[:, None]
            if np.any(np.abs(line - x[b : e + 2]) > tol):
                break
            e += 1
        cuts.append(e)
        b = e
    return cuts


def orders_from_inputs(profile: ShipProfile, inputs: np.ndarray) -> list[Order]:
    """Orders describing a sampled input sequence of an azimuth or generalized-force ship:
    one setting at t = 0, a step where the inputs jump, a steady change (``ramp_s``) where they
    move linearly; held values need no order."""
    x = np.asarray(inputs, float)
    if not len(x):
        return []
    # half the tolerance for the line fit, half for holding a value that drifts within it
    ts, tol = profile.sample_time, 0.5 * input_tolerance(profile, x)
    cuts = _segments(x, tol)
    orders = [setting_order(profile, 0.0, x[0])]
    held = x[0]
    for a, b in zip(cuts[:-1], cuts[1:]):
        if np.all(np.abs(x[a : b + 1] - held) <= tol):
            continue
        if b == a + 1:
            orders.append(setting_order(profile, b * ts, x[b]))
        else:
            orders.append(setting_order(profile, a * ts, x[b], ramp_s=(b - a) * ts))
        held = x[b]
    return orders


def _held(profile: ShipProfile, orders: list[Order], n: int, keys: list[str], start: np.ndarray) -> np.ndarray:
    """Sampled values of ``keys`` under the orders (steps and ramps, no rate limit)."""
    ts = profile.sample_time
    t = np.arange(n) * ts
    out = np.tile(start, (n, 1)).astype(float)
    for o in sorted(orders, key=lambda o: o.t_s):
        k0 = int(round(o.t_s / ts))
        if k0 >= n:
            continue
        ramp = o.values.get("ramp_s", 0.0)
        for j, key in enumerate(keys):
            if key not in o.values:
                continue
            p, q = out[k0, j], o.values[key]
            frac = np.ones(n - k0) if ramp <= 0 else np.clip((t[k0:] - t[k0]) / ramp, 0.0, 1.0)
            out[k0:, j] = p + (q - p) * frac
    return out


def rate_limited(command: np.ndarray, start: float, max_step: float | None) -> np.ndarray:
    """The actuator following ``command`` (per sample) from ``start`` at most ``max_step`` per sample."""
    if max_step is None or not np.isfinite(max_step):
        return np.asarray(command, float).copy()
    out = np.empty(len(command))
    x = start
    for k, c in enumerate(command):
        x += float(np.clip(c - x, -max_step, max_step))
        out[k] = x
    return out


def inputs_from_orders(profile: ShipProfile, orders: list[Order], n: int, start: np.ndarray | None = None) -> np.ndarray:
    """Rebuild the (n, m) input sequence the orders describe, with the profile's actuator rates.

    ``start``: the inputs before the first order (rudder/engine before execute); default zero
    rudder and the first ordered engine setting."""
    ts = profile.sample_time
    if profile.actuator == "rudder_propeller":
        helm, eng = profile.helm, profile.engine
        cmd = _held(profile, orders, n, ["rudder_deg", "n_rps"], np.zeros(2))
        first_n = next((o.values["n_rps"] for o in orders if "n_rps" in o.values), 0.0)
        d0, n0 = (0.0, first_n) if start is None else (helm.rudder_deg(start[0]), start[1])
        rud = rate_limited(cmd[:, 0], d0, helm.rudder_rate_deg_s * ts)
        shaft = rate_limited(
            np.where(np.arange(n) * ts < _first_time(orders, "n_rps"), n0, cmd[:, 1]),
            n0,
            None if eng.rps_rate is None else eng.rps_rate * ts,
        )
        return np.column_stack([helm.delta_rad(rud), shaft])
    if profile.actuator == "azimuth":
        keys = [k for i in range(1, len(profile.thrusters) + 1) for k in (f"n{i}_rps", f"alpha{i}_deg")]
        vals = _held(profile, orders, n, keys, np.zeros(len(keys)))
        vals[:, 1::2] = np.radians(vals[:, 1::2])
        return vals
    return _held(profile, orders, n, list(profile.inputs), np.zeros(len(profile.inputs)))


def _first_time(orders: list[Order], key: str) -> float:
    return min((o.t_s for o in orders if key in o.values), default=np.inf)


def limit_violations(profile: ShipProfile, orders: list[Order]) -> list[str]:
    """What in the orders exceeds the profile's limits (rudder angle, rpm, azimuth, force limits)."""
    bad = []
    lim = profile.input_limits
    for o in orders:
        v = o.values
        if "rudder_deg" in v and abs(v["rudder_deg"]) > profile.helm.max_rudder_deg + 1e-9:
            bad.append(f"t+{o.t_s:.0f} s '{o.text}': rudder {v['rudder_deg']:.1f}° beyond {profile.helm.max_rudder_deg:g}°")
        if "n_rps" in v:
            lo, hi = profile.engine.rps_limits
            if not lo - 1e-9 <= v["n_rps"] <= hi + 1e-9:
                bad.append(f"t+{o.t_s:.0f} s '{o.text}': {v['n_rpm']:.0f} rpm outside {60 * lo:.0f}..{60 * hi:.0f} rpm")
        for i in range(1, len(profile.thrusters) + 1):
            for key, name, scale in ((f"n{i}_rps", f"n{i}", 1.0), (f"alpha{i}_deg", f"alpha{i}", np.pi / 180)):
                if key in v and name in lim:
                    lo, hi = lim[name]
                    if not lo - 1e-6 <= v[key] * scale <= hi + 1e-6:
                        bad.append(f"t+{o.t_s:.0f} s '{o.text}': {key} {v[key]:.3g} outside the limits of {name}")
        if profile.actuator == "generalized":
            for name in profile.inputs:
                if name in v and name in lim and not lim[name][0] - 1e-9 <= v[name] <= lim[name][1] + 1e-9:
                    bad.append(f"t+{o.t_s:.0f} s '{o.text}': {name} {v[name]:.4g} outside {lim[name]}")
    return bad
