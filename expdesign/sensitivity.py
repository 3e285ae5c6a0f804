"""Which modelling choices move the (7.57) shares on the model ship, and how far (section 9.1.1).

The thesis states the primitives only by the states they produce, so three choices are ours:
the zig-zag period (heading at which the force switches, ``psi_switch``), the sway force held
during the zig-zags (the +-v amplitude) and whether the moments X, Y, Z are computed from the
nominal noise-free states or estimated from noisy, current-disturbed simulations like the
thesis's "estimated" matrices. Each variant is solved with :func:`expdesign.api.run_design` and
compared with the thesis's shares by the total-variation distance 0.5 * sum |w - w_thesis|.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from expdesign.api import run_design
from expdesign.dopt import InfoSet
from primitives import maneuvers as mv
from primitives.information import library_information
from primitives.library import Primitive, make_primitive, model_ship_thesis
from primitives.ship import ShipProfile

# Ljungberg (2022), section 9.1.1: the (7.57) design the thesis reports for tau1-tau11 (time fractions).
THESIS_SHARES = {"tau1": 0.16, "tau2": 0.04, "tau5": 0.09, "tau6": 0.42, "tau8": 0.04, "tau11": 0.25}
# tau3-tau8 of section 9.1.1: (name, u, v amplitude, r amplitude).
_ZIGZAGS = [
    ("tau3", 0.35, 0.1, 0.2),
    ("tau4", 0.8, 0.1, 0.2),
    ("tau5", 1.15, 0.1, 0.2),
    ("tau6", 0.35, 0.15, 0.35),
    ("tau7", 0.7, 0.15, 0.35),
    ("tau8", 1.0, 0.15, 0.35),
]


def variant_library(profile: ShipProfile, psi_switch: float = 0.5, v_scale: float = 1.0, n: int = 300) -> list[Primitive]:
    """tau1-tau11 with the zig-zags' sway amplitude scaled by ``v_scale`` (0: no sway force)."""
    lib = model_ship_thesis(profile, n=n, psi_switch=psi_switch)
    if v_scale == 1.0:
        return lib
    zz = {
        name: make_primitive(
            profile,
            name,
            f"zig-zag u {u}, v +-{v * v_scale:.3g}, r +-{r}",
            mv.excitation_zigzag(profile, n, u, v * v_scale, r, psi_switch),
        )
        for name, u, v, r in _ZIGZAGS
    }
    return [zz.get(p.name, p) for p in lib]


def tv_distance(w: dict[str, float], ref: dict[str, float]) -> float:
    keys = set(w) | set(ref)
    return 0.5 * float(sum(abs(w.get(k, 0.0) - ref.get(k, 0.0)) for k in keys))


def sensitivity_study(
    profile: ShipProfile,
    *,
    seed: int = 0,
    realisations: int = 20,
    psi_switches: tuple[float, ...] = (0.3, 0.5, 0.8, 1.2),
    v_scales: tuple[float, ...] = (-1.0, 0.0, 0.5, 1.0, 1.5, 2.0),
) -> list[dict[str, Any]]:
    """Rows {variant, psi_switch, v_scale, realisations, mean_subtraction, weights, tv_to_thesis,
    best_single}; v_scale -1 puts the sway in phase with the yaw rate instead of against it."""
    rows = []
    variants = [(ps, 1.0, 0, "complete") for ps in psi_switches]
    variants += [(0.5, vs, 0, "complete") for vs in v_scales if vs != 1.0]
    if realisations:
        variants.append((0.5, 1.0, realisations, "complete"))
    variants.append((0.5, 1.0, 0, "batchwise"))
    for ps, vs, real, ms in variants:
        lib = variant_library(profile, ps, vs)
        d = run_design(profile, lib, seed=seed, disturbed_realisations=real, n_random_starts=2, mean_subtraction=ms)
        single = {}
        if real == 0:
            info = InfoSet.from_infos(library_information(profile, lib))
            for i, nm in enumerate(info.names):
                single[nm] = info.logdet(np.eye(len(lib))[i], "complete")
        best = max(single, key=single.get) if single else None
        rows.append(
            {
                "variant": f"psi_switch {ps} rad, sway x{vs:g}, "
                + (f"noisy matrices ({real} realisations)" if real else "noise-free matrices")
                + ("" if ms == "complete" else f", {ms} mean subtraction (7.53)"),
                "psi_switch": ps,
                "v_scale": vs,
                "realisations": real,
                "mean_subtraction": ms,
                "weights": {k: round(v, 4) for k, v in d.weights.items()},
                "tv_to_thesis": tv_distance(d.weights, THESIS_SHARES),
                "best_single": best,
            }
        )
    return rows
