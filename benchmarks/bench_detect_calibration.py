"""Is ``detect``'s calibration right on the podded truth family? Each unchanged run's exceedance level,
from the truth bench's stored screenings (benchmarks/bench_detect_truth.py ``--cache``).

A run's level is the fraction of its own screening's no-change records (the 400 of
``nullsim.null_records``, with the structural draw ``glr.null_peaks`` adds, as ``glr.calibrate``
builds them) whose largest LR-CUSUM statistic is at least the run's, combined over the candidates
the way ``calibrate`` combines them ("any candidate over the same quantile"): with ``u_k(x)`` the
fraction of candidate ``k``'s null peaks at or above ``x``, a record's score is ``min_k u_k``, and the
run's level is the fraction of null records whose score is at most the run's. For a calibrated
detector the levels of unchanged runs are uniform on (0, 1) (to within one record in 400), and the
LR-CUSUM stage alarms on a run exactly when its level is at most the design rate (the verdict's
``--min-change`` and 2-sd tests then drop some of those, a separate filter: the false-alarm rate is at
most P(level <= design)). The fraction below 2, 5, 10,
25 and 50 % (95 % Clopper-Pearson intervals) and a Kolmogorov-Smirnov test against uniform are
printed per variant, pooled, and per ship (prior): far more sensitive than the false-alarm count.

Then, per prior, each unchanged run's whole-record change estimate along each candidate (the
verdict's GLR estimate) as a z-score against the spread of the same estimate over the run's null
records (``z_null``: noise and the bootstrap's parameter errors) and against the verdict's sd (that
and the structure in quadrature). If the null records describe the runs, z has mean 0 and sd 1 over
the runs of every prior; a prior's own parameter error is one fixed offset shared by all its runs
(mean off 0, sd below 1 within the prior), while the bootstrap draws it afresh per record.

    python benchmarks/bench_detect_calibration.py --cache DIR:KEY:FIRSTSHIP:NSHIPS [...]   # one per stored screening
    python benchmarks/bench_detect_calibration.py --cache /tmp/dcache:8667c7204102:102:2   # ships 102-103
    python benchmarks/bench_detect_calibration.py --cache DIR:KEY:108:2 --design 0.005 0.01 0.02   # re-decided at these rates
    python benchmarks/bench_detect_calibration.py --cache DIR:KEY:102:2 --own-misfit robust   # stop 49: the run's own misfit
"""

from __future__ import annotations

import argparse
import pickle
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.bench_detect_structure import _one, redecide, theta1, with_structure
from benchmarks.bench_detect_truth import HULL, change_times, prior_name, row, screen_name, stored_recording, summarise
from benchmarks.detect_ownmisfit import OWN, levels, with_own
from identify.detect.api import load_runs
from identify.detect.checks import MOMENT
from identify.detect.glr import SignatureCusum, exceedance_level, null_peaks
from identify.detect.inputs import Deriver, signals
from identify.detect.priorfit import structural_spread
from identify.detect.verdict import Whitened, implausible_inertia, verdict
from identify.detect.yawmodel import CANDIDATES, NOMINAL, block_mean, shift_moment

#: how a stored screening is named on the command line (benchmarks/bench_detect_truth.py --cache's folder and key);
#: no default: the stores of ships 100-107 the bench once read by default are gone (stop 53)
CACHE_FORM = "DIR:KEY:FIRSTSHIP:NSHIPS"
VARIANTS = ("nominal-mmg", "strong-roll", "pod-interaction", "steering-lag-acting", "coloured-noise")
CUTS = (0.02, 0.05, 0.10, 0.25, 0.50)


_PRIORS: dict = {}


def load_prior(folder: Path, key: str, variant: str, ship: int, setting: str = "stored"):
    """The stored prior of a ship, its structure as ``setting`` says: bench_detect_structure's settings, or
    ``gate=G``: recomputed from the cached nominal recording by ``priorfit.structural_spread(gate=G)``
    (the prior's fit, bootstrap and everything else as stored; about 6 s CPU a prior)."""
    prior = pickle.loads(_one(folder, prior_name(stored_recording(variant, ship, "*"), key)).read_bytes())
    if not setting.startswith("gate="):
        return with_structure(prior, setting)
    k = (str(folder), key, variant, ship, setting)
    if k not in _PRIORS:
        rec = load_runs([_one(folder, stored_recording(variant, ship, "*"))])[0]
        sig, r = signals(rec, prior.kind)  # as fit_prior hands them to priorfit.fit: the moment shifted
        sig = shift_moment(sig, prior.moment_shift_s, prior.dt) if MOMENT in rec.channels else sig
        x = np.array([prior.values[n] / NOMINAL[n] for n in prior.names])
        s = structural_spread(prior, sig, r, x, Deriver.of(rec, prior.kind), 0, gate=float(setting[5:]))
        _PRIORS[k] = replace(prior, structure=s)
    return _PRIORS[k]


def run_record(sc, prior, seed: int = 0) -> dict:
    """One unchanged run's level, verdict, and whole-record change estimate with its null spreads."""
    det = SignatureCusum(prior, theta1(), band=sc.roll_band)
    peaks = null_peaks(det, sc.S, sc.null_blocks, seed)
    stat = det.statistics(block_mean(sc.eps, prior.block), sc.S)
    lv = float(exceedance_level(peaks, stat.max(axis=0)))
    wd = Whitened.of(sc.eps, sc.S, prior, sc.null_blocks, sc.roll_band)
    n = len(sc.eps)
    nb = n // prior.block
    Sw, ew, nw = wd.Sw[:nb], wd.ew[:nb], wd.nw[:nb]
    den = np.sum(Sw**2, axis=0)
    est = Sw.T @ ew / den
    null_est = (Sw.T @ nw) / den[:, None]  # (k, runs)
    sd_null = null_est.std(axis=1)
    sd_verdict = np.sqrt(sd_null**2 + prior.structure**2)
    # the null records cycle the prior's B bootstrap errors (nullsim.null_records: record j is ship j % B):
    # the spread within one error is the noise's, that of the errors' means the parameter error's
    B = len(prior.boot)
    sd_noise = sd_par = np.full(len(est), np.nan)
    if B and sc.null_diverged == 0 and null_est.shape[1] >= 2 * B:
        g = np.arange(null_est.shape[1]) % B
        within = np.mean([null_est[:, g == b].var(axis=1, ddof=1) for b in range(B)], axis=0)
        means = np.array([null_est[:, g == b].mean(axis=1) for b in range(B)])
        sd_noise = np.sqrt(within)
        sd_par = np.sqrt(np.maximum(means.var(axis=0, ddof=1) - within / (null_est.shape[1] / B), 0.0))
    out = {"level": lv, "est": est, "sd_null": sd_null, "sd_verdict": sd_verdict, "sd_noise": sd_noise, "sd_par": sd_par}
    return out | {"structure": np.asarray(prior.structure, float)}


def clopper(k: int, n: int) -> tuple[float, float]:
    from scipy.stats import beta

    lo = beta.ppf(0.025, k, n - k + 1) if k > 0 else 0.0
    hi = beta.ppf(0.975, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def table_row(label: str, lv: list[float]) -> str:
    from scipy.stats import kstest

    a = np.asarray(lv)
    n = len(a)
    if n == 0:
        return f"{label:28s}    0"
    cells = []
    for c in CUTS:
        k = int(np.sum(a < c))
        lo, hi = clopper(k, n)
        cells.append(f"{100 * k / n:5.1f} [{100 * lo:4.1f},{100 * hi:5.1f}]")
    ks = kstest(a, "uniform")
    return f"{label:28s} {n:4d}  " + "  ".join(cells) + f"   KS D {ks.statistic:.3f} p {ks.pvalue:.3g}"


def collect(
    caches: list[str], variants: tuple[str, ...], runs: int = 10, setting: str = "stored", own: str = "stored"
) -> list[dict]:
    out = []
    for spec in caches:
        folder, key, first, ships = spec.split(":")
        for v in variants:
            for ship in range(int(first), int(first) + int(ships)):
                prior = load_prior(Path(folder), key, v, ship, setting)
                if implausible_inertia(prior, **HULL):
                    out.append({"variant": v, "ship": ship, "refused": True})
                    continue
                for i, ch in enumerate(change_times(ship, runs)):
                    if ch is not None:
                        continue
                    sc = pickle.loads(_one(Path(folder), screen_name(stored_recording(v, ship, "*", runs, i), key)).read_bytes())
                    sc, extra = with_own(sc, prior, own)
                    rec = run_record(sc, prior)

                    d = redecide(sc, prior)
                    stored = verdict(sc, prior, **HULL)  # the stored thresholds
                    rec |= {"variant": v, "ship": ship, "run": i, "alarm": d.changed, "alarm_stored": stored.changed}
                    rec |= {"h_same": bool(np.array_equal(d.threshold, sc.h))}  # bit for bit: the same code
                    s_run, s_null = levels(prior, sc.eps, sc.S, sc.null_blocks)
                    rec |= {"own_misfit": extra, "sigma_w": prior.sigma_w, "own_ratio": s_run / s_null}
                    out.append(rec)
    return out


def report(rows: list[dict]) -> None:
    runs = [r for r in rows if not r.get("refused")]
    refused = sorted({(r["variant"], r["ship"]) for r in rows if r.get("refused")})
    head = "  ".join(f"<{100 * c:2.0f} % [95 % CI]  " for c in CUTS)
    print(f"exceedance levels of unchanged runs (uniform if calibrated); % of runs below each level\n{'':28s} {'n':>4s}  {head}")
    for v in VARIANTS:
        sel = [r["level"] for r in runs if r["variant"] == v]
        if sel:
            print(table_row(v, sel))
    print(table_row("pooled", [r["level"] for r in runs]))
    if runs:
        from scipy.stats import spearmanr

        ratio = np.array([r["own_ratio"] for r in runs])
        rho = spearmanr(ratio, [r["level"] for r in runs])
        print(
            f"run's own misfit level / its records' (stop 49; after the best change-point fit): median {np.median(ratio):.2f}, "
            f"range {ratio.min():.2f}-{ratio.max():.2f}, over 1.1 on {np.sum(ratio > 1.1)} of {len(ratio)}; "
            f"Spearman with the level {rho.statistic:+.2f} (p {rho.pvalue:.2g})"
        )
    print(f"refused priors (runs not tested): {refused}")
    print("\nper ship (prior): levels, and verdict alarms (re-decided; stored thresholds; h reproduced: bit for bit)")
    for v in VARIANTS:
        for ship in sorted({r["ship"] for r in runs if r["variant"] == v}):
            sel = [r for r in runs if r["variant"] == v and r["ship"] == ship]
            lv = np.sort([r["level"] for r in sel])
            fa = sum(r["alarm"] for r in sel)
            fs = sum(r["alarm_stored"] for r in sel)
            print(
                f"  {v[:15]:15s} {ship}: FA {fa}/{len(sel)} (stored h {fs}), h reproduced {all(r['h_same'] for r in sel)}; "
                f"levels {' '.join(f'{x:.3f}' for x in lv)}"
            )
            ratios = " ".join(f"{r['own_ratio']:.2f}" for r in sel)
            print(f"    own misfit level / its records' (stop 49): {ratios}")
            own = np.array([r["own_misfit"] / r["sigma_w"] for r in sel])
            if np.any(own > 0):
                print(f"    own misfit added on {np.sum(own > 0)} runs, / sigma_w: {' '.join(f'{x:.2f}' for x in own)}")
    print("\nz = whole-record change estimate / sd over the run's null records (z_null) and / the verdict's sd (z_v);")
    print("per prior: mean and sd over its unchanged runs, per candidate (I_r, damping, pod gain)")
    for v in VARIANTS:
        for ship in sorted({r["ship"] for r in runs if r["variant"] == v}):
            sel = [r for r in runs if r["variant"] == v and r["ship"] == ship]
            est = np.array([r["est"] for r in sel])
            zn = est / np.array([r["sd_null"] for r in sel])
            zv = est / np.array([r["sd_verdict"] for r in sel])
            sdn = np.mean([r["sd_null"] for r in sel], axis=0)
            print(
                f"  {v[:15]:15s} {ship}: est % mean {np.array2string(100 * est.mean(0), precision=2)} sd "
                f"{np.array2string(100 * est.std(0, ddof=1), precision=2)}; null sd % {np.array2string(100 * sdn, precision=2)}; "
                f"z_null mean {np.array2string(zn.mean(0), precision=2)} sd {np.array2string(zn.std(0, ddof=1), precision=2)}; "
                f"z_v mean {np.array2string(zv.mean(0), precision=2)}"
            )
    noise_parameter_split(runs)


def rms(x) -> np.ndarray:
    return np.sqrt(np.nanmean(np.square(x), 0))


def fmt(x) -> str:
    return np.array2string(np.asarray(x), precision=2)


def noise_parameter_split(runs: list[dict]) -> None:
    """The runs' whole-record change estimates against the null records' model of them, per variant (rms over
    its priors). Per run the null model is ``est = p + s + n``: ``p`` the prior's parameter error (sd
    ``sd_par``; one value shared by all runs of a prior, drawn afresh per record in the null), ``s`` the
    structural apparent change (sd ``prior.structure``, drawn per record by ``glr.null_peaks``) and ``n`` the
    noise (sd ``sd_noise``). So over the ``n_p`` runs of one prior, the spread about their mean has sd
    sqrt(sd_noise^2 + structure^2), and the mean's square has expectation
    sd_par^2 + mean(sd_noise^2 + structure^2) / n_p: the ratios printed are 1 and about 1.04-1.27 (printed beside
    them) if the model holds. For z = est / sd_null (sd_null^2 = sd_noise^2 + sd_par^2; structure left out) the model
    predicts a variance within a prior of sd_noise^2 / sd_null^2 and of the priors' means of
    sd_par^2 / sd_null^2 + that / n_p (printed beside the measured ones)."""
    groups: dict = {}
    for r in runs:
        groups.setdefault((r["variant"], r["ship"]), []).append(r)
    print("\nthe null records' spread of that estimate split into noise (within one bootstrap error) and parameter error")
    print("(between them); the runs': spread about their prior's mean over the noise sd and over sqrt(noise^2 + structure^2)")
    print("(1 if the null describes the runs), and the prior's mean (its own parameter error, shared by its runs) over the")
    print("parameter sd (expected value printed beside it); rms over a variant's priors")
    for v in VARIANTS:
        w, ws, o, oref = [], [], [], []
        for (gv, _), sel in groups.items():
            if gv != v:
                continue
            est = np.array([r["est"] for r in sel])
            sn = np.array([r["sd_noise"] for r in sel])
            rest = sn**2 + np.array([r["structure"] for r in sel]) ** 2
            sp = np.mean([r["sd_par"] for r in sel], axis=0)
            w.append(((est - est.mean(0)) / sn).std(0, ddof=1))
            ws.append(((est - est.mean(0)) / np.sqrt(rest)).std(0, ddof=1))
            o.append(est.mean(0) / sp)
            oref.append(1 + rest.mean(0) / (len(sel) * sp**2))
        if w:
            print(
                f"  {v:20s} runs' spread / noise sd {fmt(rms(w))}, / sqrt(noise^2 + structure^2) {fmt(rms(ws))}   "
                f"prior's offset / parameter sd {fmt(rms(o))} (expected {fmt(np.sqrt(np.nanmean(oref, 0)))})"
            )
    allz = np.array([r["est"] / r["sd_null"] for r in runs])
    print(
        f"\nall runs: z_null mean {fmt(allz.mean(0))}, sd {fmt(allz.std(0, ddof=1))}, "
        f"rms {fmt(np.sqrt((allz**2).mean(0)))} ({' / '.join(CANDIDATES)})"
    )
    # how much of z's spread is per prior (shared by its runs) and how much per run, against the null model's
    z = [np.array([r["est"] / r["sd_null"] for r in g]) for g in groups.values()]
    within = np.mean([np.var(g, axis=0, ddof=1) for g in z], axis=0)
    between = np.var([np.mean(g, axis=0) for g in z], axis=0, ddof=1)
    ew = np.nanmean([np.mean([r["sd_noise"] ** 2 / r["sd_null"] ** 2 for r in g], 0) for g in groups.values()], axis=0)
    ep = np.nanmean([np.mean([r["sd_par"] ** 2 / r["sd_null"] ** 2 for r in g], 0) for g in groups.values()], axis=0)
    n_p = np.mean([len(g) for g in z])
    print(
        f"z_null variance within a prior {fmt(within)} (null model {fmt(ew)}), "
        f"of the priors' means {fmt(between)} (null model {fmt(ep + ew / n_p)})"
    )


def design_rows(
    caches: list[str], variants: tuple[str, ...], rates: list[float], runs: int = 10, setting: str = "stored", own: str = "stored"
) -> None:
    """bench_detect_truth's row per variant with every stored screening (unchanged and changed runs)
    re-decided at each design false-alarm rate (``glr.calibrate``'s ``false_alarm``; ``detect``'s default 0.02)."""
    print(f"\nre-decided at design rates {rates} (bench_detect_truth's columns; roll correlation not available here)")
    for v in variants:
        for rate in rates:
            studies = []
            for spec in caches:
                folder, key, first, ships = spec.split(":")
                for ship in range(int(first), int(first) + int(ships)):
                    prior = load_prior(Path(folder), key, v, ship, setting)
                    out = {"unchanged": [], "changed": [], "errors": []}
                    if implausible_inertia(prior, **HULL):
                        studies.append(out | {"refused": f"ship {ship}"})
                        continue
                    for i, ch in enumerate(change_times(ship, runs)):
                        sc = pickle.loads(
                            _one(Path(folder), screen_name(stored_recording(v, ship, "*", runs, i), key)).read_bytes()
                        )
                        d = redecide(with_own(sc, prior, own)[0], prior, false_alarm=rate)
                        res = {"alarm_s": d.alarm_s, "property": d.property, "change_s": ch, "h": float(d.threshold[0])}
                        res |= {"roll_max": float("nan"), "failed": False, "evidence": d.evidence}
                        out["unchanged" if ch is None else "changed"].append(res)
                    studies.append(out)
            print(row(f"{v[:9]}/{rate:g}", summarise(studies)), flush=True)


def check_caches(specs: list[str] | None) -> None:
    """Exit 2 with one line naming ``--cache`` and its form when no stored screening is given, or one is not
    ``DIR:KEY:FIRSTSHIP:NSHIPS`` with an existing DIR (the bench reads nothing else)."""
    example = "e.g. --cache /tmp/dcache:8667c7204102:102:2 (a folder of benchmarks/bench_detect_truth.py --cache)"
    if not specs:
        _fail(f"--cache is required: give each stored screening as {CACHE_FORM}, {example}")
    for spec in specs:
        parts = spec.split(":")
        if len(parts) != 4 or not (parts[2].isdigit() and parts[3].isdigit()):
            _fail(f"--cache {spec!r}: write {CACHE_FORM} (folder, cache key, first ship, number of ships), {example}")
        if not Path(parts[0]).is_dir():
            _fail(f"--cache {spec!r}: no folder {parts[0]}; give an existing stored screening as {CACHE_FORM}")


def _fail(msg: str) -> None:
    print(f"error: {msg}", file=sys.stderr)
    raise SystemExit(2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", nargs="*", help=f"{CACHE_FORM}, one per stored screening (required)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument(
        "--structure",
        default="stored",
        help="as bench_detect_structure's --structure, or gate=G (structure recomputed, priorfit.structural_spread(gate=G))",
    )
    ap.add_argument("--design", nargs="*", type=float, help="only re-decide every run at these design false-alarm rates")
    ap.add_argument(
        "--own-misfit",
        default="stored",
        help=f"the run's own misfit in stored screenings' records (screened before stop 49): {', '.join(OWN)}, bootL or bootpL (L s blocks; p: projected orthogonal to the signatures); stop 53: lowbL, scale, scaleb, scalei, mixW, bootnL (bootpL less the records' own white noise)",
    )
    a = ap.parse_args()
    check_caches(a.cache)
    warnings.simplefilter("ignore", RuntimeWarning)
    if a.design:
        design_rows(a.cache, tuple(a.variants), a.design, a.runs, a.structure, a.own_misfit)
        return
    report(collect(a.cache, tuple(a.variants), a.runs, a.structure, a.own_misfit))


if __name__ == "__main__":
    main()
