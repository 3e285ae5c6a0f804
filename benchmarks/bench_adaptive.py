"""Adaptive trial vs fixed plan (issue 28): a trial re-designed after its first third from the
recordings of that third (Ljungberg 2022, (7.58); :mod:`expdesign.adaptive`) against the fixed
plan of the same length, on simulated ships whose parameters differ from the profile's.

THE TRUTH IS THE ESTIMATOR'S OWN MODEL STRUCTURE AT DRAWN PARAMETERS (each parameter within
+-30 % of the profile's, seeded): evidence for the re-design's bookkeeping, not for a real ship;
:mod:`benchmarks.adaptive_mmg` runs the same loop on an independent truth (the MMG KVLCC2) scored
by held-out prediction. Recordings: white measurement noise on u, v, r (the figures printed), common random
numbers (:func:`sail_crn`). Parameter error of a trial: sqrt(mean(((theta_hat - theta_true) /
theta_true)^2)) over the non-zero parameters, the IV estimate (:func:`expdesign.estimators.estimate`)
from every run sailed; per truth the median over ``--runs`` noisy runs.

Per truth also, MODEL-BASED (:mod:`benchmarks.adaptive_model`, information matrices at the truth,
printed beside the measurements, never instead): the CEILING, the D-efficiency at the truth of the
fixed plan's rest against the best rest there, both counting the first third sailed
(:func:`expdesign.adaptive.rest_efficiency`; 1.0: no re-design can gain in D); a predicted error
ratio; ``--criterion-gap``: the same model's gain of a design in the scored metric (relative A).
Measured beside them: an oracle re-design at the truth, and a CONTROL re-designed from the same
recordings at the profile's values (no re-identification: what the re-design gains without
learning the ship), sailed as the other two; single-run wins (each run one noisy trial).
``--runs 0``: the model-based columns only. ``--score predictive``: the estimates scored by the
predictor's simulation of held-out noise-free runs of the truth (:func:`predictive_vs_fixed`;
refused where the predictor is not the ship's simulation model).

Design and scored estimate share ``--mean-subtraction`` (default batchwise). NOT what a default
``plan-trial --resume`` does: the resumed re-design keeps the plan's mean subtraction, 'complete'
unless the plan was made with ``--mean-subtraction batchwise``, and re-identifies batchwise;
``--mean-subtraction complete`` here measures that case (the fixed rest's D-efficiency at the
truth is then 0.992 or more on the model ship: little for a re-design to gain).

Second part: CPU time of resume + re-identify + re-design + re-plan for the default ship on the
bundled map (target < 5 s), through :func:`maps.resume.resume_plan` (the CLI adds imports and exports).

    nice -n 10 python benchmarks/bench_adaptive.py [--trials 20] [--seed 0] [--ship model-ship[,kvlcc2]] [--runs 10]
        [--mean-subtraction batchwise] [--criterion-gap] [--score parameters|predictive] [--timing-repeats 3]
"""

from __future__ import annotations

import argparse
import sys
import time
import zlib
from collections import Counter

import numpy as np

from benchmarks.adaptive_model import ceiling, criterion_gap, error_model
from expdesign import adaptive as ad
from expdesign.estimators import estimate
from maps.trialdesign import first_design, ship_library
from primitives.ship import load_profile

SPREAD = 0.30
NOISE = {"model-ship": (0.005, 0.005, 0.002), "kvlcc2": (0.05, 0.05, 0.0005)}


def noise_of(prof) -> tuple[float, float, float]:
    """The measurement noise std on u, v, r of ``prof``'s simulated recordings (the model ship's by default)."""
    return NOISE.get(prof.name, NOISE["model-ship"])


def interleave(counts: dict[str, int], lib: list) -> list:
    """The manoeuvres of ``counts`` in a round-robin sailing order (a plan mixes them too)."""
    left = dict(counts)
    seq = []
    while any(left.values()):
        for p in lib:
            if left.get(p.name, 0) > 0:
                seq.append(p)
                left[p.name] -= 1
    return seq


def param_error(prof, runs, truth: np.ndarray, ms: str) -> float:
    est = estimate(prof, [r.segment() for r in runs], method="iv", mean_subtraction=ms)
    th = est.theta[0]
    nz = truth != 0
    if not np.all(np.isfinite(th)):
        return float("inf")  # a failed fit: said, never a number
    return float(np.sqrt(np.mean(((th[nz] - truth[nz]) / truth[nz]) ** 2)))


def sail_crn(prof, prims: list, truth: np.ndarray, seed: tuple, seen: Counter) -> list:
    """:func:`expdesign.adaptive.sail` with common random numbers: the k-th time manoeuvre q is
    sailed in a run it meets the noise of stream (seed, q, k) whichever plan sails it, so two
    plans with the same manoeuvres get the same error and a difference is the design's."""
    noise = noise_of(prof)
    runs = []
    for p in prims:
        k = seen[p.name]
        seen[p.name] += 1
        runs += ad.sail(prof, [p], truth, noise, np.random.default_rng([*seed, zlib.crc32(p.name.encode()), k]), len(runs))
    return runs


def draw_truth(th0: np.ndarray, rng: np.random.Generator, corners: bool = False) -> np.ndarray:
    """A truth within +-SPREAD of the profile's parameters (uniform), or (``corners``, --corners)
    on a corner of that box: every parameter exactly SPREAD off, random sign."""
    if corners:
        return th0 * (1 + SPREAD * rng.choice([-1.0, 1.0], th0.shape))
    return th0 * (1 + SPREAD * rng.uniform(-1, 1, th0.shape))


def first_third(seq: list) -> int:
    """The manoeuvres sailed before the re-design: the first third of the fixed plan, at least one."""
    return max(1, round(len(seq) / 3))


def rest_seconds(seq: list, n_first: int) -> float:
    """The time the re-design may fill: the fixed plan's own rest, not the trial's slack the
    first design's rounding left unused (a longer adaptive rest would win by length)."""
    return float(sum(p.duration_s for p in seq[n_first:]))


def one_run(prof, lib, seq, truth, seed, ms, oracle_counts):
    """One noisy trial at ``truth`` sailed four ways from the same first third (the same noise):
    the fixed plan's rest, the rest re-designed from that third's recordings, the rest
    re-designed knowing the truth (``oracle_counts``: what a perfect re-identification would
    sail), and the CONTROL: the rest re-designed from the same recordings at the profile's values
    (no re-identification; what counting the sailed information alone gains). Returns (fixed,
    adaptive, oracle, control error, the re-design, the control re-design)."""
    n_first = first_third(seq)
    seen: Counter = Counter()
    sailed = sail_crn(prof, seq[:n_first], truth, seed, seen)
    e = [param_error(prof, sailed + sail_crn(prof, seq[n_first:], truth, seed, seen.copy()), truth, ms)]
    left = rest_seconds(seq, n_first)
    rd = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms)
    nominal = ad.Reidentification(ad.profile_predictor(prof, lib), prof.predictor_param_names, {})
    rd_nom = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms, reid=nominal)
    for counts in (rd.counts, oracle_counts, rd_nom.counts):
        e.append(param_error(prof, sailed + sail_crn(prof, interleave(counts, lib), truth, seed, seen.copy()), truth, ms))
    return *e, rd, rd_nom


def adaptive_vs_fixed(
    ship: str, trials: int, seed: int, lengths: float, runs: int, ms: str, gaps: bool, corners: bool = False
) -> dict:
    prof = load_profile(ship)
    lib = ship_library(prof)
    trial_s = lengths * sum(p.duration_s for p in lib)
    fixed = first_design(prof, lib, trial_length_s=trial_s, mean_subtraction=ms).design.counts
    seq = interleave(fixed, lib)
    n_first = first_third(seq)
    print(
        f"{ship}: trial {trial_s:.0f} s of manoeuvres, fixed plan {fixed} sailed round-robin, re-designed after "
        f"{n_first} of {len(seq)}; truths {'at' if corners else 'within'} +-{SPREAD:.0%} (seed {seed}); {runs} noisy runs per truth; "
        f"mean subtraction {ms} (design and estimate)"
    )
    print(f"noise std u, v, r {noise_of(prof)}; TRUTH = THE ESTIMATOR'S OWN MODEL AT DRAWN PARAMETERS")
    print("parameter error rms((theta_hat - theta) / theta), median over the runs; oracle: the rest re-designed at the truth;")
    print("run wins: runs (one noisy trial each, common random numbers) where the adaptive error is lower, of those that differ;")
    print(
        "pred: model-based asymptotic error ratio adaptive/fixed and oracle/fixed (benchmarks/adaptive_model.py), not a measurement;"
    )
    print(
        "eff fixed / eff adapt (model-based): D-efficiency at the truth of the fixed / re-designed rest against the best rest there"
    )
    print(
        "c.ratio: measured error ratio control/fixed, the control the rest re-designed from the same recordings at the "
        "profile's values (no re-identification); eff ctrl (model-based): its rest's D-efficiency at the truth"
    )
    print("(eff fixed is the ceiling: 1.0 = no re-design can gain in D); A/D, A/A (model-based, --criterion-gap): predicted")
    print(
        "error of the rest optimal at the truth for the scored metric over the fixed D rest's / over that metric's fixed rest\n"
    )
    rest_fixed_s = rest_seconds(seq, n_first)
    print(
        f"{'trial':>5} {'fixed':>8} {'adaptive':>9} {'ratio':>6} {'oracle':>8} {'o.ratio':>7} {'run wins':>8} "
        f"{'pred':>5} {'o.pred':>6} {'eff fixed':>9} {'eff adapt':>9} {'c.ratio':>7} {'eff ctrl':>8} {'A/D':>6} {'A/A':>6}  re-designed rest (first run)"
    )
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(28, 5)))
    th0 = prof.params()
    noise = noise_of(prof)
    rows = []
    fixed_rest = Counter(p.name for p in seq[n_first:])
    for t in range(trials):
        truth = draw_truth(th0, rng, corners)
        oracle, eff_fixed, sailed0, left0 = ceiling(prof, lib, seq[:n_first], seq[n_first:], truth, ms)
        res = [one_run(prof, lib, seq, truth, (seed, t, j), ms, oracle.counts) for j in range(runs)]
        ef, ea, eo, en = (np.array([r[i] for r in res]) for i in range(4))
        failed = int(sum((~np.isfinite(x)).sum() for x in (ef, ea, eo, en)))
        # a failed fit (inf) counts as the worst run; --runs 0: the model-based columns only
        mf, ma, mo, mn = (np.median(x) if runs else np.nan for x in (ef, ea, eo, en))
        ok = np.isfinite(mf) and np.isfinite(ma)
        _, pred = error_model(prof, lib, sailed0, truth, left0, ms, noise)
        pe = {k: pred(c) for k, c in (("f", fixed_rest), ("o", oracle.counts))}
        pa = np.median([pred(r[4].counts) for r in res]) if runs else np.nan
        gap_d, gap_a = criterion_gap(prof, lib, seq[:n_first], seq[n_first:], truth, th0, ms, noise) if gaps else (np.nan, np.nan)
        row = {
            "ratio": ma / mf if ok else float("nan"),
            "oratio": mo / mf if ok and np.isfinite(mo) else float("nan"),
            "win": bool(ok and ma < mf),
            "owin": bool(ok and mo < mf),
            "nratio": mn / mf if ok and np.isfinite(mn) else float("nan"),
            "nwin": bool(ok and mn < mf),
            "a_vs_n": bool(ok and ma < mn),
            "run_wins": int((ea < ef).sum()),
            "run_differ": int((ea != ef).sum()),
            "pred": pa / pe["f"],
            "opred": pe["o"] / pe["f"],
            "eff": eff_fixed,
            "gap_d": gap_d,
            "gap_a": gap_a,
            "eff_ad": ad.rest_efficiency(prof, lib, sailed0, truth, res[0][4].counts, left0, oracle.logdet_continuous, ms)
            if runs
            else np.nan,
            "eff_n": ad.rest_efficiency(prof, lib, sailed0, truth, res[0][5].counts, left0, oracle.logdet_continuous, ms)
            if runs
            else np.nan,
        }
        rows.append(row)
        # the rests compared must be of one length (fixed/adaptive manoeuvring seconds); flagged when not
        unequal = max((r[4].planned_s for r in res), default=0.0) > rest_fixed_s + 1e-6
        print(
            f"{t:5d} {mf:8.4f} {ma:9.4f} {row['ratio']:6.3f} {mo:8.4f} {row['oratio']:7.3f} "
            f"{row['run_wins']:>4}/{row['run_differ']:<3} {row['pred']:5.3f} {row['opred']:6.3f} {eff_fixed:9.4f} "
            f"{row['eff_ad']:9.4f} {row['nratio']:7.3f} {row['eff_n']:8.4f} {gap_d:6.3f} {gap_a:6.3f}  {dict(res[0][4].counts) if runs else dict(oracle.counts)}"
            + (f"  ({failed} fit(s) failed)" if failed else "")
            + ("  ADAPTIVE REST LONGER" if unequal else "")
        )
    col = {k: np.array([r[k] for r in rows], float) for k in rows[0]}
    wins, owins = int(col["win"].sum()), int(col["owin"].sum())
    rw, rd = int(col["run_wins"].sum()), int(col["run_differ"].sum())
    r, ef = col["ratio"], col["eff"]
    print()
    if runs:
        print(
            f"{ship}: adaptive lower in {wins} of {trials} trials ({wins / trials:.0%}; Done-when >= 75 %); "
            f"median ratio adaptive/fixed {np.nanmedian(r):.3f}; trials without a defined median {int(np.isnan(r).sum())}"
        )
        print(
            f"{ship}: single noisy runs: adaptive lower in {rw} of the {rd} that differ ({rw / max(rd, 1):.0%}); "
            f"oracle re-design lower in {owins} of {trials} ({owins / trials:.0%}), median ratio {np.nanmedian(col['oratio']):.3f}"
        )
        print(
            f"{ship}: predicted (model-based) ratio adaptive/fixed median {np.median(col['pred']):.3f}, below 1 in "
            f"{int((col['pred'] < 1).sum())} of {trials}"
        )
        nw, avn = int(col["nwin"].sum()), int(col["a_vs_n"].sum())
        print(
            f"{ship}: CONTROL (the rest re-designed from the same recordings at the profile's values, no re-identification) "
            f"lower than fixed in {nw} of {trials}, median ratio control/fixed {np.nanmedian(col['nratio']):.3f}, its rest's "
            f"D-efficiency at the truth (model-based) median {np.nanmedian(col['eff_n']):.4f}; adaptive lower than the "
            f"control in {avn} of {trials}"
        )
    print(
        f"{ship}: predicted (model-based) ratio oracle/fixed median {np.median(col['opred']):.3f}, below 1 in "
        f"{int((col['opred'] < 1).sum())} of {trials}"
    )
    print(
        f"{ship}: CEILING (model-based) fixed rest's D-efficiency at the truth: min {ef.min():.4f}, median {np.median(ef):.4f}, "
        f"under 0.99 in {int((ef < 0.99).sum())} of {trials}"
        + (f"; re-designed rest's median {np.median(col['eff_ad']):.4f}" if runs else "")
    )
    if gaps:
        print(
            f"{ship}: scored-metric optimum at the truth over the fixed D rest (model-based) median {np.median(col['gap_d']):.3f}, "
            f"over that metric's fixed rest median {np.median(col['gap_a']):.3f} (min {col['gap_a'].min():.3f})"
        )
    return {"ship": ship, "trials": trials, "wins": wins, "run_wins": rw, "run_differ": rd}


def predictive_error(prof, runs, heldout: list, ms: str) -> float:
    """The IV estimate from ``runs`` scored by :func:`simulation_error` on ``heldout``."""
    est = estimate(prof, [r.segment() for r in runs], method="iv", mean_subtraction=ms)
    th = est.theta[0]
    return simulation_error(prof, th, heldout) if np.all(np.isfinite(th)) else float("inf")


def simulation_error(prof, th: np.ndarray, heldout: list) -> float:
    """The predictor simulated at ``th`` through the inputs of each held-out recording (from its
    first state) against the recorded velocities; RMS over u, v, r of the error normalised by
    each signal's RMS, mean over the recordings; inf for a diverging prediction (the worst,
    never a number). Meaningful only where the predictor can simulate the ship."""
    from primitives.simulate import signals_read, simulate

    out = []
    for r in heldout:
        with np.errstate(all="ignore"):
            sim = simulate(
                prof, r.inputs, th, terms=prof.predictor, nu0=r.y[0], positions="psi" in signals_read(prof.predictor)
            ).nu[0]
        if not np.all(np.isfinite(sim)):
            return float("inf")
        out.append(np.sqrt(np.mean(((sim - r.y) / np.maximum(np.sqrt(np.mean(r.y**2, axis=0)), 1e-9)) ** 2)))
    return float(np.mean(out))


def predictive_vs_fixed(ship: str, trials: int, seed: int, lengths: float, runs: int, ms: str, corners: bool = False) -> dict:
    """Fixed against adaptive scored by prediction of the truth's held-out runs (every library
    manoeuvre once, noise-free), the truth the profile's simulation model at drawn parameters: a
    score the user reads (how well the identified model predicts), not the parameters. Not for a
    ship whose predictor is not its simulation model: full-scale's predictor (9.2), estimated
    batchwise from its own noise-free library at the profile's values, predicts those runs at a
    normalised RMS error of 4.8 (67 estimated under complete, 64 under none: its structure is not
    the ship's), so the score there says nothing about the design: refused."""
    prof = load_profile(ship)
    if not ad.same_structure(prof):
        print(
            f"error: --score predictive: {ship}'s predictor is not its simulation model, so its prediction error "
            "says nothing about the design; use --score parameters or a ship whose predictor simulates it",
            file=sys.stderr,
        )
        sys.exit(2)
    lib = ship_library(prof)
    trial_s = lengths * sum(p.duration_s for p in lib)
    seq = interleave(first_design(prof, lib, trial_length_s=trial_s, mean_subtraction=ms).design.counts, lib)
    n_first = first_third(seq)
    left = rest_seconds(seq, n_first)
    print(
        f"\n{ship}: predictive error "
        f"on held-out noise-free runs of the truth, median over {runs} runs; re-designed after {n_first} of {len(seq)}"
    )
    print(f"{'trial':>5} {'fixed':>8} {'adaptive':>9} {'ratio':>6} {'run wins':>8}  re-designed rest (first run)")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(28, 6)))
    th0 = prof.params()
    ratios, wins, rw, rdiff = [], 0, 0, 0
    for t in range(trials):
        truth = draw_truth(th0, rng, corners)
        heldout = ad.sail(prof, lib, truth, (0.0, 0.0, 0.0), np.random.default_rng(0))
        ef, ea, rests = [], [], []
        for j in range(runs):
            seen: Counter = Counter()
            sailed = sail_crn(prof, seq[:n_first], truth, (seed, t, j), seen)
            rest_f = sail_crn(prof, seq[n_first:], truth, (seed, t, j), seen.copy())
            rd = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms)
            rest_a = sail_crn(prof, interleave(rd.counts, lib), truth, (seed, t, j), seen.copy())
            ef.append(predictive_error(prof, sailed + rest_f, heldout, ms))
            ea.append(predictive_error(prof, sailed + rest_a, heldout, ms))
            rests.append(rd.counts)
        ef, ea = np.array(ef), np.array(ea)
        mf, ma = np.median(ef), np.median(ea)
        ratio = ma / mf if np.isfinite(mf) and np.isfinite(ma) else float("nan")
        ratios.append(ratio)
        wins += bool(ma < mf)
        rw += int((ea < ef).sum())
        rdiff += int((ea != ef).sum())
        print(f"{t:5d} {mf:8.4f} {ma:9.4f} {ratio:6.3f} {int((ea < ef).sum()):>4}/{int((ea != ef).sum()):<3}  {dict(rests[0])}")
    print(
        f"{ship} predictive: adaptive lower in {wins} of {trials} trials ({wins / trials:.0%}); median ratio "
        f"{np.nanmedian(ratios):.3f}; single runs {rw} of the {rdiff} that differ ({rw / max(rdiff, 1):.0%})"
    )
    return {"ship": ship, "trials": trials, "wins": wins, "run_wins": rw, "run_differ": rdiff}


def resume_timing(repeats: int) -> None:
    """CPU time of matching the recordings and :func:`maps.resume.resume_plan` (re-identify,
    re-design, re-plan) for the default ship on the bundled map, resumed after the first third
    of a 30-minute design; the plan and its recordings are made first, untimed."""
    from maps.geo import load_map
    from maps.planner import plan_trial
    from maps.resume import Position, match_recordings, resume_plan, simulated_recordings

    prof = load_profile("full-scale")
    sea = load_map(None, draught_m=prof.draught_m)
    plan = plan_trial(sea, profile=prof, trial_length_s=1800.0)
    steps = [s for s in plan.steps if s.segment == "informative"]
    first = steps[: max(1, len(steps) // 3)]
    truth = prof.params() * (1 + 0.2 * np.random.default_rng(0).uniform(-1, 1, prof.params().shape))
    recs = simulated_recordings(plan, prof, first, truth, (0.02, 0.02, 0.0005), 0)
    k = np.nonzero(plan.step_of_sample == first[-1].index)[0][-1]
    pos = Position(float(plan.lonlat[k, 1]), float(plan.lonlat[k, 0]), float(np.degrees(plan.track[k, 2]) % 360))
    times = []
    for _ in range(repeats + 1):
        t0 = time.process_time()
        runs = match_recordings(plan, recs, prof)
        new, rd = resume_plan(plan, runs, pos, 1200.0, sea, prof)
        times.append(time.process_time() - t0)
    print(
        f"\nresume of full-scale on helsinki after {len(first)} of {len(steps)} manoeuvres (match, re-identify, re-design, "
        f"re-plan; target < 5 s): CPU {', '.join(f'{t:.2f}' for t in times)} s; first call {times[0]:.2f} s, "
        f"median of the next {repeats} {np.median(times[1:]):.2f} s; feasible {new.feasible}, rest {new.counts}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--ship", default="model-ship", help="one ship, or several separated by commas (pooled at the end)")
    ap.add_argument("--mean-subtraction", default="batchwise", help="of the designs and of the scored estimate")
    ap.add_argument("--lengths", type=float, default=2.0, help="trial length in library lengths (every primitive once)")
    ap.add_argument("--runs", type=int, default=10, help="noisy runs per truth (the error compared is their median)")
    ap.add_argument("--timing-repeats", type=int, default=3)
    ap.add_argument("--score", choices=("parameters", "predictive"), default="parameters")
    ap.add_argument("--corners", action="store_true", help="truths with every parameter exactly 30 %% off")
    ap.add_argument("--criterion-gap", action="store_true", help="also the model-based gap of the scored metric's criterion")
    a = ap.parse_args()
    if a.trials:
        ships = a.ship.split(",")
        if a.score == "predictive":
            rows = [predictive_vs_fixed(s, a.trials, a.seed, a.lengths, a.runs, a.mean_subtraction, a.corners) for s in ships]
        else:
            rows = [
                adaptive_vs_fixed(s, a.trials, a.seed, a.lengths, a.runs, a.mean_subtraction, a.criterion_gap, a.corners)
                for s in ships
            ]
        if len(rows) > 1:
            w, n = sum(r["wins"] for r in rows), sum(r["trials"] for r in rows)
            rw, rd = sum(r["run_wins"] for r in rows), sum(r["run_differ"] for r in rows)
            print(
                f"\npooled over {', '.join(r['ship'] for r in rows)}: adaptive lower in {w} of {n} trials ({w / n:.0%}); "
                f"single runs {rw} of {rd} ({rw / max(rd, 1):.0%})"
            )
    if a.timing_repeats:
        resume_timing(a.timing_repeats)


if __name__ == "__main__":
    main()
