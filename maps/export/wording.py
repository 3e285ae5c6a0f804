"""The words of the bridge documents: manoeuvre names a master knows, the phase of each step
and its orders in helm/engine or azimuth-angle/rpm terms, speeds in knots.

Names follow IMO MSC.137(76) and ITTC 7.5-04-02-01 (2002) for the standard manoeuvres ("10/10
zig-zag to starboard", "turning circle to port, rudder 35°", "acceleration 0 → 7 kn"); the
identification manoeuvres of F. Ljungberg's PhD thesis (2022) (tau1-tau20, sections 9.1.1 and 9.3)
are named for what the ship does (crabbing, a zig-zag of so many degrees at so many knots), with
speeds and headings measured on the planned track. The design's own code (``tau12``, ``zigzag_10_10_s``) stays on the card in
small print, next to the name. Metres per second belong to the engineering outputs (plan.json,
the CSV schedule); here every speed is in knots.
"""

from __future__ import annotations

import re

import numpy as np

from maps.export._common import KN_PER_MPS, clock, describe_inputs, input_phases, order_lines, step_slice
from maps.plan import Plan, PlanStep

_SIDE = {"s": "starboard", "p": "port"}


def knots(text: str) -> str:
    """``text`` with every speed in m/s given in knots and "deg" written "°" (the words of
    plans saved before the bridge documents used knots)."""
    text = re.sub(r"(-?\d+(?:\.\d+)?) m/s", lambda m: f"{float(m.group(1)) * KN_PER_MPS:.1f} kn", text)
    text = re.sub(r"(\d) deg\b", r"\1°", text)
    text = re.sub(r"(\d+(?:\.\d+)? kn) \(\1\)", r"\1", text)  # "5.8 kn (5.8 kn)" from "3.0 m/s (5.8 kn)"
    return re.sub(r"\(\|v\| ~ ([\d.]+) kn\)", r"(sideways about \1 kn)", text)


def _kn(v_mps: float) -> str:
    return f"{abs(v_mps) * KN_PER_MPS:.1f}"


def _samples(plan: Plan, st: PlanStep) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and heading change from the step's entry (deg, + starboard) over the step."""
    sl = step_slice(plan, st)
    psi = np.unwrap(plan.track[sl, 2])
    return plan.speed[sl], np.degrees(psi - psi[0])


def _core(plan: Plan, st: PlanStep) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`_samples`, without the recovery after the manoeuvre (its order says where it starts)."""
    v, dpsi = _samples(plan, st)
    rec = [o.get("t_s") for o in getattr(st, "orders", None) or [] if isinstance(o, dict) and o.get("phase") == "recovery"]
    if rec and isinstance(rec[0], (int, float)) and len(plan.t) > 1:
        n = max(2, int(round(rec[0] / max(float(plan.t[1] - plan.t[0]), 1e-9))) + 1)
        return v[:n], dpsi[:n]
    return v, dpsi


def standard_name(name: str) -> str | None:
    """The IMO/ITTC name of a standard manoeuvre from the design's code, else None."""
    if m := re.fullmatch(r"zigzag_(\d+)_(\d+)_([sp])", name):
        return f"{m[1]}/{m[2]} zig-zag to {_SIDE[m[3]]}"
    if m := re.fullmatch(r"zz_exc_([\d.]+)_(\d+)_(\d+)", name):
        return f"{m[1]}/{m[2]} zig-zag to starboard at {m[3]} % of approach rpm"
    if m := re.fullmatch(r"turning_circle_([\d.]+)_([sp])", name):
        return f"turning circle to {_SIDE[m[2]]}, rudder {m[1]}°"
    if m := re.fullmatch(r"pull_out_(\d+)_([sp])", name):
        return f"pull-out after rudder {m[1]}° {_SIDE[m[2]]}"
    return {"direct_spiral": "direct spiral (Dieudonné)", "reverse_spiral": "reverse spiral (Bech)"}.get(name)


def manoeuvre_name(plan: Plan, st: PlanStep) -> str:
    """What the bridge calls the step, with its parameters measured on the planned track."""
    name, desc = st.primitive, str(st.description or "")
    if st.segment == "run-in":
        if phase(plan, st) == "stop":
            return "stop and settle"
        held = [o.get("speed_kn") for o in st.orders or [] if isinstance(o, dict) and isinstance(o.get("speed_kn"), (int, float))]
        v = held[0] / KN_PER_MPS if held else float(_samples(plan, st)[0][-1])
        return f"steady approach at {_kn(v)} kn"
    if st.segment == "transit" or st.kind == "basic":
        return _basic_name(name, desc)
    std = standard_name(name)
    if std:
        return std
    v, dpsi = _core(plan, st)
    v0, vmax, vmin, vend = float(v[0]), float(v.max()), float(v.min()), float(v[-1])
    low = desc.lower()
    if name == "stopping" or "stop" in low and "from cruise" in low:
        # a short form regains speed full ahead afterwards (primitives.sized): name the lowest speed, and the regain
        again = ", then full ahead back to speed" if vend > vmin + 0.05 * max(v0, 1e-6) else ""
        if "crash" in low or "full astern" in low:
            return f"crash stop from {_kn(v0)} kn" + (f" to {_kn(vmin)} kn{again}" if again else "")
        return f"engine stop from {_kn(v0)} kn, coasting to {_kn(vmin)} kn{again}"
    if "sway" in low and ("acceleration" in low or "step" in low) and v0 < 0.2:
        return f"crabbing from rest, to starboard and to port (up to {_kn(vmax)} kn)"
    if "sway" in low:
        return f"crabbing at {_kn(v0)} kn to starboard, then to port"
    if re.search(r"u 0 -> ([\d.]+) -> 0\b", desc):  # the thesis's tau12: from rest, thrust ahead, then none
        return f"acceleration 0 → {_kn(vmax)} kn, then thrusters stopped, coasting down"  # the top speed sailed, not the nominal
    if name in ("acceleration", "tau2") or low.startswith("accelerat"):
        return f"acceleration {_kn(v0)} → {_kn(vmax)} kn"
    if name in ("deceleration", "tau1") or low.startswith("decelerat"):
        return f"deceleration {_kn(v0)} → {_kn(vmin)} kn"
    if "zig-zag" in low or "zigzag" in name:
        amp = float(np.abs(dpsi).max())
        m = re.search(r"T ~ (\d+) s", desc)
        return f"zig-zag ±{amp:.0f}° at {_kn(v0)} kn" + (f", period about {m[1]} s" if m else "")
    if "spiral" in low:
        return f"{'inward ' if 'inward' in low else ''}spiral from {_kn(v0)} kn"
    return knots(desc)


def _basic_name(name: str, desc: str) -> str:
    if name == "transit":
        return "transit, " + knots(re.sub(r"^transit:\s*", "", desc))
    if m := re.fullmatch(r"spot_turn_([sp])", name):
        return f"turn on the spot 90° to {_SIDE[m[1]]}"
    if m := re.fullmatch(r"round_turn_([sp])", name):
        return f"180° turn to {_SIDE[m[1]]} onto the reciprocal course"
    return knots(desc)


def phase(plan: Plan, st: PlanStep) -> str:
    """The step's phase as the card names it: EXECUTE (a manoeuvre begun at its execute point),
    manoeuvre, run-in (steady course and speed), stop (the ship comes to rest before a manoeuvre
    that starts from rest: no run-in) or transit."""
    if getattr(st, "execute", False):
        return "EXECUTE"
    if st.segment == "informative":
        return "manoeuvre"
    if st.segment == "run-in":
        words = " ".join([str(st.description), *(str(o.get("text", "")) for o in st.orders or [] if isinstance(o, dict))])
        if "come to rest" in words or str(st.description).startswith("stop before"):
            return "stop"
        return "run-in"
    return "transit"


def _typical(plan: Plan, st: PlanStep, a: int, b: int) -> str:
    """The inputs of samples a..b of the step as one setting (median; the angles' circular mean)."""
    sl = step_slice(plan, st)
    u = plan.inputs[sl][a : max(b, a + 1)]
    row = np.median(u, axis=0)
    for j, nm in enumerate(plan.input_names):
        if nm.startswith("alpha") or nm.startswith("delta"):
            row[j] = np.arctan2(np.sin(u[:, j]).mean(), np.cos(u[:, j]).mean())
    return describe_inputs(plan, row)


def _spot_turn_orders(plan: Plan, st: PlanStep) -> list[str]:
    """Stop, turn on the spot, regain speed: each phase's time and thruster settings, read from
    the planned inputs (the phases end when the ship is at rest and when it is on the new heading)."""
    v, dpsi = _samples(plan, st)
    t = plan.t[step_slice(plan, st)] - plan.t[step_slice(plan, st).start]
    rest = np.flatnonzero(v < 0.05 * max(float(v[0]), 1e-6))
    k1 = int(rest[0]) if len(rest) else len(v) // 3
    on = np.flatnonzero(np.abs(dpsi[k1:] - dpsi[-1]) < 2.0)
    k2 = k1 + (int(on[0]) if len(on) else (len(v) - k1) // 2)
    side = "starboard" if dpsi[-1] > 0 else "port"
    course = (np.degrees(plan.track[step_slice(plan, st)][-1, 2])) % 360
    return [
        f"at +{clock(t[0])}: stop the ship: {_typical(plan, st, 0, k1)}",
        f"at +{clock(t[k1])}: turn on the spot {abs(dpsi[-1]):.0f}° to {side}: {_typical(plan, st, k1, k2)}",
        f"at +{clock(t[k2])}: on course {course:03.0f}°, regain {_kn(float(v[-1]))} kn: {_typical(plan, st, k2, len(v) - 1)}",
    ]


def bridge_orders(plan: Plan, st: PlanStep) -> list[str]:
    """The step's orders for the bridge, timed, in the ship's own terms and in knots: the
    manoeuvre's helm/engine or azimuth orders (and its recovery), a run-in's course and speed, a
    spot turn's stop, turn and speed-up with thruster angles and rpm, a transit's course and
    speed with the typical setting."""
    lines = order_lines(st)
    if lines:
        return [knots(x) for x in lines]
    if re.fullmatch(r"spot_turn_[sp]", st.primitive) and any(n.startswith("alpha") for n in plan.input_names):
        return _spot_turn_orders(plan, st)
    out = [knots(c) for c in st.commands]
    if out and not out[0].startswith(("at +", "t+")):  # the planner's words for a closed-loop step: from its start
        out[0] = f"at +0:00: {out[0]}"
    if plan.inputs.size and plan.input_names and out:
        n = step_slice(plan, st).stop - step_slice(plan, st).start
        out.append(_helm_range(plan, st) if "delta" in plan.input_names else f"typical setting: {_typical(plan, st, 0, n - 1)}")
    return out


def _helm_range(plan: Plan, st: PlanStep) -> str:
    """A rudder ship's helm and engine over a closed-loop step: the largest rudder to each side
    and the engine's rpm (a median rudder says nothing of a turn)."""
    names = list(plan.input_names)
    u = plan.inputs[step_slice(plan, st)]
    d = np.degrees(u[:, names.index("delta")])
    sides = [
        f"{abs(x):.0f}° {w}"
        for x, w in ((d.max(), "starboard"), (d.min(), "port"))
        if abs(x) >= 1.0 and x * (1 if w == "starboard" else -1) > 0
    ]
    helm = f"rudder up to {' and '.join(sides)}" if sides else "rudder amidships"
    rpm = f", engine about {60 * float(np.median(u[:, names.index('n')])):.0f} rpm" if "n" in names else ""
    return f"helm as needed: {helm}{rpm}"


def step_orders(plan: Plan, step: PlanStep) -> list[str]:
    """What the crew is told for ``step``, in knots and the ship's own terms
    (:func:`bridge_orders`: its structured orders, a spot turn's phases, its commands), else the
    timed input orders read from the planned inputs."""
    return bridge_orders(plan, step) or input_phases(plan, step)
