"""What the profile part of a diagnosed ``model.json`` leaves out of the scored model.

``shiptrial diagnose`` writes the scored model twice (``diagnose.model_file``): as a ship profile
(what ``--ship model.json`` plans, designs and simulates with) and exactly, in the
``diagnosed_model`` section only the diagnosis reads back. The profile format and the one
simulation kernel hold the refitted terms, a term a finding adds, a thrust loss (its terms
scaled) and a current (``disturbances.current_mean_ne``); an actuator delay, an input offset, a
sensor bias, an inertia change and a term reading signals the planner does not simulate (the
measured wind's ``wx``, ``wy``, ``wn``, the roll angle ``phi``) have no place there and are
dropped. :func:`left_out` names each such finding with its value so that the commands can say
the ship they plan with is not the whole diagnosed model.

Warned, not refused: the profile part is the baseline refitted together with those effects, the
closest model the profile format can run; refusing would leave the user no way to plan with the
diagnosis at all. A current the profile part has lost, which the format can hold, is refused
(:func:`primitives.diagnosed_sections.check_model_json_as_ship`).
"""

from __future__ import annotations

from typing import Any

# slot kinds the profile part holds: "term" only when the term is among the profile's model terms
HELD_KINDS = ("current", "thrust", "thrust_share")
MEASUREMENT_KINDS = ("bias",)  # an error of the recorded signals, not of the ship's motion


def left_out(d: dict[str, Any], model_terms: tuple[tuple[str, ...], ...]) -> list[str]:
    """Each candidate of ``d``'s ``diagnosed_model.candidates`` that the profile part (its terms
    ``model_terms`` per DOF) does not hold, as "key (slot value, ...)"; [] for a plain profile.
    Run after :func:`primitives.diagnosed_sections.check_model_json_as_ship` (the list is a list of
    tables); a candidate too malformed to read is left to ``diagnose.model_file.load_model``."""
    dm = d.get("diagnosed_model")
    if not isinstance(dm, dict):
        return []
    out = []
    for c in dm.get("candidates") or []:
        slots, values = c.get("slots"), c.get("values")
        if not isinstance(slots, list) or not all(isinstance(s, dict) for s in slots):
            continue
        if all(_held(s, model_terms) for s in slots):
            continue
        vals = values if isinstance(values, list) and len(values) == len(slots) else [None] * len(slots)
        said = ", ".join(
            f"{s.get('name')} {v:.3g}" if isinstance(v, int | float) else str(s.get("name")) for s, v in zip(slots, vals)
        )
        kind = " [a measurement error]" if all(s.get("kind") in MEASUREMENT_KINDS for s in slots) else ""
        out.append(f"{c.get('key', c.get('effect'))} ({said}){kind}")
    return out


def _held(slot: dict, model_terms: tuple[tuple[str, ...], ...]) -> bool:
    if slot.get("kind") in HELD_KINDS:
        return True
    dof = slot.get("dof")
    return (
        slot.get("kind") == "term"
        and isinstance(dof, int)
        and not isinstance(dof, bool)
        and 0 <= dof < len(model_terms)
        and slot.get("term") in model_terms[dof]
    )


def left_out_warning(src: str, dropped: list[str]) -> str:
    """The one-line warning for the findings ``dropped`` of the model.json ``src``."""
    return (
        f"{src}: the ship profile in this model.json leaves out {len(dropped)} finding(s) of the diagnosed model that a "
        f"profile cannot hold: {'; '.join(dropped)}; plans, designs and simulations with --ship {src} run without "
        "them (the exact model: diagnose.model_file.load_model)"
    )
