"""Adaptive trial vs fixed plan on a truth that is NOT the estimator's model: the MMG KVLCC2
(Yasukawa & Yoshimura 2015; ``tests/physics/mmg_kvlcc2.py``, which shares no code with the
product) with its hull and rudder coefficients drawn within +-30 % of the paper's, planned and
re-designed with the ``kvlcc2`` profile (a discrete-time model of another structure fitted on
MARIN data).

Scoring. The ship has no parameters in the predictor's terms, and with a structure the model lacks
the IV estimate's limit depends on the experiment sailed, so a "pseudo-true" parameter vector
(the fit to one long rich recording) favours the designs that resemble that recording. The
primary score is therefore what the user reads from an identified model: its HELD-OUT PREDICTION
ERROR, the predictor simulated at the estimate through the inputs of runs the trial never sailed
(closed-loop 15/15 zig-zags and 25 deg turns, both sides, from ``tests/physics/mmg_sim.py``),
normalised RMS over u, v, r, mean over those runs. Printed beside it, secondary: the rms relative
error against the pseudo-true parameters (the IV fit, same mean subtraction, to the noise-free
runs of every library manoeuvre once, 7.2 h), and the model-based ceiling at them.

The profile's propeller order is mapped to the MMG's so that the paper's ship sails the profile's
cruise speed at the profile's cruise order (the MMG needs 1.756 rps for 7.97 m/s, the profile
1.523: a calibration of the telegraph, the same for every truth). The library's inputs are
replayed open loop (rudder angle and order held over each 1 s sample), each run from the MMG's
steady straight run at its first order; measurement noise as :mod:`benchmarks.bench_adaptive`'s
kvlcc2 recordings, common random numbers.

Arms, each the same first third (same recordings) and a rest of the fixed plan's remaining
seconds: FIXED (the plan's own rest), ADAPTIVE (re-designed from the first third's recordings,
re-identified, (7.58)), CONTROL (re-designed from the same recordings at the profile's values: what
counting the sailed information alone gains), ORACLE (re-designed at the pseudo-true parameters: the
best a re-design aiming at D can do, what a perfect re-identification would give), and NOISE ALONE
(the fixed rest again on a fresh noise stream: how far a ratio moves by chance when none of the
rest's noise is shared; the other arms share the noise of the manoeuvres they have in common with
the fixed rest, so this spread is an upper reference). Each arm's count of truths below the fixed
plan is printed with a fair coin's tail probability of that count over the truths that are not ties
(a one-sided sign test: a tie is the fixed plan's own rest, no comparison).

    PYTHONPATH=. nice -n 10 python benchmarks/adaptive_mmg.py [--trials 20] [--seed 0] [--runs 1]
"""

from __future__ import annotations

import argparse
import math
import zlib
from collections import Counter
from dataclasses import replace

import numpy as np

from benchmarks.bench_adaptive import SPREAD, first_third, interleave, noise_of, rest_seconds, simulation_error
from expdesign import adaptive as ad
from expdesign.estimators import estimate
from maps.trialdesign import first_design, ship_library
from primitives.ship import load_profile
from tests.physics.mmg_kvlcc2 import Environment, derivative, kvlcc2, self_propulsion_rps
from tests.physics.mmg_sim import Manoeuvre, simulate_runs, straight_speed

# the coefficients drawn: resistance, every hull derivative (Yasukawa & Yoshimura 2015, (10)-(12))
# and the rudder's lift slope f_alpha (27)
DRAWN = "R_0 X_vv X_vr X_rr X_vvvv Y_v Y_r Y_vvv Y_vvr Y_vrr Y_rrr N_v N_r N_vvv N_vvr N_vrr N_rrr f_alpha".split()
SUBSTEPS = 1  # RK4 steps per 1 s sample: the library replayed at 1 differs from 4 by 1e-6 of each signal's RMS
ARMS = ("fixed", "adaptive", "control", "oracle", "fixed, new noise")
HELD_OUT = [Manoeuvre("zigzag", 15, 15, s, 600) for s in (1, -1)] + [Manoeuvre("turn", 25, 0, s, 400) for s in (1, -1)]


def truth_ship(rng: np.random.Generator):
    """The paper's KVLCC2 at full scale, each coefficient of :data:`DRAWN` times 1 + U(-SPREAD, SPREAD)."""
    ship = kvlcc2()
    c = ship.c
    return replace(ship, c=replace(c, **{k: getattr(c, k) * (1 + SPREAD * rng.uniform(-1, 1)) for k in DRAWN}))


def order_scale(prof) -> float:
    """MMG rps per profile order: the nominal MMG sails the profile's cruise speed at its cruise order."""
    cruise_n = max(p.inputs[0, 1] for p in ship_library(prof))
    return self_propulsion_rps(kvlcc2(), prof.cruise_speed_mps) / cruise_n


def replay(ship, prims: list, k_n: float) -> dict[str, ad.SailedRun]:
    """Noise-free recordings of ``prims`` sailed by ``ship`` with the primitives' own inputs (rudder
    in the recorded convention, positive to port; order times ``k_n`` in rps), open loop, one batch."""
    b = len(prims)
    n_max = max(p.n_samples for p in prims)
    inp = np.stack([np.vstack([p.inputs, np.repeat(p.inputs[-1:], n_max - p.n_samples, 0)]) for p in prims])
    s = np.zeros((b, 6))
    s[:, 3] = [straight_speed(ship, p.inputs[0, 1] * k_n) for p in prims]
    minv = np.linalg.inv(ship.mass_matrix())
    env = Environment()
    h = 1.0 / SUBSTEPS
    out = np.empty((b, n_max + 1, 6))
    out[:, 0] = s
    for k in range(n_max):
        d, n = -inp[:, k, 0], inp[:, k, 1] * k_n  # MMG rudder: positive to starboard
        for _ in range(SUBSTEPS):
            k1 = derivative(ship, minv, s, d, n, env)
            k2 = derivative(ship, minv, s + 0.5 * h * k1, d, n, env)
            k3 = derivative(ship, minv, s + 0.5 * h * k2, d, n, env)
            k4 = derivative(ship, minv, s + h * k3, d, n, env)
            s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[:, k + 1] = s
    runs = {}
    for i, p in enumerate(prims):
        a = out[i, : p.n_samples + 1]
        runs[p.name] = ad.SailedRun(-1, p.name, p.inputs, a[:, 3:6].copy(), a[:, 2].copy(), f"MMG {p.name}")
    return runs


def held_out(ship, prof, k_n: float, mans: list[Manoeuvre] = HELD_OUT) -> list[ad.SailedRun]:
    """Noise-free runs of manoeuvres the library does not hold (:data:`HELD_OUT`, closed loop at
    the cruise order), as the predictor reads them: recorded rudder and order, body velocities."""
    cruise_n = max(p.inputs[0, 1] for p in ship_library(prof))
    runs = simulate_runs(ship, mans, cruise_n * k_n)
    out = []
    for m, r in zip(mans, runs):
        inputs = np.column_stack([r.delta[:-1], r.n[:-1] / k_n])
        out.append(ad.SailedRun(-1, m.label, inputs, np.column_stack([r.u, r.v, r.r]), r.psi, f"MMG {m.label}"))
    return out


def noisy(clean: dict, prims: list, noise, seed: tuple, seen: Counter) -> list[ad.SailedRun]:
    """The clean recordings of ``prims`` in order with white noise on u, v, r; common random
    numbers: the k-th sailing of manoeuvre q meets stream (seed, q, k) whichever plan sails it."""
    runs = []
    for p in prims:
        k = seen[p.name]
        seen[p.name] += 1
        g = np.random.default_rng([*seed, zlib.crc32(p.name.encode()), k])
        c = clean[p.name]
        y = c.y + g.standard_normal(c.y.shape) * np.asarray(noise, float)
        runs.append(ad.SailedRun(len(runs), p.name, c.inputs, y, c.psi, c.source))
    return runs


def scores(prof, runs: list, heldout: list, pseudo: np.ndarray, ms: str) -> tuple[float, float]:
    """(held-out prediction error, rms relative error against ``pseudo``) of the IV estimate from
    ``runs``; inf for a failed fit or a diverging prediction (said, never a number)."""
    th = estimate(prof, [r.segment() for r in runs], method="iv", mean_subtraction=ms).theta[0]
    if not np.all(np.isfinite(th)):
        return float("inf"), float("inf")
    nz = pseudo != 0
    return simulation_error(prof, th, heldout), float(np.sqrt(np.mean(((th[nz] - pseudo[nz]) / pseudo[nz]) ** 2)))


def one_truth(prof, lib, seq, n_first, ship, k_n, seed, runs, ms) -> dict:
    clean = replay(ship, lib, k_n)
    heldout = held_out(ship, prof, k_n)
    pseudo = estimate(prof, [clean[p.name].segment() for p in lib], method="iv", mean_subtraction=ms).theta[0]
    left = rest_seconds(seq, n_first)
    first = [replace(clean[p.name], step=i) for i, p in enumerate(seq[:n_first])]
    reid = ad.Reidentification(pseudo, prof.predictor_param_names, {})
    oracle = ad.redesign(prof, lib, first, left, mean_subtraction=ms, reid=reid)
    fallback = [n for n in oracle.notes if n.startswith("the rest's information is at the profile's values")]
    if fallback:  # its rest designed at the profile's values would be the control, not the oracle
        raise SystemExit(f"truth {seed}: the oracle is not re-designed at the pseudo-true parameters: {fallback[0]}")
    fixed_rest = Counter(p.name for p in seq[n_first:])
    ceiling = ad.rest_efficiency(prof, lib, first, pseudo, fixed_rest, left, oracle.logdet_continuous, ms)
    nominal = ad.Reidentification(ad.profile_predictor(prof, lib), prof.predictor_param_names, {})
    noise = noise_of(prof)
    res = []
    for j in range(runs):
        seen: Counter = Counter()
        sailed = noisy(clean, seq[:n_first], noise, (*seed, j), seen)
        rd = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms)
        ctrl = ad.redesign(prof, lib, sailed, left, mean_subtraction=ms, reid=nominal)
        rests = [seq[n_first:], interleave(rd.counts, lib), interleave(ctrl.counts, lib), interleave(oracle.counts, lib)]
        res.append([scores(prof, sailed + noisy(clean, r, noise, (*seed, j), seen.copy()), heldout, pseudo, ms) for r in rests])
        # noise alone: the same fixed rest sailed again on a fresh noise stream (the first third shared)
        res[-1].append(scores(prof, sailed + noisy(clean, seq[n_first:], noise, (*seed, j, 1), seen.copy()), heldout, pseudo, ms))
        res[-1].append(rd.counts)
    # runs x (fixed, adaptive, control, oracle, fixed re-noised) x (pred, par)
    arr = np.array([[x for pair in r[: len(ARMS)] for x in pair] for r in res])
    med = np.median(arr, axis=0)
    return {"pred": med[0::2], "par": med[1::2], "ceiling": ceiling, "rest": res[0][-1], "oracle": oracle.counts}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--runs", type=int, default=1, help="noisy runs per truth (their median is compared)")
    ap.add_argument("--lengths", type=float, default=2.0, help="trial length in library lengths")
    ap.add_argument("--mean-subtraction", default="batchwise")
    a = ap.parse_args()
    prof = load_profile("kvlcc2")
    lib = ship_library(prof)
    ms = a.mean_subtraction
    trial_s = a.lengths * sum(p.duration_s for p in lib)
    seq = interleave(first_design(prof, lib, trial_length_s=trial_s, mean_subtraction=ms).design.counts, lib)
    n_first = first_third(seq)
    k_n = order_scale(prof)
    print(
        f"kvlcc2 profile, TRUTH = MMG KVLCC2 (Yasukawa & Yoshimura 2015) with {len(DRAWN)} coefficients within "
        f"+-{SPREAD:.0%} (seed {a.seed}); trial {trial_s:.0f} s, re-designed after {n_first} of {len(seq)} manoeuvres; "
        f"{a.runs} noisy run(s) per truth, noise {noise_of(prof)}; mean subtraction {ms}; order x {k_n:.4f} rps"
    )
    print("pred: held-out prediction error (normalised RMS, mean over 15/15 zig-zags and 25 deg turns, both sides)")
    print("par: rms relative error against the pseudo-true parameters (the IV fit to every library manoeuvre, noise-free)")
    print("ratios over the fixed plan: ad = adaptive (re-identified from the first third), ctl = CONTROL (re-designed from")
    print("the same recordings at the profile's values), orc = ORACLE (re-designed at the pseudo-true parameters: the best a")
    print("re-design can aim for), nse = NOISE ALONE (the same fixed rest on a fresh noise stream, none of the rest's noise")
    print("shared: an upper reference for chance); ceiling (model-based, at the pseudo-true parameters): the fixed rest's")
    print("D-efficiency\n")
    print(
        f"{'truth':>5} {'pred fix':>8} {'ad':>6} {'ctl':>6} {'orc':>6} {'nse':>6} {'par fix':>8} {'ad':>6} {'ctl':>6} "
        f"{'orc':>6} {'nse':>6} {'ceiling':>7}  re-designed rest (first run) | oracle rest"
    )
    rng = np.random.default_rng(np.random.SeedSequence(a.seed, spawn_key=(28, 7)))
    rows = []
    for t in range(a.trials):
        r = one_truth(prof, lib, seq, n_first, truth_ship(rng), k_n, (a.seed, t), a.runs, ms)
        ratios = [r[k][1:] / r[k][0] for k in ("pred", "par")]
        rows.append((*ratios[0], *ratios[1], r["ceiling"]))
        print(
            f"{t:5d} {r['pred'][0]:8.4f} {' '.join(f'{x:6.3f}' for x in ratios[0])} {r['par'][0]:8.4f} "
            f"{' '.join(f'{x:6.3f}' for x in ratios[1])} {r['ceiling']:7.4f}  {dict(r['rest'])} | {dict(r['oracle'])}"
        )
    summary(np.array(rows))


def coin_tail(k: int, n: int) -> float:
    """P(at least k of n) for a fair coin: how often chance alone wins k of n comparisons (the
    one-sided sign test; ``n`` counts the comparisons that are not ties)."""
    return sum(math.comb(n, i) for i in range(k, n + 1)) / 2**n


def summary(x: np.ndarray) -> None:
    """The counts and median ratios of each arm over the fixed plan, for both scores, with the
    chance level (noise alone, and a fair coin's tail probability) beside them."""
    n = len(x)
    need = math.ceil(0.75 * n)
    arms = ARMS[1:]
    for s, score in enumerate(("held-out prediction", "pseudo-true parameters")):
        print(f"\nMMG truth, {score} (lower than the fixed plan, of {n}; Done-when: >= {need}):")
        for a, arm in enumerate(arms):
            c = x[:, s * len(arms) + a]
            k, ties = int((c < 1).sum()), int((c == 1).sum())
            with np.errstate(invalid="ignore"):
                lo, hi = np.nanpercentile(c, [10, 90])
            # a sign test: a tie (the same rest as the fixed plan's, so the same score) is no comparison
            print(
                f"  {arm:<17} lower in {k:2d} (equal {ties}), median ratio {np.nanmedian(c):.3f}, "
                f"10-90 % {lo:.3f}-{hi:.3f}; P(>= {k} of {n - ties} untied | coin) {coin_tail(k, n - ties):.3f}"
            )
    ad = x[:, 0:4]
    print(
        f"adaptive lower than the control in {int((ad[:, 0] < ad[:, 1]).sum())} of {n}, than the oracle in "
        f"{int((ad[:, 0] < ad[:, 2]).sum())} of {n} (held-out prediction)"
    )
    c = x[:, -1]
    print(f"CEILING (model-based): min {c.min():.4f} median {np.median(c):.4f}, under 0.99 in {int((c < 0.99).sum())} of {n}")


if __name__ == "__main__":
    main()
