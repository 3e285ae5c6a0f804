"""Change detection study of seed 000 section 5.2, ours beside the thesis's Tables 5.2/5.3.

Truth: the shared kernel (primitives.simulate) on the 4-DOF podded profile ``naval-vessel``
(surge-sway-yaw-roll, (2.13) with the two pods); changed ships are that profile with changed data
(identify/detect/vessel.py: ``Vessel.profile``). Priors, as in section 5.2: model 0 = true
parameters, models 1..M = output-error fits of the full (2.17) or simplified (2.18) yaw row to
500 s of noisy harbour manoeuvring (10 Hz). Each prior is evaluated on ``--runs`` noise
realisations of the nominal ship and of a ship with "a moment of inertia 10 % larger" (L1591),
read two ways: 10 % more I_z (I_r = I_z - N_rdot +5.4 %; seed 000's section 4.5 changes I_z) and
10 % more I_r (the lumped yaw inertia the model identifies), 500 s of a different manoeuvre. Noise: white, on every measured signal, Table 4.1 as printed (r 0.0025 rad/s,
v' 0.015 m/s^2, u and v 0.15 m/s, phi 0.025 rad, tau_r 5e4 N m) and half of it; no anti-alias
filter. The priors see their inputs low-passed at 0.5 Hz, v fused with the measured v' (full model;
``--prefilter 0`` uses them as measured, the thesis's way). Both detectors are calibrated for 2 %
false alarms per 500 s from the prior alone, never from the evaluation runs: no-change records
simulated from the prior (its ``--bootstrap`` parametric-bootstrap parameter errors, the noise
levels read from its own 500 s, the evaluation manoeuvre's measured inputs smoothed); the LR-CUSUM
is also shown at a stricter design (``--strict``, the threshold/delay trade). Rates are pooled
over models 1..M (as the thesis's aggregates); model 0 and per-model rows (``--per-model``)
follow, with each prior's I_r error and its bootstrap rms error.

    python benchmarks/bench_detect.py --models 10 --runs 100
    python benchmarks/bench_detect.py --models 10 --runs 100 --models-kind full --noise table --strict 0.015
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from identify.detect.cusum import calibrate_dead_zone, first_alarms
from identify.detect.glr import calibrate
from identify.detect.nullsim import null_records
from identify.detect.priorfit import fit
from identify.detect.verdict import attribute
from identify.detect.vessel import TABLE_4_1, Vessel, harbour_inputs, measure, truth
from identify.detect.yawmodel import NOMINAL, PREFILTER_HZ, SIGNALS, block_mean, signatures

DT, N = 0.1, 5000
#: seed 000 Tables 5.2/5.3 aggregated over models 1-10 (false alarm %, miss %, mean time s), and model 0
SEED000 = {"full": ((1.7, 3.5, 219), (14, 17, 304)), "simplified": ((0.9, 6.7, 272), (10, 19, 271))}
SHIPS = {"nominal": Vessel(), "I_z": Vessel(inertia=1.1), "I_r": Vessel(lumped_inertia=1.1)}
DESIGNS = {"dz": ("dead-zone CUSUM (5.1)", 0.02), "sc": ("LR-CUSUM, 2 % design", 0.02), "sc05": ("LR-CUSUM, 0.5 % design", 0.005)}


def make_prior(kind: str, noise: dict, m: int, bootstrap: int = 64, prefilter_hz: float = PREFILTER_HZ):
    """Prior ``m`` (0 = true parameters) from 500 s of its own noisy manoeuvre; with ``bootstrap``
    its parameter covariance from that many parametric-bootstrap refits (errors in variables)."""
    ch = harbour_inputs(N, DT, seed=10_000 + m)
    meas = measure(truth(ch), noise, np.random.default_rng(20_000 + m))
    return fit(
        kind,
        {k: meas[k] for k in SIGNALS[kind]},
        meas["r"],
        DT,
        source=f"model {m}",
        estimate=m > 0,
        bootstrap=bootstrap,
        seed=30_000 + m,
        prefilter_hz=prefilter_hz,
    )


def evaluate(prior, noise: dict, runs: int, seed: int) -> dict:
    """First alarms (sample index, -1 none) of each detector on ``runs`` records of each ship."""
    ch = harbour_inputs(N, DT, seed=seed)
    rng = np.random.default_rng(seed + 1)
    kind = prior.kind
    # what the detector sees before any alarm: this manoeuvre's measured inputs (one realisation)
    nominal = truth(ch)  # noise-free, so simulated once for the calibration and the nominal runs
    seen = measure(nominal, noise, rng)
    seen = {k: seen[k] for k in SIGNALS[kind]}
    S = signatures(prior, seen)
    null_raw = null_records(prior, seen, 400, seed + 2)
    null_blocks = block_mean(null_raw, prior.block)
    dz = calibrate_dead_zone(prior.sigma, null_raw, false_alarm=DESIGNS["dz"][1])
    scs = {k: calibrate(prior, S, null_blocks, false_alarm=DESIGNS[k][1]) for k in ("sc", "sc05")}
    out = {}
    for ship, ves in SHIPS.items():
        meas = measure(nominal if ves == Vessel() else truth(ch, ves), noise, rng, runs=runs)
        eps = meas["r"] - prior.predict({k: meas[k] for k in SIGNALS[kind]})
        st = scs["sc"].statistics(block_mean(eps, prior.block), S)  # the same statistic; the designs differ in h
        out[ship] = {"dz": first_alarms(dz.statistic(eps), dz.h), **{k: sc.alarms(st) for k, sc in scs.items()}}
        out[ship]["named"] = (
            [attribute(eps[:, k], S, prior, i + 600)["property"] for k, i in enumerate(out[ship]["sc"]) if i >= 0]
            if ship != "nominal"
            else []
        )
    return out


def rates(nom: np.ndarray, chg: np.ndarray) -> tuple[float, float, float]:
    hit = chg[chg >= 0]
    return 100 * np.mean(nom >= 0), 100 * np.mean(chg < 0), (float(np.mean(hit)) * DT if hit.size else float("nan"))


def study(kind: str, noise: dict, models: int, runs: int, bootstrap: int = 64, prefilter_hz: float = PREFILTER_HZ) -> list[dict]:
    per = []
    for m in range(models + 1):
        prior = make_prior(kind, noise, m, bootstrap, prefilter_hz)
        per.append(
            {
                "prior_I_r": prior.values["I_r"] / NOMINAL["I_r"] - 1,
                "prior_I_r_sd": float(np.sqrt(prior.cov[0, 0])),
                **evaluate(prior, noise, runs, seed=500 + m),
            }
        )
    return per


def fmt(r: tuple) -> str:
    return f"{r[0]:5.1f} {r[1]:6.1f} {r[2]:6.0f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=int, default=10, help="estimated priors (the thesis used 10)")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--per-model", action="store_true", help="print every prior's row")
    ap.add_argument("--models-kind", choices=("full", "simplified", "both"), default="both", help="prior structures to run")
    ap.add_argument("--strict", type=float, default=0.005, help="the stricter LR-CUSUM design false-alarm rate shown")
    ap.add_argument(
        "--bootstrap",
        type=int,
        default=64,
        help="prior parameter errors from N parametric-bootstrap refits (errors in variables); 0: Gaussian, fit Jacobian",
    )
    ap.add_argument(
        "--prefilter", type=float, default=PREFILTER_HZ, help="low-pass the model inputs at this many Hz (0: as measured)"
    )
    ap.add_argument("--noise", choices=("both", "table", "half"), default="both", help="noise levels to run")
    a = ap.parse_args()
    DESIGNS["sc05"] = (f"LR-CUSUM, {100 * a.strict:g} % design", a.strict)
    print(
        f"500 s at 10 Hz; white noise on every measured signal; {a.models} estimated priors (+ model 0, the true "
        f"parameters), {a.runs} runs per ship; FA on the nominal ship, misses/mean alarm time on each changed ship; "
        f"prior parameter error: {f'{a.bootstrap} bootstrap refits' if a.bootstrap else 'Gaussian, fit Jacobian'}; "
        f"inputs {f'low-passed at {a.prefilter:g} Hz' if a.prefilter else 'as measured'}"
    )
    print(
        f"{'noise':>9} {'model':10} {'detector':23}| {'FA %':>5} | {'10 % I_z: miss% t s':>19} | "
        f"{'10 % I_r: miss% t s':>19} | seed 000 FA/miss/t | model 0: FA, miss/t I_z, I_r | named yaw_inertia"
    )
    t0, c0 = time.perf_counter(), time.process_time()
    for label, scale in (("Table 4.1", 1.0), ("half", 0.5)):
        if a.noise != "both" and (a.noise == "half") != (scale == 0.5):
            continue
        noise = {k: scale * s for k, s in TABLE_4_1.items()}
        for kind in ("full", "simplified") if a.models_kind == "both" else (a.models_kind,):
            per = study(kind, noise, a.models, a.runs, a.bootstrap, a.prefilter)
            ref = SEED000[kind][0]
            for det, (name, _) in DESIGNS.items():
                est = per[1:]
                pooled = {ship: np.concatenate([p[ship][det] for p in est]) for ship in SHIPS}
                r_z, r_r = rates(pooled["nominal"], pooled["I_z"]), rates(pooled["nominal"], pooled["I_r"])
                m0z, m0r = rates(per[0]["nominal"][det], per[0]["I_z"][det]), rates(per[0]["nominal"][det], per[0]["I_r"][det])
                named = [x for p in est for ship in ("I_z", "I_r") for x in p[ship]["named"]] if det == "sc" else []
                nm = f"{100 * np.mean([x == 'yaw_inertia' for x in named]):.0f} %" if named else ""
                print(
                    f"{label:>9} {kind:10} {name:23}| {r_z[0]:5.1f} | {r_z[1]:10.1f} {r_z[2]:6.0f}   | {r_r[1]:10.1f} {r_r[2]:6.0f}   | "
                    f"{ref[0]:4.1f} {ref[1]:4.1f} {ref[2]:4.0f} | {m0z[0]:4.0f}, {m0z[1]:3.0f}/{m0z[2]:3.0f} {m0r[1]:3.0f}/{m0r[2]:3.0f} | {nm}"
                )
                if a.per_model:
                    for m, p in enumerate(per):
                        rz, rr = rates(p["nominal"][det], p["I_z"][det]), rates(p["nominal"][det], p["I_r"][det])
                        print(
                            f"{'':>9} {'':10}   model {m:2d}: I_r {100 * p['prior_I_r']:+5.1f} % (sd {100 * p['prior_I_r_sd']:.1f}) | "
                            f"{rz[0]:5.1f} | {rz[1]:10.1f} {rz[2]:6.0f}   | {rr[1]:10.1f} {rr[2]:6.0f}"
                        )
    print(
        f"seed 000 model 0: full 14/17/304, simplified 10/19/271. ({time.perf_counter() - t0:.0f} s wall, "
        f"{time.process_time() - c0:.0f} s cpu; machine shared)"
    )


if __name__ == "__main__":
    main()
