"""Plan what the water allows: shorter manoeuvres, and the parameters held when even they cannot identify the model.

When a manoeuvre of the ship's library fits nowhere on the map, :func:`with_short_forms` offers
its shorter forms (:mod:`primitives.sized`), each with its own information matrix from the same
simulation kernel, and keeps those that have a placement in the water the ship can reach. Only
then: on water where the library fits, the library and so the plan are what they were.

When what fits still cannot identify every parameter, :func:`held_design` designs over the
parameters it can identify and holds the others at the profile's values: with a parameter
theta_h known, its regressor's part phi_h theta_h moves to the left-hand side of the
instrumental-variable normal equations (Ljungberg 2022, (7.50)-(7.53)) and the information of
the rest is the information matrix restricted to their rows and columns (no Schur complement:
nothing is estimated for the held ones). Each held parameter is named with the manoeuvre that
fits nowhere but would identify it, and the open water that manoeuvre needs (or, when the
water would hold it but its move has no placement reachable from the start, that).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from expdesign.dopt import InfoSet
from maps.sizing import Needs, row_text
from primitives.information import PrimitiveInfo, library_information, unidentified_parameters
from primitives.library import Primitive
from primitives.ship import ShipProfile
from primitives.sized import short_form_table, short_forms

# short forms checked against the map in one lattice: its memory estimate grows with the counters
CHECK_AT_ONCE = 10
FitsNowhere = Callable[[list[Primitive], dict[str, int]], dict[str, tuple[float, float]]]


@dataclass
class SeaRoom:
    """The library the design runs on for this map: the ship's library plus the short forms
    offered so far, their moments, and what fits nowhere ({name: (along, cross) m of water})."""

    library: list[Primitive]
    infos: list[PrimitiveInfo]
    exclude: dict[str, tuple[float, float]]
    offered: set[str]

    @property
    def fitting(self) -> list[int]:
        return [i for i, p in enumerate(self.library) if p.name not in self.exclude]


def with_short_forms(profile: ShipProfile, room: SeaRoom, fits_nowhere: FitsNowhere) -> bool:
    """Add the short forms of the excluded long manoeuvres not offered yet; those that fit
    nowhere either (checked ``CHECK_AT_ONCE`` to a lattice) join the exclusions. True if any was added."""
    table = short_form_table(profile)
    todo = [n for n in room.exclude if n in table and n not in room.offered]
    if not todo:
        return False
    room.offered.update(todo)
    known = {p.name for p in room.library}
    new = [p for p in short_forms(profile, todo, table) if p.name not in known]
    if not new:
        return False
    for i in range(0, len(new), CHECK_AT_ONCE):
        part = new[i : i + CHECK_AT_ONCE]
        room.exclude.update(fits_nowhere(part, {p.name: 1 for p in part}))
    room.library = room.library + new
    room.infos = room.infos + library_information(profile, new)
    return True


def held_parameters(profile: ShipProfile, room: SeaRoom, mean_subtraction: str) -> list[str]:
    """Parameters no mix of the manoeuvres that fit identifies (equal shares, as
    :func:`expdesign.api.check_identifiable` tests the whole library)."""
    keep = room.fitting
    if not keep:
        return list(profile.predictor_param_names)
    info = InfoSet.from_infos([room.infos[i] for i in keep])
    return unidentified_parameters(profile, info.gamma(np.full(len(keep), 1.0 / len(keep)), mean_subtraction))


def what_identifies(profile: ShipProfile, room: SeaRoom, held: list[str], mean_subtraction: str) -> dict[str, dict[str, Any]]:
    """For each held parameter, the manoeuvre that fits nowhere (shortest longer side of open water first) whose
    addition to what fits would identify it, with the water it needs; none for a parameter none does."""
    keep = room.fitting
    out: dict[str, dict[str, Any]] = {}
    for name, need in sorted(room.exclude.items(), key=lambda kv: (max(kv[1]), kv[1][0] * kv[1][1])):
        idx = next((i for i, p in enumerate(room.library) if p.name == name), None)
        if idx is None:
            continue
        sub = [room.infos[i] for i in [*keep, idx]]
        gamma = InfoSet.from_infos(sub).gamma(np.full(len(sub), 1.0 / len(sub)), mean_subtraction)
        dead = set(unidentified_parameters(profile, gamma))
        for h in held:
            if h not in out and h not in dead:
                out[h] = {"primitive": name, "needs_m": [float(need[0]), float(need[1])]}
                out[h] |= need.record() if isinstance(need, Needs) else {}
        if len(out) == len(held):
            break
    return out


def held_records(
    profile: ShipProfile, room: SeaRoom, held: list[str], mean_subtraction: str
) -> tuple[list[dict[str, Any]], list[str]]:
    """The plan's ``held_parameters`` rows (name, the profile's value, what would identify it) and
    one note for the summary."""
    values = dict(zip(profile.predictor_param_names, _predictor_values(profile)))
    helps = what_identifies(profile, room, held, mean_subtraction)
    rows = [{"parameter": h, "value": values.get(h), "identified_by": helps.get(h)} for h in held]
    note = (
        f"{len(held)} parameter(s) the manoeuvres that fit cannot identify are held at the profile's values "
        f"and the design is over the other {len(profile.predictor_param_names) - len(held)}: {held_text(rows)}"
    )
    return rows, [note]


def held_text(rows: list[dict[str, Any]]) -> str:
    """The plan's held parameters in one line: 'Yur = -0.6433, Nrr = -1.74 (zz_exc_10_5_60 needs
    10.1 km x 529 m of open water; it would identify them)', grouped by what would identify them (the water as :func:`maps.sizing.water_text` says it)."""
    groups: dict[str, list[str]] = {}
    for r in rows:
        by = r.get("identified_by")
        how = f"{row_text(by)}; it would identify them" if by else "no manoeuvre of the library identifies them here"
        val = f"{r['value']:.4g}" if isinstance(r.get("value"), (int, float)) else "the profile's value"
        groups.setdefault(how, []).append(f"{r['parameter']} = {val}")
    return "; ".join(f"{', '.join(names)} ({how})" for how, names in groups.items())


def dropped_text(rows: list[dict[str, Any]], show: int = 4) -> str:
    """The plan's dropped manoeuvres for the summary: '; stopping dropped (stopping needs 10.6 km x
    98 m of open water)' each, past ``show`` of them only a count."""
    parts = [f"; {r['primitive']} dropped ({row_text(r)})" for r in rows[:show]]
    return "".join(parts) + (f"; and {len(rows) - show} more dropped" if len(rows) > show else "")


def _predictor_values(profile: ShipProfile) -> list[float | None]:
    """The profile's value of each predictor parameter (the simulation set's, where the predictor
    is the model; None where a separate predictor has no value in the profile)."""
    if profile.predictor_names is None or tuple(profile.predictor_names) == tuple(profile.parameter_names):
        return [float(x) for x in profile.params()]
    sim = dict(zip(profile.param_names, profile.params()))
    return [float(sim[n]) if n in sim else None for n in profile.predictor_param_names]
