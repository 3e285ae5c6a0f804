"""The found path sailed: its legs re-simulated continuously from the start and checked against the
margin (:func:`verify_plan`), then the crew's Plan assembled from them (:func:`assemble_plan`);
steps of :mod:`maps.chain`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from maps.plan import Plan, PlanStep
from maps.smooth import Leg, Realiser, Shortcutter
from maps.verify import Verification, resimulate

if TYPE_CHECKING:
    from maps.chain import Lattice, SearchOutcome


# A verified plan's re-simulated track ends within this many lattice cells (or ship lengths, the
# larger) of the lattice's end point: legs are sailed from the ship's actual state and settle on the
# lattice, so their drift is metres to tens of metres (tests/test_planner.py); kilometres mean the
# profile's moves do not end where the lattice put them, and the plan searched is not the one sailed.
MAX_DRIFT_CELLS = 3.0


@dataclass
class Realised:
    legs: list[Leg]
    verification: Verification
    shortcuts: int = 0
    replaced_moves: int = 0


def _track_m(leg: Leg) -> float:
    """Distance sailed along a leg (its simulated track; sailed already)."""
    eta = leg.sim[1]
    return float(np.hypot(*np.diff(eta[:, :2], axis=0).T).sum())


def _sail_repositioning(
    lat: Lattice, res: Any, k: int, k1: int, sailor: Realiser, cutter: Shortcutter | None, nu: np.ndarray, eta: np.ndarray
) -> tuple[list[Leg], np.ndarray, np.ndarray, int]:
    """The repositioning moves ``k``..``k1`` of the path sailed from the ship's actual state, or one
    straightened leg in their place where the water allows and it is the shorter way: (legs, state
    after them, 1 if straightened else 0)."""
    moves = res.moves
    sailed, s_nu, s_eta = [], nu, eta
    for i in range(k, k1):
        for leg in sailor.legs(moves[i], res.spatial[i], s_nu, s_eta, res.spatial[i + 1]):
            sailed.append(leg)
            s_nu, s_eta = leg.sail(s_nu, s_eta)
    new = None
    if cutter is not None:
        poses = np.array([lat.pose(res.spatial[i]) for i in range(k, k1 + 1)])
        new = cutter.legs(poses, nu, eta)
    # the shortcut only where it is the shorter way: a lattice move sailed from the ship's
    # actual state can be long (a round turn that settles on a lattice line it overshot)
    if new is not None and _track_m(new) < sum(_track_m(leg) for leg in sailed):
        nu, eta = new.sail(nu, eta)
        return [new], nu, eta, 1
    return sailed, s_nu, s_eta, 0


def verify_plan(lat: Lattice, out: SearchOutcome) -> Realised:
    """Legs of the found path (run-ins split off, transit runs straightened where the water
    allows), re-simulated continuously from the start and checked against the margin."""
    if not out.found:
        raise ValueError(f"verify_plan needs a path: the search found none ({out.result.reason})")
    K = len(lat.table)
    res = out.result
    p = lat.profile
    nu = np.array([p.cruise_speed_mps, 0.0, 0.0])
    eta = np.array(lat.start, float)
    cutter = Shortcutter(lat.sea, p, lat.res, K, lat.options.margin) if lat.options.smooth else None
    sailor = Realiser(lat)
    legs: list[Leg] = []
    shortcuts = replaced = 0
    k = 0
    moves = res.moves
    while k < len(moves):
        if lat.moves[moves[k]].counter < 0:  # a run of repositioning moves
            k1 = k
            while k1 < len(moves) and lat.moves[moves[k1]].counter < 0:
                k1 += 1
            run_legs, nu, eta, cut = _sail_repositioning(lat, res, k, k1, sailor, cutter, nu, eta)
            legs += run_legs
            shortcuts += cut
            replaced += cut * (k1 - k)
            k = k1
        else:
            for leg in sailor.legs(moves[k], res.spatial[k], nu, eta, res.spatial[k + 1]):
                legs.append(leg)
                nu, eta = leg.sail(nu, eta)
            k += 1
    end_cell = res.spatial[-1] // K
    ver = resimulate(
        lat.sea,
        legs,
        lat.start,
        lat.options.margin,
        lat.window.point(end_cell // lat.window.nj, end_cell % lat.window.nj),
        nu0=np.array([p.cruise_speed_mps, 0.0, 0.0]),
        sims=[leg.sim for leg in legs],
        max_drift=MAX_DRIFT_CELLS * max(lat.res, p.length_m),
    )
    return Realised(legs, ver, shortcuts, replaced)


def assemble_plan(
    lat: Lattice,
    out: SearchOutcome,
    real: Realised,
    stats: dict[str, Any] | None = None,
    *,
    design: dict[str, Any] | None = None,
    vessel_name: str = "",
) -> Plan:
    """The Plan of a found path: steps (legs), the re-simulated track, counts and figures."""
    sea, p, ver = lat.sea, lat.profile, real.verification
    lon, lat_ = sea.to_lonlat(ver.track[:, 0], ver.track[:, 1])
    steps = []
    t_acc = 0
    clear = f"smallest clearance below {lat.options.margin:g} m: stop the manoeuvre, steer for open water"
    generic = "heading more than 10 deg or speed more than 10 % off the expected values at a check point: abort and repeat"
    for k, leg in enumerate(real.legs):
        x, y, psi = ver.track[t_acc]
        steps.append(
            PlanStep(
                index=k,
                primitive=leg.source if leg.segment != "transit" else leg.name,
                kind=leg.kind,
                description=leg.description,
                start_time_s=float(ver.t[t_acc]),
                duration_s=leg.duration_s,
                entry_x=float(x),
                entry_y=float(y),
                entry_psi=float(psi),
                entry_lon=float(lon[t_acc]),
                entry_lat=float(lat_[t_acc]),
                entry_speed_mps=float(np.hypot(*ver.nu[t_acc, :2])),
                commands=list(leg.commands),
                space_m=leg.space_m,
                segment=leg.segment,
                orders=list(leg.orders),
                abort=[clear, *(leg.abort or [generic])] if leg.segment == "informative" else [],
                execute=leg.execute,
            )
        )
        t_acc += leg.n_samples
    used = dict.fromkeys(lat.cnames, 0)
    for mi in out.result.moves:
        q = lat.moves[mi].counter
        if q >= 0:
            used[lat.cnames[q]] += 1
    st = dict(stats or {})
    st.update(
        drift_m=ver.drift_m,
        basic_moves=sum(1 for mi in out.result.moves if lat.moves[mi].counter < 0),
        shortcuts=real.shortcuts,
        moves_straightened=real.replaced_moves,
    )
    if ver.drifted:
        st.update(
            reason=ver.reason,
            help=["sail the profile's manoeuvres with `primitives` and check where they end", "use a finer --resolution"],
        )
    elif not ver.ok:
        st.update(reason=ver.reason, help=["increase --margin (more room for drift)", "use a finer --resolution"])
    return Plan(
        ship=p.name,
        steps=steps,
        t=ver.t,
        track=ver.track,
        lonlat=np.column_stack([lon, lat_]),
        speed=np.hypot(ver.nu[:, 0], ver.nu[:, 1]),
        step_of_sample=ver.step_of_sample,
        inputs=ver.inputs,
        input_names=list(p.inputs),
        projection=sea.projection_info(),
        feasible=ver.ok,
        optimal=out.result.optimal and ver.ok,
        min_clearance_m=ver.min_clearance_m,
        margin_m=lat.options.margin,
        counts=used,
        targets=dict(lat.targets),
        stats=st,
        map_name=sea.name,
        hull=(p.length_m, p.beam_m),
        design=dict(design or {}),
        vessel_name=vessel_name or getattr(p, "display_name", "") or p.name,
    )
