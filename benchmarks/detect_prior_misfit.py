"""Stop 54 (issue 25): how much of the yaw prior's misfit would a term it lacks explain?

Stop 53 found that no no-change model drawn from a run's own residual calibrates ``detect`` without
losing misses: every run shares the prior's misfit. This diagnostic asks whether a small set of yaw-row
terms the prior (:class:`identify.detect.yawmodel.YawPrior`, (2.17) with ``N_p p``) lacks would take a
material share of that misfit away, on the truth family's stored screenings (read-only:
``benchmarks/bench_detect_truth.py --cache``).

For each recording (a prior's own 500 s nominal run and a few of its ship's unchanged runs) the
prior's simulated yaw-rate residual ``e = r - r_hat`` (as :func:`identify.detect.api.screen` makes it)
is regressed, in 1 s block means, on

* ``J``: the sensitivities of ``r_hat`` to the prior's own parameters (a linearised refit), and
* ``G_c``: the sensitivity of ``r_hat`` to a candidate term ``c`` added to the yaw row's moment
  (``I_r r' = ... + tau_r + theta_c g_c``, ``g_c`` built from the recorded channels only, as the prior
  filters them: :data:`TERMS`), found by simulating the prior with ``tau_r + eps g_c``; one
  output-side column, ``r_hat'``, stands for a sensor lag of the gyro against the inputs.

Coefficients are fitted on the NOMINAL recording and applied unchanged to the runs (out of sample);
the share of a candidate set is ``1 - var(e - X c) / var(e)`` less the share of ``J`` alone, overall
and inside the signatures' band (between the frequencies below which 5 % and 95 % of the block-mean
signatures' power lies, :func:`benchmarks.detect_ownmisfit.signature_edge`). Beside them: the share of
the residual that noise alone gives (16 no-change records of the prior without parameter error or
model-error term, :func:`identify.detect.nullsim.null_records`) and the share the prior's own
parameters refitted on the run itself explain (in-sample: the prior's parameter error on that run).

With ``--clean DIR`` every recording is also re-simulated by the truth without sensor noise
(``podded_truth`` ``noise_scale=0``: the sensors' low-pass kept; for the diagnosis only, never a
regressor), and a second table splits the runs' residual into the sensors' noise (the run less the same
run without noise), the share of it the prior's records read as noise, the prior's parameter offset the
runs share (its parameters refitted on the noise-free nominal, applied to the noise-free run) and the best
single candidate on the noise-free runs; a third gives yaw inertia's whole-record reading on the runs with and
without noise (:func:`readings`). Stop 54's output: ``benchmarks/detect_prior_misfit_s54.txt``;
the reading: docs/detect-accuracy.md, stop 54 (no term explains a material share; the in-band residual is
84-93 % sensor noise, of which the prior's records carry 0-3 % as noise, and 6.2-9.9 % the prior's shared parameter
offset, which along yaw inertia is the whole of a prior's mean reading).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/detect_prior_misfit.py \\
        --cache /tmp/dcache:8667c7204102:102:2 --cache /tmp/dcache-108:8667c7204102:108:2 --runs 5 \\
        --clean /tmp/s54/clean --save /tmp/s54/cols.pkl   # then: --load /tmp/s54/cols.pkl re-tabulates in seconds
"""

from __future__ import annotations

import argparse
import pickle
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from benchmarks.detect_ownmisfit import signature_edge
from identify.detect.api import load_runs
from identify.detect.checks import MOMENT
from identify.detect.inputs import Deriver, signals
from identify.detect.nullsim import null_records
from identify.detect.priorfit import _jacobian
from identify.detect.yawmodel import (
    CANDIDATES,
    NOMINAL,
    YawPrior,
    block_mean,
    predict_with_signatures,
    shift_moment,
    simulate_r,
    whiten,
)
from primitives.iir import lfilter

VARIANTS = ("nominal-mmg", "strong-roll", "pod-interaction", "steering-lag-acting", "coloured-noise")
#: the truth family's recordings' fingerprint (tests/physics at the stored screenings' time)
TRUTH_FP = "0b77fdf7a61a"
STORED_RUNS = 10  # the stored studies' --runs: 10 unchanged runs, then 10 changed (bench_detect_truth.ship_study)


def _d(x: np.ndarray, dt: float) -> np.ndarray:
    return np.gradient(x, dt, axis=0)


def _lag(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Causal first-order low-pass (time constant ``tau``) less the signal: what a lag adds."""
    a = np.exp(-dt / tau)
    return lfilter([1.0 - a], [1.0, -a], x, zi=np.array([a * x[0]])) - x  # y[k] = a y[k-1] + (1-a) x[k], y[-1] = x[0]


#: candidate moment terms g(w, dt) from the prior's filtered inputs ``w`` (u, v, v_dot, phi, p, tau_r as
#: the prior sees them, plus its simulated yaw rate r_hat as r, mean pod angle a and propeller speed n): none of
#: them is a term of (2.17) + N_p p; the ``d/dt`` ones are a first-order time shift of a term the row has
#: (the sensors' different low-passes), ``lag`` a moment that follows the measured one through a lag
TERMS: dict[str, Callable[[dict[str, np.ndarray], float], np.ndarray]] = {
    "v|v|": lambda w, dt: w["v"] * np.abs(w["v"]),
    "v^3": lambda w, dt: w["v"] ** 3,
    "v r^2": lambda w, dt: w["v"] * w["r"] ** 2,
    "v^2 r": lambda w, dt: w["v"] ** 2 * w["r"],
    "r^3": lambda w, dt: w["r"] ** 3,
    "u^2 r": lambda w, dt: w["u"] ** 2 * w["r"],
    "u_dot": lambda w, dt: _d(w["u"], dt),
    "u_dot r": lambda w, dt: _d(w["u"], dt) * w["r"],
    "tau u": lambda w, dt: w["tau_r"] * w["u"],
    "tau |tau|": lambda w, dt: w["tau_r"] * np.abs(w["tau_r"]),
    "tau lag 1 s": lambda w, dt: _lag(w["tau_r"], dt, 1.0),
    "tau lag 5 s": lambda w, dt: _lag(w["tau_r"], dt, 5.0),
    "d tau/dt": lambda w, dt: _d(w["tau_r"], dt),
    "a u^2": lambda w, dt: w["a"] * w["u"] ** 2,
    "a n^2": lambda w, dt: w["a"] * w["n"] ** 2,
    "a|a| n^2": lambda w, dt: w["a"] * np.abs(w["a"]) * w["n"] ** 2,
    "r n": lambda w, dt: w["r"] * w["n"],
    "phi": lambda w, dt: w["phi"],
    "phi^3": lambda w, dt: w["phi"] ** 3,
    "phi r": lambda w, dt: w["phi"] * w["r"],
    "p|p|": lambda w, dt: w["p"] * np.abs(w["p"]),
    "p u": lambda w, dt: w["p"] * w["u"],
    "p_dot": lambda w, dt: _d(w["p"], dt),
    "d v_dot/dt": lambda w, dt: _d(w["v_dot"], dt),
    "d(|u|v)/dt": lambda w, dt: _d(np.abs(w["u"]) * w["v"], dt),
    "d(phi u|u|)/dt": lambda w, dt: _d(w["phi"] * w["u"] * np.abs(w["u"]), dt),
}
#: the output-side column: the gyro's lag against the inputs (``r_hat'``, not through the dynamics)
OUTPUT_TERM = "r_hat'"


@dataclass
class Columns:
    """One recording's 1 s block means: the residual, the prior's own sensitivities J, the candidates' G,
    noise-only records, and the signatures' band (cycles a block)."""

    e: np.ndarray  # (nb,)
    J: np.ndarray  # (nb, P)
    G: np.ndarray  # (nb, C), ordered as names
    names: tuple[str, ...]
    noise: np.ndarray  # (nb, R)
    band: tuple[float, float]
    S: np.ndarray | None = None  # (nb, 3) the change signatures (CANDIDATES)
    ar: np.ndarray | None = None  # the prior's whitening filter


def sensitivity_columns(
    prior: YawPrior, w: dict[str, np.ndarray], extra: dict[str, np.ndarray], r0: float
) -> tuple[np.ndarray, list[str]]:
    """(n, C) change of ``r_hat`` per unit coefficient of each candidate moment term (TERMS, each scaled to the
    measured moment's sd), in one vectorised simulation; then the output-side column ``r_hat'``."""
    base = simulate_r(prior.kind, prior.values, w, prior.dt, r0=r0)
    ww = w | extra
    g = np.column_stack([TERMS[k](ww, prior.dt) for k in TERMS])
    g = (g - g.mean(axis=0)) / np.maximum(g.std(axis=0), 1e-300) * np.std(w["tau_r"])
    eps = 1e-3
    cols = {k: np.repeat(x[:, None], g.shape[1], axis=1) for k, x in w.items()}
    cols["tau_r"] = cols["tau_r"] + eps * g
    r = simulate_r(prior.kind, prior.values, cols, prior.dt, r0=r0)
    G = (r - base[:, None]) / eps
    return np.column_stack([G, _d(base, prior.dt)]), [*TERMS, OUTPUT_TERM]


def recording_columns(prior: YawPrior, path: Path, noise_runs: int = 16, seed: int = 0) -> Columns:
    """The :class:`Columns` of one recording against ``prior`` (its moment read with the prior's advance)."""
    rec = load_runs([path])[0]
    sig, r = signals(rec, prior.kind)
    sig = shift_moment(sig, prior.moment_shift_s, prior.dt) if MOMENT in rec.channels else sig
    r0 = float(np.mean(r[:5]))
    w = prior.inputs(sig)
    r_hat, S = predict_with_signatures(prior, w, r0)
    ch = rec.channels
    raw = {"a": 0.5 * (ch["alpha1"] + ch["alpha2"]), "n": 0.5 * (ch["n1"] + ch["n2"])}
    # the yaw rate in a candidate is the prior's own r_hat, as a state term of the output-error row is: the
    # measured r carries the gyro's noise, which the residual carries too (coloured-noise: r n, u^2 r, r^3 built
    # from the measured r took 31-33 % of the runs' in-band residual, 0-1 % of the same runs' without noise)
    extra = {k: v for k, v in prior.inputs(sig | raw).items() if k in raw} | {"r": r_hat}
    G, names = sensitivity_columns(prior, w, extra, r0)
    x = np.array([prior.values[k] / NOMINAL[k] for k in prior.names])
    J = _jacobian(prior.kind, x, w, prior.dt, r0=r0)
    exact = replace(prior, boot=np.zeros((0, len(prior.names))), cov=np.zeros_like(prior.cov), model_error=0.0)
    with np.errstate(all="ignore"):
        noise = null_records(exact, sig, noise_runs, seed, Deriver.of(rec, prior.kind), r0)
    Sb = block_mean(S, prior.block)
    band = (signature_edge(Sb, 0.05), signature_edge(Sb, 0.95))
    bm = lambda a: block_mean(a, prior.block)  # noqa: E731
    return Columns(bm(r - r_hat), bm(J), bm(G), tuple(names), bm(noise), band, Sb, prior.ar)


def readings(c: Columns) -> np.ndarray:
    """The whole-record GLR estimate of each candidate change (relative, CANDIDATES) on the recording: the
    whitened residual's least-squares fit along each whitened signature, as the verdict estimates a change."""
    ew, Sw = whiten(c.e, c.ar), whiten(c.S, c.ar)
    return Sw.T @ ew / np.sum(Sw**2, axis=0)


def reading_rows(noisy: list[tuple[Columns, list[Columns]]], clean: list[tuple[Columns, list[Columns]]]) -> dict:
    """Yaw inertia's reading (% of I_r) on the unchanged runs with and without noise: the runs' mean and sd
    without noise (what the prior's offset and structure make, shared), with noise (what detect reads), and the
    sd within a prior's runs (pooled over the priors) with noise and of the noise's own part (noisy less noise-free)."""
    k = CANDIDATES.index("yaw_inertia")
    rn = np.array([[readings(c)[k] for c in runs] for _, runs in noisy])
    rc = np.array([[readings(c)[k] for c in runs] for _, runs in clean])
    return {
        "clean_mean": 100 * rc.mean(),
        "clean_abs": 100 * np.abs(rc.mean(axis=1)).mean(),
        "noisy_mean": 100 * rn.mean(),
        "noisy_sd": 100 * rn.std(),
        "noise_sd": 100 * np.sqrt(np.mean(np.var(rn - rc, axis=1, ddof=1))),
        "within_sd": 100 * np.sqrt(np.mean(np.var(rn, axis=1, ddof=1))),
        "per_prior": [f"{100 * a:+.2f}/{100 * b:+.2f}" for a, b in zip(rc.mean(axis=1), rn.mean(axis=1))],
    }


def band_pass(x: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    """``x`` (nb, ...) centred, its FFT bins outside ``band`` (cycles a sample, inclusive) set to zero."""
    x = np.asarray(x, float) - np.mean(x, axis=0)
    f = np.fft.rfftfreq(len(x))
    X = np.fft.rfft(x, axis=0)
    X[(f < band[0]) | (f > band[1])] = 0.0
    return np.fft.irfft(X, n=len(x), axis=0)


def explained(e: np.ndarray, X: np.ndarray, coef: np.ndarray) -> float:
    """``1 - var(e - X coef) / var(e)`` (centred)."""
    e = e - e.mean()
    res = e - (X - X.mean(axis=0)) @ coef
    return float(1.0 - np.var(res) / np.var(e))


def fit_coef(e: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Least squares of centred ``e`` on centred ``X`` (columns scaled for conditioning)."""
    Xc = X - X.mean(axis=0)
    s = np.maximum(np.linalg.norm(Xc, axis=0), 1e-300)
    c, *_ = np.linalg.lstsq(Xc / s, e - e.mean(), rcond=None)
    return c / s


def shares(fit_on: Columns, test: Columns, chosen: list[int], band: bool) -> float:
    """Share of ``test``'s residual (in the signatures' band of ``test`` when ``band``) that ``J`` and the
    candidates ``chosen`` explain with coefficients fitted on ``fit_on`` (the same band), beyond ``J`` alone."""

    def prep(c: Columns, cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
        X = np.column_stack([c.J, c.G[:, cols]]) if cols else c.J
        return (band_pass(c.e, c.band), band_pass(X, c.band)) if band else (c.e, X)

    out = []
    for cols in (chosen, []):
        e_f, X_f = prep(fit_on, cols)
        e_t, X_t = prep(test, cols)
        out.append(explained(e_t, X_t, fit_coef(e_f, X_f)))
    return out[0] - out[1]


def noise_share(c: Columns, band: bool) -> float:
    """Variance of the noise-only records over the residual's (both in the band when ``band``)."""
    e = band_pass(c.e, c.band) if band else c.e - c.e.mean()
    n = band_pass(c.noise, c.band) if band else c.noise - c.noise.mean(axis=0)
    return float(np.mean(np.var(n, axis=0)) / np.var(e))


def refit_share(c: Columns, band: bool) -> float:
    """Share of the recording's residual that the prior's own parameters refitted on it explain (in-sample)."""
    e, X = (band_pass(c.e, c.band), band_pass(c.J, c.band)) if band else (c.e, c.J)
    return explained(e, X, fit_coef(e, X))


def offset_share(fit_on: Columns, test: Columns, band: bool) -> float:
    """Share of ``test``'s residual that the prior's own parameters, refitted on ``fit_on``, explain on
    ``test`` (out of sample when they differ): the parameter offset the two recordings share."""
    e_f, X_f = (band_pass(fit_on.e, fit_on.band), band_pass(fit_on.J, fit_on.band)) if band else (fit_on.e, fit_on.J)
    e_t, X_t = (band_pass(test.e, test.band), band_pass(test.J, test.band)) if band else (test.e, test.J)
    return explained(e_t, X_t, fit_coef(e_f, X_f))


def decomposition(noisy: list[tuple[Columns, list[Columns]]], clean: list[tuple[Columns, list[Columns]]], band: bool) -> dict:
    """What the unchanged runs' residual is made of (means over the runs): the sensors' noise (the residual less
    the same run's without noise), the prior's reading of it (its no-change records' noise share), the prior's
    parameter offset the runs share (its parameters refitted on the noise-free nominal, applied to the noise-free
    run), the run's own refit (in-sample), and the best single candidate term (fitted on the noise-free nominal,
    out of sample; the best on each run, so an upper bound), the last three as shares of the whole (noisy) residual."""
    bp = (lambda c, x: band_pass(x, c.band)) if band else (lambda c, x: x - np.mean(x, axis=0))  # noqa: E731
    rows = []
    for (_, runs_n), (nom_c, runs_c) in zip(noisy, clean):
        for rn, rc in zip(runs_n, runs_c):
            v, vc = np.var(bp(rn, rn.e)), np.var(bp(rn, rc.e))
            best = max(shares(nom_c, rc, [j], band) for j in range(rc.G.shape[1]))  # chosen on the run: an upper bound
            rows.append(
                (
                    np.sqrt(v),
                    np.sqrt(vc),
                    np.var(bp(rn, rn.e) - bp(rn, rc.e)) / v,
                    noise_share(rn, band),
                    offset_share(nom_c, rc, band) * vc / v,
                    refit_share(rc, band) * vc / v,
                    best * vc / v,
                )
            )
    keys = ("sd", "sd_clean", "noise", "noise_read", "offset", "refit", "terms")
    return dict(zip(keys, np.mean(rows, axis=0)))


def greedy(pairs: list[tuple[Columns, list[Columns]]], size: int, band: bool) -> list[int]:
    """Forward selection of ``size`` candidates by their mean in-sample share on the nominal recordings."""
    chosen: list[int] = []
    n = pairs[0][0].G.shape[1]
    for _ in range(size):
        gain = [
            np.mean([shares(nom, nom, chosen + [j], band) for nom, _ in pairs]) if j not in chosen else -np.inf for j in range(n)
        ]
        chosen.append(int(np.argmax(gain)))
    return chosen


def load_prior(folder: Path, variant: str, ship: int, key: str) -> YawPrior:
    from benchmarks.bench_detect_truth import prior_name, stored_recording

    return pickle.loads((folder / prior_name(stored_recording(variant, ship, TRUTH_FP), key)).read_bytes())


def clean_recording(variant: str, ship: int, seed: int, folder: Path) -> Path:
    """The truth's recording of ``seed`` without sensor noise (the sensors' low-pass kept; coloured-noise's
    gyro drift kept too: ``podded_truth.measure`` does not scale it), written to ``folder``: for the diagnosis
    only (what of the residual is noise), never a regressor."""
    from benchmarks.bench_detect_truth import variant_recordings
    from tests.physics.podded_truth import write_csv

    path = folder / f"clean-{variant}-{ship}-{seed}.csv"
    if path.exists():  # written by an earlier call (the truth's code is fingerprinted in the stores' names, not here)
        return path
    return write_csv(variant_recordings(variant, ship, [seed], noise_scale=0.0)[0], path)


def cache_spec(spec: str) -> tuple[Path, str, int, int] | None:
    """``DIR:KEY:FIRSTSHIP:NSHIPS`` as (folder, screening key, first ship, ships); None when it is not one."""
    parts = spec.rsplit(":", 3)
    if len(parts) != 4 or not parts[0] or not parts[1] or not parts[2].isdigit() or not parts[3].isdigit():
        return None
    return Path(parts[0]), parts[1], int(parts[2]), int(parts[3])


def cache_problem(specs: list[str], variants: tuple[str, ...], runs: int) -> str | None:
    """What a ``--cache`` spec lacks for :func:`study` (the folder, or the first stored prior or recording it
    would read, named with :mod:`benchmarks.bench_detect_truth`'s file names), as one line; None when all is there."""
    from benchmarks.bench_detect_truth import prior_name, stored_recording

    if not specs:
        return "--cache: give at least one DIR:KEY:FIRSTSHIP:NSHIPS (or --load a --save'd file)"
    for spec in specs:
        parsed = cache_spec(spec)
        if parsed is None or parsed[3] < 1:
            return f"--cache {spec}: expected DIR:KEY:FIRSTSHIP:NSHIPS, NSHIPS >= 1 (e.g. /tmp/dcache:8667c7204102:102:2)"
        folder, key, first, n = parsed
        if not folder.is_dir():
            return f"--cache {spec}: {folder}: no such folder; give a folder benchmarks/bench_detect_truth.py --cache filled"
        for v in variants:
            for ship in range(first, first + n):
                nominal = stored_recording(v, ship, TRUTH_FP)
                names = [prior_name(nominal, key), nominal]
                names += [stored_recording(v, ship, TRUTH_FP, STORED_RUNS, i) for i in range(runs)]
                missing = next((folder / f for f in names if not (folder / f).is_file()), None)
                if missing is not None:
                    return (
                        f"--cache {spec}: {missing} is missing (screening key {key}, truth fingerprint {TRUTH_FP}); "
                        f"give the key and ships bench_detect_truth.py --cache {folder} stored"
                    )
    return None


def study(
    specs: list[str], variants: tuple[str, ...], runs: int, clean: Path | None = None
) -> dict[str, list[tuple[Columns, list[Columns]]]]:
    """Per variant: (nominal, [unchanged runs]) Columns of every ship of every cache spec DIR:KEY:FIRST:N;
    with ``clean`` (a folder), those of the same recordings without sensor noise (key ``variant + " clean"``)."""
    from benchmarks.bench_detect_truth import nominal_seed, run_seeds, stored_recording

    out: dict[str, list] = {}
    for spec in specs:
        parsed = cache_spec(spec)
        if parsed is None:  # main() refuses it in one line first (cache_problem); another caller gets no empty table
            raise ValueError(f"--cache {spec}: expected DIR:KEY:FIRSTSHIP:NSHIPS")
        folder, key, first, n = parsed
        for v in variants:
            for ship in range(first, first + n):
                prior = load_prior(folder, v, ship, key)
                paths = [folder / stored_recording(v, ship, TRUTH_FP)]
                paths += [folder / stored_recording(v, ship, TRUTH_FP, STORED_RUNS, i) for i in range(runs)]
                cols = [recording_columns(prior, p) for p in paths]
                out.setdefault(v, []).append((cols[0], cols[1:]))
                if clean is not None:
                    seeds = [nominal_seed(ship), *run_seeds(ship, runs)]
                    cc = [recording_columns(prior, clean_recording(v, ship, s, clean)) for s in seeds]
                    out.setdefault(f"{v} clean", []).append((cc[0], cc[1:]))
    return out


def table(data: dict[str, list[tuple[Columns, list[Columns]]]], size: int = 3) -> list[str]:
    """Markdown rows per variant: residual sd, noise share, own refit share, each candidate's share (nominal
    in-sample / runs out of sample), in the band and overall, and the best ``size``-term set's."""
    names = next(iter(data.values()))[0][0].names
    lines = []
    for v, pairs in data.items():
        for band in (True, False):
            tag = "band" if band else "all"
            nom = [p[0] for p in pairs]
            run = [t for p in pairs for t in p[1]]
            sd = np.mean([np.std(band_pass(c.e, c.band) if band else c.e) for c in run]) * 1e3
            row = {
                "noise": (np.mean([noise_share(c, band) for c in nom]), np.mean([noise_share(c, band) for c in run])),
                "refit": (np.mean([refit_share(c, band) for c in nom]), np.mean([refit_share(c, band) for c in run])),
            }
            for j, name in enumerate(names):
                ins = np.mean([shares(n_, n_, [j], band) for n_ in nom])
                oos = np.mean([shares(p[0], t, [j], band) for p in pairs for t in p[1]])
                row[name] = (ins, oos)
            best = greedy(pairs, size, band)
            ins = np.mean([shares(n_, n_, best, band) for n_ in nom])
            oos = np.mean([shares(p[0], t, best, band) for p in pairs for t in p[1]])
            top = sorted(names, key=lambda k: -row[k][1])[:3]
            cells = " ".join(f"{k} {100 * row[k][0]:.1f}/{100 * row[k][1]:.1f}" for k in top)
            lines.append(
                f"| {v} | {tag} | {sd:.3f} | {100 * row['noise'][0]:.0f} / {100 * row['noise'][1]:.0f} | "
                f"{100 * row['refit'][0]:.1f} / {100 * row['refit'][1]:.1f} | {cells} | "
                f"{' + '.join(names[j] for j in best)}: {100 * ins:.1f} / {100 * oos:.1f} |"
            )
            lines.append("<!-- " + " ".join(f"{k}={100 * row[k][0]:.1f}/{100 * row[k][1]:.1f}" for k in names) + " -->")
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", action="append", default=[], help="DIR:KEY:FIRSTSHIP:NSHIPS of a stored screening (read only)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--runs", type=int, default=3, help="unchanged runs per ship tested out of sample")
    ap.add_argument("--size", type=int, default=3, help="terms in the best set (forward selection on the nominals)")
    ap.add_argument("--clean", type=Path, help="folder for the recordings re-simulated without sensor noise (diagnosis)")
    ap.add_argument("--save", type=Path, help="pickle the columns here (a later --load re-tabulates without simulating)")
    ap.add_argument("--load", type=Path, help="tabulate the columns a --save wrote")
    a = ap.parse_args(argv)
    if not 1 <= a.runs <= STORED_RUNS:  # run i >= 10 of the stored studies is a changed one
        ap.error(f"--runs {a.runs}: give 1 to {STORED_RUNS} (the stored studies' unchanged runs per ship)")
    if a.load is not None and not a.load.is_file():
        ap.error(f"--load {a.load}: no such file; give a file --save wrote")
    if a.load is None and (problem := cache_problem(a.cache, tuple(a.variants), a.runs)) is not None:
        ap.error(problem)  # before any simulation: a missing folder or file was a traceback after minutes
    warnings.simplefilter("ignore", RuntimeWarning)
    if a.load:
        data = pickle.loads(a.load.read_bytes())
    else:
        if a.clean:
            a.clean.mkdir(parents=True, exist_ok=True)
        data = study(a.cache, tuple(a.variants), a.runs, a.clean)
        if a.save:
            a.save.write_bytes(pickle.dumps(data))
    print(
        "| variant | part | run residual sd, 1e-3 rad/s | noise % nominal / runs | own refit % nominal / runs (in-sample) | "
        "best 3 single terms % nominal (in-sample) / runs (fitted on the nominal) | best set % nominal / runs |"
    )
    print("|---|---|---|---|---|---|---|")
    print("\n".join(table(data, a.size)))
    print()
    print(
        "| variant | part | run residual sd / noise-free, 1e-3 rad/s | noise % (truth) | noise % (prior's reading) | "
        "shared prior offset % | run's own refit % | best single term % (noise-free, out of sample, best per run) |"
    )
    print("|---|---|---|---|---|---|---|")
    for v in [k for k in data if not k.endswith(" clean") and f"{k} clean" in data]:
        for band in (True, False):
            d = decomposition(data[v], data[f"{v} clean"], band)
            print(
                f"| {v} | {'band' if band else 'all'} | {1e3 * d['sd']:.3f} / {1e3 * d['sd_clean']:.3f} | {100 * d['noise']:.0f} | "
                f"{100 * d['noise_read']:.0f} | {100 * d['offset']:.1f} | {100 * d['refit']:.1f} | {100 * d['terms']:.1f} |"
            )
    print()
    print(
        "| variant | yaw inertia read on the runs without noise: mean, mean |per prior| % | with noise: mean, sd % | "
        "sd within a prior: with noise, its noise's own part % | per prior: without / with noise, mean % |"
    )
    print("|---|---|---|---|---|")
    for v in [k for k in data if not k.endswith(" clean") and f"{k} clean" in data]:
        if data[v][0][0].S is None:
            continue
        d = reading_rows(data[v], data[f"{v} clean"])
        print(
            f"| {v} | {d['clean_mean']:+.2f}, {d['clean_abs']:.2f} | {d['noisy_mean']:+.2f}, {d['noisy_sd']:.2f} | "
            f"{d['within_sd']:.2f}, {d['noise_sd']:.2f} | {' '.join(d['per_prior'])} |"
        )


if __name__ == "__main__":
    main()
