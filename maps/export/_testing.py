"""Synthetic plans for tests and demos of the exporters (no planner needed).

:func:`synthetic_plan` chains primitives of the library, re-simulates their concatenated input
sequence as one continuous run (``primitives.simulate.simulate``, calm water, the profile's
simulation set), places the start near Helsinki (lon 24.95, lat 60.12) and converts the local
metric frame (x north, y east) to WGS-84 with a transverse Mercator projection centred there.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from pyproj import Transformer

from maps.plan import Plan, PlanStep
from primitives.library import build_library, by_name
from primitives.ship import load_profile
from primitives.simulate import simulate

DEFAULT_STEPS = {
    "full-scale": ("straight", "zigzag_10_10_s", "turn_s", "tau17", "spot_turn_p", "tau14"),
    "model-ship": ("straight", "zigzag_20_20_p", "turn_s", "tau4", "straight"),
}


@lru_cache(maxsize=4)
def _library(ship: str) -> list:
    """The profile's primitive library, built once per process (tests share it read-only)."""
    return build_library(load_profile(ship))


def local_proj4(lon0: float, lat0: float) -> str:
    """Transverse Mercator centred on (lon0, lat0): easting/northing in metres from there."""
    return f"+proj=tmerc +lat_0={lat0} +lon_0={lon0} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"


def to_lonlat(proj4: str, x_north: np.ndarray, y_east: np.ndarray) -> np.ndarray:
    """(K, 2) lon, lat of local points (x north, y east) in metres."""
    tr = Transformer.from_crs(proj4, "EPSG:4326", always_xy=True)
    lon, lat = tr.transform(np.asarray(y_east, float), np.asarray(x_north, float))
    return np.column_stack([lon, lat])


def synthetic_plan(
    ship: str = "full-scale",
    names: tuple[str, ...] | None = None,
    *,
    lon0: float = 24.95,
    lat0: float = 60.12,
    x0: float = 0.0,
    y0: float = 0.0,
    psi0_deg: float = 30.0,
    margin_m: float = 10.0,
    run_in: bool = False,
) -> Plan:
    """A plan of ``names`` (library primitives, sailed in order) for built-in profile ``ship``.

    Steps carry the primitives' orders (``Primitive.orders``) and abort criteria. With
    ``run_in`` each informative primitive is preceded by a ``straight`` run-in step and starts
    at an execute point; the other basic primitives are transit.
    """
    profile = load_profile(ship)
    names = tuple(names or DEFAULT_STEPS.get(ship, ("straight", "turn_s", "straight")))
    lib = _library(ship)
    if run_in:
        kinds = {p.name: p.kind for p in lib}
        names = tuple(n for name in names for n in (("straight", name) if kinds.get(name) == "informative" else (name,)))
    prims = by_name(lib, list(names))
    run_ins = {i for i, p in enumerate(prims[:-1]) if run_in and p.name == "straight" and prims[i + 1].kind == "informative"}
    inputs = np.vstack([p.inputs for p in prims])
    psi0 = np.radians(psi0_deg)
    res = simulate(profile, inputs, nu0=prims[0].nu0, eta0=(x0, y0, psi0))
    eta, nu = res.eta[0], res.nu[0]
    k_total = eta.shape[0]
    proj4 = local_proj4(lon0, lat0)
    lonlat = to_lonlat(proj4, eta[:, 0], eta[:, 1])
    speed = np.hypot(nu[:, 0], nu[:, 1])
    step_of_sample = np.zeros(k_total, dtype=int)
    steps = []
    k = 0
    for i, p in enumerate(prims):
        n = p.n_samples
        step_of_sample[k : k + n] = i
        minx, miny, maxx, maxy = p.footprint.bounds
        steps.append(
            PlanStep(
                index=i,
                primitive=p.name,
                kind=p.kind,
                description=p.description,
                start_time_s=float(res.t[k]),
                duration_s=p.duration_s,
                entry_x=float(eta[k, 0]),
                entry_y=float(eta[k, 1]),
                entry_psi=float(eta[k, 2]),
                entry_lon=float(lonlat[k, 0]),
                entry_lat=float(lonlat[k, 1]),
                entry_speed_mps=float(speed[k]),
                commands=list(p.commands),
                space_m=(float(maxx - minx), float(maxy - miny)),
                segment="run-in" if i in run_ins else ("informative" if p.kind == "informative" else "transit"),
                orders=[o.to_dict() for o in getattr(p, "orders", [])],
                abort=[p.abort_criteria()] if hasattr(p, "abort_criteria") else [],
                execute=run_in and p.kind == "informative",
            )
        )
        k += n
    step_of_sample[k:] = len(prims) - 1
    counts: dict[str, int] = {}
    for p in prims:
        if p.kind == "informative":
            counts[p.name] = counts.get(p.name, 0) + 1
    return Plan(
        ship=profile.name,
        steps=steps,
        t=np.asarray(res.t, float),
        track=eta.copy(),
        lonlat=lonlat,
        speed=speed,
        step_of_sample=step_of_sample,
        inputs=np.vstack([inputs, inputs[-1:]]),
        input_names=list(profile.inputs),
        projection={"proj4": proj4, "lon0": lon0, "lat0": lat0},
        feasible=True,
        optimal=False,
        min_clearance_m=42.0,
        margin_m=margin_m,
        counts=counts,
        targets=dict(counts),
        stats={"synthetic": True},
        map_name="synthetic",
        hull=(profile.length_m, profile.beam_m),
        max_wind_mps=10.0,
        vessel_name=str(getattr(profile, "display_name", "") or ""),
    )
