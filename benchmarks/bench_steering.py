"""Benchmark of ``shiptrial steering`` (issue 27: Källström 1977, LISPID on the Sea Splendour).

    python benchmarks/bench_steering.py [--seeds 50] [--parts sea,split,time,kvlcc2] [--json FILE]

* ``sea``: the simulated Sea Splendour experiments (tests/physics/sea_splendour.py: SSPA's model of
  Table 3.1 as the truth, integrated there by its own RK4, with a rudder rate limit, PRBS with manual
  changes, the 20 deg course change, 10 m/s wind, sea, biases, quantisation, late and lost readings),
  ``--seeds`` noise seeds each of experiment 1 (30 s) and 2 (15 s): the share of seeds whose
  maximum-likelihood 95 % interval holds the truth, for K', T1', T2', T3' (a failed fit counts as not
  holding it, and is counted); how often AIC prefers ML to OE (Källström: always); median estimates.
  ``--sample-times 20,25``: experiment 1 also read every 20 and 25 s (coverage and interval width against
  the sampling interval; the fastest time constant T2 is 14.4 s).
* ``split``: experiment 1 split at the course change (1158-1732 s left out), each part by OE and ML and
  cross-validated (Källström's Tables 3.5 and 3.8 beside ours, medians over up to 20 seeds).
* ``time``: CPU time of one maximum-likelihood fit of the second-order model to a 3,000-sample record
  (the simulated experiment sampled every second), from its output-error start (median of 3), and of
  the whole ``fit_model`` (every start); target < 2 s.
* ``kvlcc2``: the MARIN KVLCC2 zig-zags (diagnose/data): first- and second-order Nomoto by ML per run
  and pooled per amplitude, K' and T' of 10/10 against 20/20, and the overshoots of the identified
  first- and second-order models simulated with the measured rudder beside the measured ones.
* ``wind`` (not in the default parts): experiment 2 (15 s, 10 m/s wind, the course change) by nomoto2 with and
  without the heading-dependent wind phi_3: the ML intervals' coverage of K', T1', T2', T3' and how often AIC
  prefers the wind term, by ML and by OE (Källström's Table 4.1: OE preferred it, ML did not).
* ``noise-corr`` (not in the default parts): experiment 2 in the default sea and in one 6 times it, its force and
  moment correlated at 0.8 (and at 0 in the strong sea), by the state-space model's ML with and without R1's
  cross-correlation: how often the 95 % interval of rho holds the truth, excludes zero, and AIC prefers it.

Figures are measured on this machine; the script prints them, it does not assert targets.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from identify.steering.api import fit_model, nomoto_parameters  # noqa: E402
from identify.steering.estimate import SteeringData, fit  # noqa: E402
from identify.steering.recording import read_records  # noqa: E402
from tests.physics import sea_splendour as ss  # noqa: E402

NAMES = ("K'", "T1'", "T2'", "T3'")


def _record(run: dict) -> SteeringData:
    return SteeringData(run["t"], run["delta"], np.column_stack([run["r"], run["psi"]]), ("r", "psi"), "sea-splendour")


def sea(seeds: int, experiments: str = "1,2", sample_times: str = "") -> dict:
    import dataclasses

    out = {}
    chosen = [("experiment 1 (30 s)", ss.EXPERIMENT_1), ("experiment 2 (15 s)", ss.EXPERIMENT_2)]
    chosen = [c for i, c in enumerate(chosen) if str(i + 1) in experiments.split(",")]
    # experiment 1's record (3120 s, the course change, the lost readings) read every h s instead of 30
    chosen += [
        (f"experiment 1 read every {h} s", dataclasses.replace(ss.EXPERIMENT_1, sample_time=float(h)))
        for h in sample_times.split(",")
        if h
    ]
    for label, exp in chosen:
        cover = {k: 0 for k in NAMES}
        failed_ml = failed_oe = ml_better = 0
        est = {k: [] for k in NAMES}
        width = {k: [] for k in NAMES}
        aic = []
        t0 = time.process_time()
        for seed in range(seeds):
            d = _record(ss.simulate(exp, seed))
            ml = fit_model(d, ss.L, ss.V, "nomoto2", "ml")
            oe = fit_model(d, ss.L, ss.V, "nomoto2", "oe")
            ok_ml = ml.ok and all(np.isfinite(e.value) and np.isfinite(e.std) for e in nomoto_parameters(ml).values())
            failed_ml += not ok_ml
            failed_oe += not oe.converged
            if ok_ml:
                nm = nomoto_parameters(ml)
                for k in NAMES:
                    cover[k] += nm[k].covers(ss.TRUTH[k])
                    est[k].append(nm[k].value)
                    width[k].append(nm[k].interval[1] - nm[k].interval[0])
            if ok_ml and oe.converged:
                ml_better += ml.aic < oe.aic
                aic.append((ml.aic, oe.aic))
        cpu = time.process_time() - t0
        a = np.array(aic)
        out[label] = {
            "seeds": seeds,
            "coverage_95": {k: cover[k] / seeds for k in NAMES},
            "ml_failed": failed_ml,
            "oe_failed": failed_oe,
            "aic_prefers_ml": f"{ml_better}/{len(aic)}",
            "median_aic_ml": float(np.median(a[:, 0])) if len(a) else None,
            "median_aic_oe": float(np.median(a[:, 1])) if len(a) else None,
            "median_estimate": {k: float(np.median(v)) if v else None for k, v in est.items()},
            "median_width_95": {k: float(np.median(v)) if v else None for k, v in width.items()},
            "truth": {k: float(ss.TRUTH[k]) for k in NAMES},
            "cpu_s": cpu,
        }
        r = out[label]
        print(f"Sea Splendour {label}, {seeds} seeds ({cpu:.0f} s CPU): ML failed {failed_ml}, OE failed {failed_oe}")
        for k in NAMES:
            med = r["median_estimate"][k]
            print(
                f"  {k:4s} truth {ss.TRUTH[k]:7.3f}  ML median {med if med is None else round(med, 3)!s:>7}  "
                f"95 % interval holds the truth in {100 * r['coverage_95'][k]:.0f} % of seeds, median width "
                f"{r['median_width_95'][k] if r['median_width_95'][k] is None else round(r['median_width_95'][k], 3)}"
            )
        print(f"  AIC prefers ML to OE in {r['aic_prefers_ml']} seeds (median ML {r['median_aic_ml']}, OE {r['median_aic_oe']})")
    return out


def timing(repeat: int = 3) -> dict:
    import dataclasses

    exp = dataclasses.replace(ss.EXPERIMENT_2, sample_time=1.0, duration_s=4410.0, missing=(0.0, 0.0), course_change_s=2200.0)
    d = _record(ss.simulate(exp, 0))
    n = len(d.t)
    oe = fit_model(d, ss.L, ss.V, "nomoto2", "oe")
    start = {**oe.p, "ln_q_x": 0.0, "ln_q_r": 0.0}
    fit(oe.structure, d, start, "ml")  # warm-up (numba load)
    one, whole = [], []
    for _ in range(repeat):
        t0 = time.process_time()
        f = fit(oe.structure, d, start, "ml")
        one.append(time.process_time() - t0)
        t0 = time.process_time()
        fit_model(d, ss.L, ss.V, "nomoto2", "ml")
        whole.append(time.process_time() - t0)
    r = {
        "samples": n,
        "one_ml_fit_cpu_s": float(np.median(one)),
        "fit_model_ml_cpu_s": float(np.median(whole)),
        "converged": f.converged,
    }
    print(
        f"one ML fit of the second-order model, {n} samples: {r['one_ml_fit_cpu_s']:.2f} s CPU (median of {repeat}; target 2 s); "
        f"with every start (fit_model): {r['fit_model_ml_cpu_s']:.2f} s; converged {f.converged}"
    )
    return r


def _overshoots(delta: np.ndarray, psi: np.ndarray, check_deg: float) -> list[float]:
    """Zig-zag overshoot angles [deg] (IMO MSC.137(76)): after each rudder reversal, how far the heading change
    from the approach heading goes beyond the check angle before the ship turns back; a segment cut off by the
    end of the record (its peak at its last sample) is left out."""
    neutral = 0.5 * (delta.max() + delta.min())
    d = delta - neutral
    half = 0.5 * (delta.max() - delta.min())
    sgn = np.where(np.abs(d) > 0.5 * half, np.sign(d), 0.0)
    nz = np.flatnonzero(sgn)
    rev = [nz[i] for i in range(1, len(nz)) if sgn[nz[i]] != sgn[nz[i - 1]]]
    dpsi = np.degrees(psi - psi[0])
    out = []
    for a, b in zip(rev, rev[1:] + [len(psi) - 1]):
        seg = np.sign(dpsi[a]) * dpsi[a : b + 1]
        if np.argmax(seg) < len(seg) - 1:
            out.append(float(seg.max() - check_deg))
    return out


def model_zigzag(f, amp_deg: float, first_side: float, duration_s: float = 1200.0) -> list[float]:
    """The identified model's own zig-zag (IMO MSC.137(76)): rudder to ``first_side`` * amp at 2.32 deg/s (the
    KVLCC2 steering gear), reversed each time the heading change reaches the check angle; its overshoots [deg].
    Rudder sign as recorded (a positive delta turns the KVLCC2 to port); the fitted rudder offset is kept."""
    from identify.steering.models import discretize

    p = dict(f.p)
    p = {k.split("@")[0]: v for k, v in p.items() if "@" not in k or k.endswith("@0")}
    p.update({"r_0": 0.0, "psi_0": 0.0, "rdot_0": 0.0, "b_r": 0.0})
    A, B, C, D, x0, _ = f.structure.system(p)
    Phi, Gam, _ = discretize(A, B, np.zeros_like(A), np.array([1.0]), 0.0)
    x, rud = np.zeros(len(x0)), 0.0
    target = -first_side * np.radians(amp_deg)  # recorded sign: a negative delta turns to starboard
    psi, reversals = [], []
    for k in range(int(duration_s)):
        rud += float(np.clip(target - rud, -np.radians(2.32), np.radians(2.32)))
        x = Phi[0] @ x + Gam[0] @ np.array([rud, 1.0, rud])
        psi.append(float(np.degrees(x[-1])))
        if -np.sign(target) * psi[-1] >= amp_deg:  # the heading change the rudder drives reached the check angle
            target = -target
            reversals.append(k)
    psi = np.array(psi)
    out = []
    for a, b in zip(reversals, reversals[1:]):
        seg = np.sign(psi[a]) * psi[a : b + 1]
        out.append(float(seg.max() - amp_deg))
    return out[:4]


def kvlcc2() -> dict:
    files = {a: [ROOT / "diagnose" / "data" / f"MARIN_FREE_KVLCC2_zz_{s}{a}_m.dat" for s in ("", "-")] for a in (10, 20)}
    out = {}
    for amp, paths in files.items():
        recs, speeds = [], []
        for p in paths:
            r, u, _ = read_records(p)
            recs += r
            speeds.append(u)
        V = float(np.mean(speeds))
        row = {"V_mps": V}
        for model in ("nomoto1", "nomoto2"):
            for label, data in [(p.name, [d]) for p, d in zip(paths, recs)] + [("pooled", recs)]:
                f = fit_model(data, 320.0, V, model, "ml")
                ok = f.ok and all(np.isfinite(e.value) and np.isfinite(e.std) for e in nomoto_parameters(f).values())
                entry = {"ok": bool(ok)}
                if ok:
                    entry["nomoto"] = {k: [e.value, e.std] for k, e in nomoto_parameters(f).items()}
                    if label == "pooled":
                        entry["overshoots_deg"] = [
                            {
                                "record": Path(rec.source).name,
                                "measured": _overshoots(rec.delta, rec.y[:, rec.channels.index("psi")], amp),
                                "model_driven_by_measured_rudder": _overshoots(rec.delta, ys[:, 1], amp),
                                "model_own_zigzag": model_zigzag(f, amp, 1.0 if "_-" not in rec.source else -1.0),
                            }
                            for rec, ys in zip(recs, f.y_sim)
                        ]
                row[f"{model} {label}"] = entry
        out[f"{amp}/{amp}"] = row
    _print_kvlcc2(out)
    return out


def _print_kvlcc2(out: dict) -> None:
    for amp, row in out.items():
        print(f"KVLCC2 {amp} zig-zags (V = {row['V_mps']:.2f} m/s mean recorded, L = 320 m), maximum likelihood:")
        for key, e in row.items():
            if key == "V_mps":
                continue
            if not e["ok"]:
                print(f"  {key:36s} FAILED (not converged or parameters undetermined)")
                continue
            txt = ", ".join(f"{k} {v:.3f} +- {1.96 * s:.3f}" for k, (v, s) in e["nomoto"].items())
            print(f"  {key:36s} {txt}")
            for o in e.get("overshoots_deg", []):
                print(
                    f"    overshoots {o['record']}: measured {', '.join(f'{x:.1f}' for x in o['measured'][:4])}; model's own "
                    f"zig-zag {', '.join(f'{x:.1f}' for x in o['model_own_zigzag'][:4])}; model driven by the measured rudder "
                    f"{', '.join(f'{x:.1f}' for x in o['model_driven_by_measured_rudder'][:4])} deg"
                )
    a, b = out["10/10"].get("nomoto1 pooled", {}), out["20/20"].get("nomoto1 pooled", {})
    if a.get("ok") and b.get("ok"):
        for k in ("K'", "T'"):
            (va, sa), (vb, sb) = a["nomoto"][k], b["nomoto"][k]
            print(
                f"  first-order {k}: 10/10 {va:.3f} +- {1.96 * sa:.3f} vs 20/20 {vb:.3f} +- {1.96 * sb:.3f}: "
                f"difference {va - vb:.3f} ({abs(va - vb) / np.hypot(sa, sb):.1f} standard errors)"
            )


# Källström (1977) Table 3.5 (AIC of each part) and Table 3.8 (cross-validation AIC), as printed
PRINTED_PARTS = {(1, "oe"): -279, (1, "ml"): -299, (2, "oe"): -200, (2, "ml"): -321}
PRINTED_CROSS = {(2, 1, "oe"): -158, (2, 1, "ml"): -163, (1, 2, "oe"): -250, (1, 2, "ml"): -262}


def split(seeds: int) -> dict:
    """Experiment 1 split at the course change (1158-1732 s left out, as Källström did), each part by OE and ML,
    each part's models cross-validated on the other part (Table 3.8)."""
    from identify.steering.crossval import cross_validate, split_record

    rows_all, parts_all = [], []
    for seed in range(seeds):
        p1, p2 = split_record(_record(ss.simulate(ss.EXPERIMENT_1, seed)), 1158.0, 1732.0)
        fits, rows = cross_validate((p1, p2), ss.L, ss.V)
        parts_all.append({k: (f.aic if f.converged else np.nan) for k, f in fits.items()})
        rows_all.append(
            {
                (r.data_part, r.model_part, r.estimator): (r.fit.aic if r.fit is not None and r.fit.converged else np.nan)
                for r in rows
            }
        )
    print(
        f"Experiment 1 split at 1158-1732 s, {seeds} seeds: median AIC (ours: r and psi; Källström: 4 outputs in knots and deg,"
    )
    print("so only the order within a column compares)")
    out = {"parts": {}, "cross": {}}
    for k, printed in PRINTED_PARTS.items():
        v = np.array([p[k] for p in parts_all])
        out["parts"][f"part {k[0]} {k[1]}"] = {
            "median_aic": float(np.nanmedian(v)),
            "failed": int(np.isnan(v).sum()),
            "printed": printed,
        }
        print(
            f"  part {k[0]} {k[1].upper():3s}: ours {np.nanmedian(v):9.1f} (failed {int(np.isnan(v).sum())})   Table 3.5 {printed}"
        )
    for k, printed in PRINTED_CROSS.items():
        v = np.array([r[k] for r in rows_all])
        out["cross"][f"part {k[0]} data, model from part {k[1]} {k[2]}"] = {
            "median_aic": float(np.nanmedian(v)),
            "printed": printed,
        }
        print(f"  part {k[0]} data, model from part {k[1]} {k[2].upper():3s}: ours {np.nanmedian(v):9.1f}   Table 3.8 {printed}")
    for dp, mp in ((2, 1), (1, 2)):
        ml_wins = sum(r[(dp, mp, "ml")] < r[(dp, mp, "oe")] for r in rows_all)
        print(
            f"  part {dp} data: the part-{mp} ML model generalises better than the OE model (lower AIC) in {ml_wins}/{seeds} seeds"
        )
        out["cross"][f"ml_better_on_part_{dp}"] = f"{ml_wins}/{seeds}"
    ml_parts = sum(p[(i, "ml")] < p[(i, "oe")] for p in parts_all for i in (1, 2))
    print(f"  within the parts AIC prefers ML to OE in {ml_parts}/{2 * seeds} part fits (Källström: both parts)")
    out["ml_preferred_in_parts"] = f"{ml_parts}/{2 * seeds}"
    return out


def wind(seeds: int) -> dict:
    """nomoto2 with and without phi_3 on the simulated experiment 2 (its wind turns with the heading)."""
    cover = {w: {k: 0 for k in NAMES} for w in (False, True)}
    ok = {False: 0, True: 0}
    prefer = {"ml": 0, "oe": 0}
    t0 = time.process_time()
    for seed in range(seeds):
        d = _record(ss.simulate(ss.EXPERIMENT_2, seed))
        fits = {(w, e): fit_model(d, ss.L, ss.V, "nomoto2", e, wind=w) for w in (False, True) for e in ("ml", "oe")}
        for w in (False, True):
            if fits[w, "ml"].ok:
                ok[w] += 1
                nm = nomoto_parameters(fits[w, "ml"])
                for k in NAMES:
                    cover[w][k] += nm[k].covers(ss.TRUTH[k])
        for e in prefer:
            prefer[e] += fits[True, e].aic < fits[False, e].aic
    print(f"Wind term phi_3, experiment 2 (15 s), {seeds} seeds, {time.process_time() - t0:.0f} s CPU:")
    for w in (False, True):
        print(
            f"  {'with' if w else 'without'} phi_3: ML ok {ok[w]}/{seeds}, 95 % intervals hold the truth (K'/T1'/T2'/T3') "
            + "/".join(f"{cover[w][k]}" for k in NAMES)
        )
    print(f"  AIC prefers phi_3: ML {prefer['ml']}/{seeds}, OE {prefer['oe']}/{seeds}")
    return {
        "seeds": seeds,
        "coverage": {str(w): cover[w] for w in cover},
        "ok": {str(w): ok[w] for w in ok},
        "aic_prefers_wind": prefer,
    }


def noise_corr(seeds: int) -> dict:
    """ML of the state-space model with R1(1,2) on experiment 2: default sea at 0.8, 6x sea at 0.8 and 0."""
    import dataclasses

    from identify.steering.models import RHO

    out = {}
    t0 = time.process_time()
    for sea_x, corr in ((1.0, 0.8), (6.0, 0.8), (6.0, 0.0)):
        hold = excl = prefer = ok = 0
        rhos = []
        for seed in range(seeds):
            run = ss.simulate(dataclasses.replace(ss.EXPERIMENT_2, sea=sea_x, sea_corr=corr), seed)
            d = SteeringData(run["t"], run["delta"], np.column_stack([run[c] for c in ("v", "r", "psi")]), ("v", "r", "psi"))
            f = fit_model(d, ss.L, ss.V, "state-space", "ml", noise_corr=True)
            g = fit_model(d, ss.L, ss.V, "state-space", "ml")
            sd = f.std[RHO]
            if not (f.ok and np.isfinite(sd)):
                continue
            ok += 1
            lo, hi = np.tanh(f.p[RHO] - 1.96 * sd), np.tanh(f.p[RHO] + 1.96 * sd)
            rhos.append(float(np.tanh(f.p[RHO])))
            hold += lo <= corr <= hi
            excl += not lo <= 0.0 <= hi
            prefer += f.aic < g.aic
        key = f"sea {sea_x:g}x, correlation {corr:g}"
        out[key] = {
            "ok": ok,
            "holds_truth": hold,
            "excludes_zero": excl,
            "aic_prefers": prefer,
            "rho_median": float(np.median(rhos)) if rhos else None,
        }
        print(
            f"R1 cross-correlation, experiment 2, {key}, {seeds} seeds: ML ok with an interval "
            f"{ok}/{seeds}, interval holds {corr} {hold}/{seeds}, excludes 0 {excl}/{seeds}, AIC prefers it {prefer}/{seeds}, "
            f"median rho {out[key]['rho_median']}"
        )
    print(f"  {time.process_time() - t0:.0f} s CPU")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--parts", default="sea,split,time,kvlcc2")
    ap.add_argument("--experiments", default="1,2", help="Sea Splendour experiments to run (1: 30 s, 2: 15 s)")
    ap.add_argument("--sample-times", default="", help="also experiment 1 read every h s, e.g. 20,25 (coverage against sampling)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    parts = a.parts.split(",")
    res = {}
    if "time" in parts:
        res["time"] = timing()
    if "kvlcc2" in parts:
        res["kvlcc2"] = kvlcc2()
    if "sea" in parts:
        res["sea"] = sea(a.seeds, a.experiments, a.sample_times)
    if "split" in parts:
        res["split"] = split(min(a.seeds, 20))
    if "wind" in parts:
        res["wind"] = wind(a.seeds)
    if "noise-corr" in parts:
        res["noise_corr"] = noise_corr(a.seeds)
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
