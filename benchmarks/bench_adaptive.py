"""Adaptive trial vs fixed plan (issue 28): a trial re-designed after its first third from the
recordings of that third (Ljungberg 2022, (7.58); :mod:`expdesign.adaptive`) against the fixed
plan of the same length, on simulated ships whose parameters differ from the profile's.

THE TRUTH IS THE ESTIMATOR'S OWN MODEL STRUCTURE AT DRAWN PARAMETERS (each parameter within
+-30 % of the profile's, seeded): no ship in the project has a truth of another structure whose
parameters the predictor's can be scored against (tests/physics/mmg_kvlcc2.py is an MMG model,
whose coefficients are not the predictor's), so this is evidence for the re-design, not for a
real ship. Recordings: white measurement noise on u, v, r (the figures printed). Parameter error
of a trial: sqrt(mean(((theta_hat - theta_true) / theta_true)^2)) over the non-zero parameters,
the IV estimate (:func:`expdesign.estimators.estimate`) from every run sailed.

Second part: CPU time of resume + re-identify + re-design + re-plan for the default ship on the
bundled map (target < 5 s), through :func:`maps.resume.resume_plan`.

    nice -n 10 python benchmarks/bench_adaptive.py [--trials 20] [--seed 0] [--ship model-ship]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from expdesign import adaptive as ad
from expdesign.estimators import estimate
from maps.trialdesign import first_design, ship_library
from primitives.ship import load_profile

SPREAD = 0.30
NOISE = {"model-ship": (0.005, 0.005, 0.002), "kvlcc2": (0.05, 0.05, 0.0005)}


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


def param_error(prof, runs, truth: np.ndarray) -> float:
    est = estimate(prof, [r.segment() for r in runs], method="iv", mean_subtraction="batchwise")
    th = est.theta[0]
    nz = truth != 0
    if not np.all(np.isfinite(th)):
        return float("inf")  # a failed fit: said, never a number
    return float(np.sqrt(np.mean(((th[nz] - truth[nz]) / truth[nz]) ** 2)))


def one_trial(prof, lib, fixed_counts, trial_s, truth, seed):
    seq = interleave(fixed_counts, lib)
    n_first = max(1, round(len(seq) / 3))
    noise = NOISE.get(prof.name, (0.005, 0.005, 0.002))
    sailed = ad.sail(prof, seq[:n_first], truth, noise, np.random.default_rng([seed, 1]))
    rest_fixed = ad.sail(prof, seq[n_first:], truth, noise, np.random.default_rng([seed, 2]), n_first)
    e_fixed = param_error(prof, sailed + rest_fixed, truth)
    left = trial_s - sum(r.n_samples for r in sailed) * prof.sample_time
    rd = ad.redesign(prof, lib, sailed, left)
    rest = interleave(rd.counts, lib)
    rest_ad = ad.sail(prof, rest, truth, noise, np.random.default_rng([seed, 2]), n_first)
    e_ad = param_error(prof, sailed + rest_ad, truth)
    return e_fixed, e_ad, rd


def adaptive_vs_fixed(ship: str, trials: int, seed: int, lengths: float) -> None:
    prof = load_profile(ship)
    lib = ship_library(prof)
    trial_s = lengths * sum(p.duration_s for p in lib)
    fixed = first_design(prof, lib, trial_length_s=trial_s).design.counts
    print(f"{ship}: trial {trial_s:.0f} s of manoeuvres, fixed plan {fixed}; truths within +-{SPREAD:.0%} (seed {seed});")
    print(f"noise std u, v, r {NOISE.get(ship)}; truth = the estimator's own model at drawn parameters\n")
    print(f"{'trial':>5} {'fixed':>8} {'adaptive':>9} {'ratio':>7}  re-designed rest")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(28, 5)))
    th0 = prof.params()
    ratios, wins = [], 0
    for t in range(trials):
        truth = th0 * (1 + SPREAD * rng.uniform(-1, 1, th0.shape))
        ef, ea, rd = one_trial(prof, lib, fixed, trial_s, truth, seed * 1000 + t)
        ok = np.isfinite(ef) and np.isfinite(ea)
        ratio = ea / ef if ok else float("nan")
        wins += bool(ok and ea < ef)
        ratios.append(ratio)
        print(f"{t:5d} {ef:8.4f} {ea:9.4f} {ratio:7.3f}  {rd.counts}" + ("" if ok else "  (a fit failed)"))
    r = np.array(ratios)
    print(
        f"\nadaptive lower in {wins} of {trials} trials ({wins / trials:.0%}; Done-when >= 75 %); "
        f"median ratio adaptive/fixed {np.nanmedian(r):.3f}; failed fits {int(np.isnan(r).sum())}"
    )


def resume_timing(repeats: int) -> None:
    """CPU time of maps.resume.resume_plan on a plan of the default ship on the bundled map."""
    from maps.resume import demo_resume

    times = []
    for i in range(repeats + 1):
        t0 = time.process_time()
        plan = demo_resume(warm=i > 0)
        times.append(time.process_time() - t0)
    print(
        f"\nresume (re-identify, re-design, re-plan) for full-scale on helsinki: CPU {times[1:]} s; "
        f"median {np.median(times[1:]):.2f} s (first call {times[0]:.2f} s incl. imports/caches); "
        f"feasible {plan.feasible}, counts {plan.counts}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--ship", default="model-ship")
    ap.add_argument("--lengths", type=float, default=2.0, help="trial length in library lengths (every primitive once)")
    ap.add_argument("--timing-repeats", type=int, default=3)
    a = ap.parse_args()
    adaptive_vs_fixed(a.ship, a.trials, a.seed, a.lengths)
    if a.timing_repeats:
        resume_timing(a.timing_repeats)


if __name__ == "__main__":
    main()
