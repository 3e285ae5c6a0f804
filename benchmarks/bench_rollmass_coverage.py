"""Coverage of `shiptrial mass` (oe) intervals on the basin truth, measurable without refitting.

``fit`` runs the oe fits of :mod:`benchmarks.bench_rollmass_truth` (same seeds, so runs pair with it)
one process, one fit at a time, and stores per fit what the sandwich covariance needs: each dataset's
per-sample scores ``h_t = sum_channels J_t f_t`` (n x p), the residual per channel (n x 3), ``A = J^T J``,
the prior rows of ``J``, the estimate, its reported sd and the truth (one ``.npz`` per fit, so an
interrupted run keeps what it fitted). ``analyse`` re-evaluates covariance estimators on the stored fits
and prints per variant and case the z-scores ``(estimate - truth) / sd`` of mass and height, their
spread, and the 95 % coverage, for each estimator (:mod:`identify.rollmass.sandwich`).

    python benchmarks/bench_rollmass_coverage.py fit /tmp/cov --runs 4                      # stop 49: stopped after runs 0-1
    python benchmarks/bench_rollmass_coverage.py fit /tmp/quiet --runs 4 --quiet --like /tmp/cov   # the same fits, no noise
    python benchmarks/bench_rollmass_coverage.py analyse /tmp/cov --quiet-dir /tmp/quiet
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise  # stop 50
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise --store /tmp/s51/imu
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise --store /tmp/s60c/cal --vary calibration  # stop 60: one dataset's sea
    python benchmarks/bench_rollmass_coverage.py sea_analyse /tmp/s51/imu   # stop 51: the spread against the meats

``repeat --store`` keeps each converged sea's Jacobian, residual and final point and the sea's own response in the
residual at the quiet fit's point; ``sea_analyse`` compares the load's spread over the seas with the sandwich from
the fitted residual, the leverage-corrected one the fit reports (:func:`identify.rollmass.sandwich.load_cov`) and
the one from that true response.

The ships of a run depend on ``--runs`` (the family is drawn at once), so a directory is resumed (fits already
stored are skipped) and paired only with the same ``--runs``.
"""

from __future__ import annotations

import argparse
import copy
import inspect
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, see bench_rollmass_truth.py

import numpy as np  # noqa: E402
from scipy.signal import lfilter  # noqa: E402
from scipy.special import stdtrit  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.rollmass_sea_analysis import _leveraged, sea_analyse, vary_analyse  # noqa: E402
from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass import sandwich as sw  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from identify.rollmass.fit_path import Counted  # noqa: E402
from primitives.errors import UserError  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

CONSTANT_SPEED = ("base", "sway_roll", "restoring", "imu_mount", "waves")


def _capture() -> dict:
    """Wrap oe_fit's covariance call (the fit's last, at its final point) to keep its arguments and result."""
    seen: dict = {}
    orig = oe_fit.load_interval

    def wrapped(basis, f, lengths, lags):
        lengths = list(lengths)
        out = orig(basis, f, lengths, lags)
        seen.update(J=basis.J, f=f, lengths=lengths, lags=lags, rho=out.rho, nu=out.dof)
        return out

    oe_fit.load_interval = wrapped
    finish = oe_fit._gauss_newton

    def finished(prob, x, steps, lags):
        out = finish(prob, x, steps, lags)
        bare = prob._prob if isinstance(prob, Counted) else prob  # a Counted wrapper (stop 56) does not copy
        seen.update(x=out[0], free=prob.free, prob=bare)  # the final point (the last _fit's, as the covariance's)
        return out

    oe_fit._gauss_newton = finished
    return seen


def _store(seen: dict, path: Path, **extra) -> None:
    """The scores, residuals and products of one fit (see the module docstring) in ``path``."""
    J, f, lengths = seen["J"], seen["f"], seen["lengths"]
    out, i = {}, 0
    for k, n in enumerate(lengths):
        rows = slice(i, i + 3 * n)
        out[f"h{k}"] = (J[rows] * f[rows, None]).reshape(n, 3, -1).sum(axis=1)
        out[f"f{k}"] = f[rows].reshape(n, 3)
        i += 3 * n
    out.update(A=J.T @ J, Jp=J[i:], fp=f[i:], lengths=np.array(lengths), lags=seen["lags"])
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **out, **{k: np.asarray(v) for k, v in extra.items()})
    tmp.replace(path)


def _load(d: Path) -> list[tuple[str, str, int, dict]]:
    """The stored fits of ``d``: (variant, case, run, arrays)."""
    out = []
    for p in sorted(d.glob("*_case?_run?.npz")) + sorted(d.glob("*_case?_run??.npz")):  # not a killed write's .tmp
        variant, case, run = p.stem.rsplit("_", 2)
        z = dict(np.load(p))
        k = len(z["lengths"])
        z["h"] = [z[f"h{i}"] for i in range(k)]
        z["f"] = [z[f"f{i}"] for i in range(k)]
        out.append((variant, case, int(run[3:]), z))
    return out


def _cov(z: dict, lags: list[int] | int) -> np.ndarray:
    """The load's sandwich covariance from a stored fit, Bartlett window ``lags`` (one per dataset or all)."""
    Ainv = np.linalg.inv(z["A"])
    lags = lags if isinstance(lags, list) else [lags] * len(z["h"])
    S = z["Jp"].T @ z["Jp"]
    for h, L in zip(z["h"], lags):
        S += sw.bartlett_meat(h, L)
    return (Ainv @ S @ Ainv)[-2:, -2:]


def _reported(z: dict) -> np.ndarray:
    """The covariance the fit reported: the plain 5 s sandwich, leverage-corrected where the fit stored ``rho``."""
    C = _cov(z, int(z["lags"]))
    return _leveraged(z, C) if "rho" in z else C


def andrews_lags(g: np.ndarray) -> int:
    """Andrews' (1991, eq. 6.2-6.4) data-driven Bartlett window for the series ``g`` (n x k): an AR(1)
    ``rho_a`` per (standardised) column, ``alpha(1) = sum 4 rho^2 s^4 / ((1-rho)^6 (1+rho)^2) /
    sum s^4 / (1-rho)^4`` with ``s^2 = 1 - rho^2`` the innovation variance, window
    ``1.1447 (alpha(1) n)^(1/3)`` samples."""
    x = (g - g.mean(axis=0)) / np.maximum(g.std(axis=0), 1e-300)
    rho = np.clip(np.einsum("ij,ij->j", x[1:], x[:-1]) / np.einsum("ij,ij->j", x[:-1], x[:-1]), -0.99, 0.99)
    s4 = (1 - rho**2) ** 2
    alpha = np.sum(4 * rho**2 * s4 / ((1 - rho) ** 6 * (1 + rho) ** 2)) / np.sum(s4 / (1 - rho) ** 4)
    return max(1, round(1.1447 * (alpha * len(g)) ** (1 / 3)))


def _influence(z: dict) -> list[np.ndarray]:
    """Each dataset's load influence series ``g_t = (A^-1 h_t)[load]`` (n x 2)."""
    Ainv = np.linalg.inv(z["A"])
    return [h @ Ainv[:, -2:] for h in z["h"]]


def _tau(g: np.ndarray, T: float, max_s: float = 20.0) -> float:
    """Integrated autocorrelation time [s] of the load influence (mass column), lags up to ``max_s``:
    ``T (1 + 2 sum rho_k)`` truncated at the first negative rho (a rough long-correlation figure)."""
    x = g[:, 0] - g[:, 0].mean()
    n = len(x)
    c = np.correlate(x, x, "full")[n - 1 : n - 1 + int(max_s / T)] / (x @ x)
    neg = np.flatnonzero(c < 0)
    k = neg[0] if len(neg) else len(c)
    return T * (1 + 2 * c[1:k].sum())


def _rows(fits: list, name: str, cov_fn, cv_fn=lambda z: 1.96) -> list[tuple]:
    rows = []
    for variant, case, run, z in fits:
        C = cov_fn(z)
        sd = np.sqrt(np.diag(C))
        zs = np.array([(z["m"] - z["m_true"]) / sd[0], (z["z"] - z["z_true"]) / sd[1]])
        rows.append((name, variant, case, run, zs, cv_fn(z), sd))
    return rows


def _table(rows: list[tuple], by_case: bool) -> None:
    keys = dict.fromkeys((r[0], r[1], r[2] if by_case else "all") for r in rows)
    print(
        f"{'estimator':18} {'variant':10} {'case':5} {'n':>3} | {'z_m mean':>8} {'sd':>5} {'cov m%':>6} | "
        f"{'z_z mean':>8} {'sd':>5} {'cov z%':>6} | {'both%':>5} | {'med sd m':>8} {'med sd z':>8}"
    )
    for est, variant, case in keys:
        sel = [r for r in rows if r[0] == est and r[1] == variant and (not by_case or r[2] == case)]
        zs = np.array([r[4] for r in sel])
        cv = np.array([r[5] for r in sel])
        inside = np.abs(zs) <= (cv if cv.ndim == 2 else cv[:, None])  # one critical value per fit, or per parameter
        sds = np.array([r[6] for r in sel])
        print(
            f"{est:18} {variant:10} {case:5} {len(sel):3d} | {zs[:, 0].mean():+8.2f} {zs[:, 0].std(ddof=1) if len(sel) > 1 else np.nan:5.2f} "
            f"{100 * inside[:, 0].mean():6.0f} | {zs[:, 1].mean():+8.2f} {zs[:, 1].std(ddof=1) if len(sel) > 1 else np.nan:5.2f} "
            f"{100 * inside[:, 1].mean():6.0f} | {100 * inside.all(axis=1).mean():5.0f} | "
            f"{1000 * np.median(sds[:, 0]):7.1f}g {1000 * np.median(sds[:, 1]):7.1f}mm"
        )


def analyse(a: argparse.Namespace) -> None:
    fits = _load(Path(a.dir))
    T = 5.0 / float(fits[0][3]["lags"])  # the fits' window is SANDWICH_LAG_S = 5 s
    print(f"{len(fits)} stored fits; sample time {T:g} s\n")
    print(
        "reported sd reproduced from the stored scores (max relative difference): "
        + f"{max(abs(np.sqrt(_reported(z)[0, 0]) / z['m_sd'] - 1) for *_, z in fits):.1e}\n"
    )
    print("integrated autocorrelation time of the mass influence, per dataset [s] (nominal, calibration, loaded):")
    for variant, case, run, z in fits:
        taus = [_tau(g, T) for g in _influence(z)]
        print(f"  {variant:10} {case} run {run}: " + " ".join(f"{t:5.2f}" for t in taus))
    rows = []
    for L_s in (1.0, 5.0, 10.0, 20.0):
        rows += _rows(fits, f"NW {L_s:g} s", lambda z, L=round(L_s / T): _cov(z, L))
    rows += _rows(fits, "NW auto (A91)", lambda z: _cov(z, [andrews_lags(g) for g in _influence(z)]))
    if all("rho" in z for *_, z in fits):
        rows += _rows(fits, "NW 5 s leverage", lambda z: _leveraged(z, _cov(z, int(z["lags"]))))
    if all("nu" in z for *_, z in fits):  # Bell & McCaffrey's t_{0.975, nu} for 1.96 (sandwich.load_dof)
        rows += _rows(
            fits, "NW 5 s lev t_nu", lambda z: _leveraged(z, _cov(z, int(z["lags"]))), lambda z: stdtrit(z["nu"], 0.975)
        )
    print()
    _table(rows, by_case=False)
    if all("nu" in z for *_, z in fits):
        _dof_table(fits)
    print()
    _table([r for r in rows if r[0] in ("NW 5 s", "NW 5 s leverage", "NW 5 s lev t_nu")], by_case=True)
    if a.quiet_dir:
        quiet = {(v, c, r): z for v, c, r, z in _load(Path(a.quiet_dir))}
        _split(fits, quiet)
        for spec in a.part or []:
            _part(spec, quiet)


def _dof_table(fits: list) -> None:
    """Per fit the Satterthwaite ``nu`` (:func:`sandwich.load_dof`), its ``t_{0.975, nu}`` and the leverage-corrected
    z-scores: does the interval hold the truth with 1.96, with ``t``? (mass / height)"""
    print("\nper fit: nu (m / z), t_0.975 (m / z), |z| leverage-corrected (m / z), holds with 1.96 -> with t")
    for variant, case, run, z in fits:
        sd = np.sqrt(np.diag(_leveraged(z, _cov(z, int(z["lags"])))))
        a = np.abs([(z["m"] - z["m_true"]) / sd[0], (z["z"] - z["z_true"]) / sd[1]])
        t = stdtrit(z["nu"], 0.975)
        print(
            f"  {variant:10} {case} run {run}: nu {z['nu'][0]:5.1f} / {z['nu'][1]:5.1f}, t {t[0]:.3f} / {t[1]:.3f}, "
            f"|z| {a[0]:.2f} / {a[1]:.2f}, holds {''.join('y' if v else 'n' for v in a <= 1.96)} -> "
            f"{''.join('y' if v else 'n' for v in a <= t)}"
        )


def _part(spec: str, quiet: dict) -> None:
    """Fits with one noise source (``NAME=DIR``, e.g. ``waves=`` a ``fit --no-sensor-noise``): does their own
    sandwich cover what that source moves the load by (the fit minus the quiet fit, in its reported sd)?"""
    name, d = spec.split("=", 1)
    rows = [
        (v, np.array([(z["m"] - quiet[v, c, r]["m"]) / z["m_sd"], (z["z"] - quiet[v, c, r]["z"]) / z["z_sd"]]))
        for v, c, r, z in _load(Path(d))
        if (v, c, r) in quiet
    ]
    print(f"\n{name} alone: (fit - quiet fit) / the fit's own sd, mass, height")
    for v in [*dict.fromkeys(r[0] for r in rows), "pooled"]:
        e = np.array([r[1] for r in rows if v in ("pooled", r[0])])
        print(
            f"  {v:10} n {len(e):2d} | mean {e.mean(axis=0).round(2)} sd {e.std(axis=0, ddof=1).round(2)} "
            f"| |z| <= 1.96: {(100 * (np.abs(e) <= 1.96).mean(axis=0)).round(0)} %"
        )


def _split(fits: list, quiet: dict) -> None:
    """Each error in the reported sd (NW 5 s) split into the structure's bias (the quiet fit's error, the
    same ship without waves and noise) and the noise's part (the noisy fit minus the quiet one)."""
    print("\nerror / reported sd = bias (quiet fit - truth) + noise (noisy - quiet fit); mass, then height")
    rows = []
    for v, c, r, z in fits:
        q = quiet.get((v, c, r))
        if q is None:
            continue
        sd = np.array([z["m_sd"], z["z_sd"]])
        est, tru, qe = np.array([z["m"], z["z"]]), np.array([z["m_true"], z["z_true"]]), np.array([q["m"], q["z"]])
        rows.append((v, c, (qe - tru) / sd, (est - qe) / sd))
    print(
        f"{'variant':10} {'case':5} {'n':>3} | {'bias m':>6} {'noise m mean':>12} {'sd':>5} | {'bias z':>6} {'noise z mean':>12} {'sd':>5}"
    )
    for v, c in dict.fromkeys((r[0], r[1]) for r in rows):
        b = np.array([r[2] for r in rows if r[0] == v and r[1] == c])
        e = np.array([r[3] for r in rows if r[0] == v and r[1] == c])
        sd = e.std(axis=0, ddof=1) if len(e) > 1 else np.full(2, np.nan)
        print(
            f"{v:10} {c:5} {len(b):3d} | {b[:, 0].mean():+6.2f} {e[:, 0].mean():+12.2f} {sd[0]:5.2f} | "
            f"{b[:, 1].mean():+6.2f} {e[:, 1].mean():+12.2f} {sd[1]:5.2f}"
        )
    for v in dict.fromkeys(r[0] for r in rows):
        e = np.array([r[3] for r in rows if r[0] == v])
        b = np.array([r[2] for r in rows if r[0] == v])
        print(
            f"{v:10} all   {len(e):3d} | rms bias {np.sqrt((b**2).mean(axis=0))} | noise sd {e.std(axis=0, ddof=1)} "
            f"| noise |z|<=1.96: {100 * (np.abs(e) <= 1.96).mean(axis=0)} %"
        )


def _sensor_noise_off() -> None:
    """The truth's waves kept and its IMU noise and bias switched off (its ``_measure``'s noise scale 0; the
    filters stay): with the ``quiet`` and the full fits it splits the noise's part into waves and sensor."""
    measure = bt._measure

    def quiet_sensor(*args):
        return measure(*args[:14], 0.0, *args[15:])

    bt._measure = quiet_sensor


def _waves_off() -> None:
    """The truth's IMU noise kept and its sea (JONSWAP or narrow-band disturbance) switched off."""
    for name in ("_jonswap", "_narrowband"):
        draw = getattr(bt, name)
        setattr(bt, name, lambda *args, _draw=draw: 0.0 * _draw(*args))  # drawn, so the rng stream is unchanged


def _sea_without_common() -> None:
    """The truth's base disturbance (:func:`basin_truth._narrowband`, its draws unchanged) without the component
    it shares across sway, roll and yaw: each degree of freedom only its own resonance, same sd."""

    def own(n: int, rng: np.random.Generator, runs: int) -> np.ndarray:
        out = np.empty((runs, n, 3))
        for j in range(runs):
            f0, zeta = rng.uniform(1.0, 1.4), rng.uniform(0.15, 0.35)
            w0, T = 2 * np.pi * f0, 1 / bt.FS
            r = np.exp(-zeta * w0 * T)
            a = [1.0, -2 * r * np.cos(w0 * T * np.sqrt(1 - zeta**2)), r * r]
            x = lfilter([1.0, -1.0], a, rng.standard_normal((n + 400, 4)), axis=0)[400:, 1:]
            out[j] = x / x.std(axis=0)
        return out * np.array([0.015, 0.002, 0.002])

    bt._narrowband = own


def _sea_scaled(k: float) -> None:
    """The truth's sea (JONSWAP or base disturbance, draws unchanged) times ``k``."""
    for name in ("_jonswap", "_narrowband"):
        draw = getattr(bt, name)
        setattr(bt, name, lambda *args, _draw=draw: k * _draw(*args))


def _drop_column(path: Path, name: str) -> Path:
    """Rewrite a recording written by :func:`basin_truth.write_csv` without its column ``name`` (its
    ``# key: value`` lines and the other columns' text unchanged)."""
    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    j = lines[head].split(",").index(name)
    keep = lines[:head] + [",".join(c for k, c in enumerate(line.split(",")) if k != j) for line in lines[head:]]
    path.write_text("\n".join(keep) + "\n")
    return path


def fit(a: argparse.Namespace) -> None:
    if a.sea_scale != 1.0:
        _sea_scaled(a.sea_scale)
    if a.own_sea:
        _sea_without_common()
    if a.no_sensor_noise:
        _sensor_noise_off()
    if a.no_waves:
        _waves_off()
    outdir = Path(a.dir)
    outdir.mkdir(parents=True, exist_ok=True)
    seen = _capture()
    sims = {}
    for variant in a.variants.split(","):
        seed = bt.variant_seed(a.seed, variant)  # as bench_rollmass_truth.py
        sims[variant] = bt.simulate_runs(variant, a.runs, seed, quiet=a.quiet)
    for run in range(a.runs):  # run-major: an interrupted run has about as many runs of every variant
        for variant, (ship, data) in sims.items():
            for case in a.cases.split(","):
                path = outdir / f"{variant}_{case}_run{run}.npz"
                if path.exists() or (a.like and not (Path(a.like) / path.name).exists()):
                    continue
                m_true, z_true = bt.truth_load(case)
                seen.clear()
                c0 = time.process_time()
                with tempfile.TemporaryDirectory() as d:
                    recs = bt.case_recordings(ship, data, case, run)
                    paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs]
                    if a.no_phi:  # no roll angle: no wall-sided heel input from the measured (sea-driven) roll
                        paths = [_drop_column(p, "phi") for p in paths]
                    try:
                        e = estimate_from_files(*paths, method="oe")
                    except UserError as exc:
                        print(f"{path.name}: refused: {exc}", flush=True)
                        continue
                cpu = time.process_time() - c0
                if "J" not in seen:
                    print(f"{path.name}: no covariance ({'; '.join(e.warnings)[:80]})", flush=True)
                    continue
                keep = {"J": seen["J"]} if a.keep_jacobian else {}
                _store(
                    seen,
                    path,
                    **_load_fields(e, m_true, z_true),
                    converged=e.converged,
                    cpu=cpu,
                    rho=seen["rho"],
                    nu=seen["nu"],
                    **keep,
                )
                print(
                    f"{path.name}: m {e.m:.4f} ({m_true}) sd {e.m_sd:.4f}, z {e.zbar_m:.4f} ({z_true}) sd {e.zbar_m_sd:.4f}, "
                    f"conv {e.converged}, {cpu:.1f} s cpu",
                    flush=True,
                )


def _fresh_sea(scale: float, key: list[int], hold: tuple[list[int], set[int]] | None = None) -> None:
    """The truth's sea (JONSWAP or base disturbance) drawn from a stream of its own, ``key`` + a call
    counter, times ``scale``; the truth's own draw is made and dropped, so the run's stream goes on as
    before (the ship, the steering and the sensor noise stay the draws of the truth's seed). The sea is
    drawn once per dataset, in :data:`basin_truth.DATASETS` order, so the call counter is the dataset's index;
    ``hold = (fixed_key, varied)``: only the datasets whose index is in ``varied`` take ``key``'s sea, the others
    ``fixed_key``'s (one sea held for them over the realizations)."""
    calls = [0]

    def fresh(draw, *args):
        draw(*args)  # consumes the run's stream
        k = key if hold is None or calls[0] in hold[1] else hold[0]
        own = np.random.default_rng([*k, calls[0]])
        calls[0] += 1
        return scale * draw(*[own if isinstance(x, np.random.Generator) else x for x in args])

    for name in ("_jonswap", "_narrowband"):
        draw = _TRUTH_SEA.setdefault(name, getattr(bt, name))  # the truth's own, not an earlier call's wrapper
        setattr(bt, name, lambda *args, _draw=draw: fresh(_draw, *args))


_TRUTH_SEA: dict = {}


def _fresh_sensor(key: list[int]) -> None:
    """The IMU's noise and bias (:func:`basin_truth._measure`'s draws, and its AHRS roll error's seed) drawn from a
    stream of its own, ``key`` + a call counter (the dataset's index, as in :func:`_fresh_sea`), instead of the run's
    stream: each realization then has its own sensor noise, where plain ``repeat`` keeps the family's draw on every
    sea. ``_measure`` is the run stream's last consumer, so the ship, the steering and the sea are unchanged."""
    calls = [0]
    measure = _TRUTH_SEA.setdefault("_measure", bt._measure)  # the truth's own, not an earlier call's wrapper

    def fresh(*args):
        own = np.random.default_rng([*key, 0x5E45, calls[0]])
        calls[0] += 1
        return measure(args[0], own, *args[2:15], int(own.integers(2**31)))  # args[15]: the AHRS error's seed

    bt._measure = fresh


def _quiet_reference(a: argparse.Namespace, seed: int, seen: dict) -> dict:
    """The same ship, case and steering without the sea (and, with ``--no-sensor-noise``, without the sensor's noise):
    its fit's final point ``x_q`` (the ship's pseudo-true parameters in the oe model) and its datasets as the
    fit read them (for :func:`_disturbance`)."""
    _fresh_sea(0.0, [a.sea_seed, 10**6])
    ship, data = bt.simulate_runs(a.variant, a.runs, seed)
    seen.clear()
    with tempfile.TemporaryDirectory() as d:
        recs = bt.case_recordings(ship, data, a.case, a.run)
        e = estimate_from_files(*[bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs], method="oe")
    print(f"quiet: m {e.m:.4f}, z {e.zbar_m:.4f}, converged {e.converged}", flush=True)
    return {"x": seen["x"], "datasets": seen["prob"].datasets}


def _disturbance(prob, quiet: dict) -> dict:
    """The residual of one sea's fit at the quiet fit's point ``x_q``, on its own data and on the quiet data with the
    same whiteners, weights and turn inputs: ``e = f(x_q; sea) - f(x_q; quiet)`` is the sea's response in the
    residual at fixed parameters (the true disturbance the fit sees, not projected)."""
    q = copy.copy(prob)
    q.datasets = quiet["datasets"]
    q.Y = [oe_fit._measured(d, prob.kn.g) for d in q.datasets]
    f_sea, f_quiet = prob.residual(quiet["x"]), q.residual(quiet["x"])
    return {"x_q": quiet["x"], "f_sea_q": f_sea, "e_q": f_sea - f_quiet}


def _load_fields(e, m_true: float, z_true: float) -> dict[str, float]:
    """A fit's load, its reported sds and the truth's, as the stored files name them."""
    return {"m": e.m, "z": e.zbar_m, "m_sd": e.m_sd, "z_sd": e.zbar_m_sd, "m_true": m_true, "z_true": z_true}


def _store_sea(out: Path, seen: dict, quiet: dict, fields: dict[str, float]) -> None:
    """One sea's whole Jacobian, residual and final point with the sea's own response (see `sea_analyse`)."""
    keep = {k: seen[k] for k in ("J", "f", "x", "lengths", "lags")}
    np.savez_compressed(out, **keep, free=np.array(seen["free"]), **fields, **_disturbance(seen["prob"], quiet))


ROLES = ("nominal", "calibration", "loaded")
# a fit's _reweighted calls per LM path: fit_output_error's n_reweight default (read, so it cannot go stale)
FROZEN_STAGES = inspect.signature(oe_fit.fit_output_error).parameters["n_reweight"].default


def _held_sea(a: argparse.Namespace) -> tuple[list[int], set[int]] | None:
    """``--vary ROLE``: the fresh sea for that role's dataset only, the case's other datasets on one held sea
    (``--held-sea K``: realization K's of ``--sea-seed``), for :func:`_fresh_sea`; ``None`` for ``--vary all``."""
    if not 0 <= a.held_sea < a.realizations:
        raise SystemExit(f"--held-sea {a.held_sea}: must be one of the {a.realizations} realizations (it is fitted first)")
    if a.vary == "all":
        return None
    name = bt.CASES[a.case][ROLES.index(a.vary)]
    return [a.sea_seed, a.held_sea], {list(bt.DATASETS).index(name)}


def _frozen_noise() -> list:
    """``--freeze-noise``: the first fit after this call records its stages' whiteners and weights
    (``oe_fit._reweighted``'s returns), every later fit replays them in the same order instead of estimating its own
    from its residuals (the noise model held, as the sandwich takes it: given, not estimated from the same data)."""
    kept: list = []
    calls = [0]
    orig = oe_fit._reweighted

    def frozen(errs, ar, ar_order):
        if len(kept) < FROZEN_STAGES:
            kept.append(orig(errs, ar, ar_order))
            return kept[-1]
        calls[0] += 1
        return kept[(calls[0] - 1) % FROZEN_STAGES]

    oe_fit._reweighted = frozen
    return kept


def _sensor_label(a: argparse.Namespace) -> str:
    """Which sensor noise the realizations had, for the summary line."""
    return "off" if a.no_sensor_noise else "fresh" if a.fresh_sensor else "the run's"


def repeat(a: argparse.Namespace) -> None:
    """One ship, case and steering of the family (``--variant``, ``--run``, ``--case``: the truth bench's
    draws), fitted on ``--realizations`` fresh seas (:func:`_fresh_sea`): the load's spread over the seas
    against the mean sd the fits report, and the z-scores ``(estimate - truth) / reported sd``. Unlike the
    pooled fits of ``fit`` (ships and cases differ, and a run's cases share datasets) this measures the
    interval of one ship: its sandwich's error, not the spread of the family's biases."""
    if a.fresh_sensor and a.no_sensor_noise:
        raise SystemExit("--fresh-sensor with --no-sensor-noise: there is no sensor noise to draw afresh; fix: drop one")
    if a.no_sensor_noise:
        _sensor_noise_off()
    seed = bt.variant_seed(a.seed, a.variant)  # as bench_rollmass_truth.py
    m_true, z_true = bt.truth_load(a.case)
    seen = _capture()
    if a.store:
        Path(a.store).mkdir(parents=True, exist_ok=True)
    quiet = _quiet_reference(a, seed, seen) if a.store else None
    rows = []
    hold = _held_sea(a)
    if a.freeze_noise:  # recorded on the held sea's fit (realization --held-sea is fitted first)
        _frozen_noise()
    order = sorted(range(a.realizations), key=lambda k: k != a.held_sea)
    for k in order:
        seen.clear()
        _fresh_sea(a.sea_scale, [a.sea_seed, k], hold)
        if a.fresh_sensor:
            _fresh_sensor([a.sea_seed, k])
        ship, data = bt.simulate_runs(a.variant, a.runs, seed)
        with tempfile.TemporaryDirectory() as d:
            recs = bt.case_recordings(ship, data, a.case, a.run)
            paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs]
            c0 = time.process_time()
            try:
                e = estimate_from_files(*paths, method="oe")
            except UserError as exc:
                print(f"sea {k:2d}: refused: {exc}", flush=True)
                continue
        if e.converged and np.isfinite(e.m_sd) and np.isfinite(e.zbar_m_sd):  # a failed fit is said, not averaged
            rows.append((e.m, e.m_sd, e.zbar_m, e.zbar_m_sd))
            if a.store and "J" in seen:
                _store_sea(Path(a.store) / f"sea{k:02d}.npz", seen, quiet, _load_fields(e, m_true, z_true))
        print(
            f"sea {k:2d}: m {e.m:.4f} sd {e.m_sd:.4f}, z {e.zbar_m:.4f} sd {e.zbar_m_sd:.4f}, converged {e.converged}, "
            f"{time.process_time() - c0:.1f} s cpu",
            flush=True,
        )
    if len(rows) < 2:
        print(f"{len(rows)} of {a.realizations} fits converged: no spread to compare")
        return
    x = np.array(rows)
    zs = np.column_stack([(x[:, 0] - m_true) / x[:, 1], (x[:, 2] - z_true) / x[:, 3]])
    inside = int(np.all(np.abs(zs) <= 1.96, axis=1).sum())
    print(
        f"{a.variant} run {a.run} {a.case}, sea x{a.sea_scale:g}, vary {a.vary}, sensor {_sensor_label(a)}, {len(x)} of {a.realizations} seas converged: spread / mean reported sd "
        f"{x[:, 0].std(ddof=1) / x[:, 1].mean():.2f} (mass) {x[:, 2].std(ddof=1) / x[:, 3].mean():.2f} (height); "
        f"z sd {zs[:, 0].std(ddof=1):.2f} / {zs[:, 1].std(ddof=1):.2f}, mean {zs[:, 0].mean():+.2f} / {zs[:, 1].mean():+.2f}; "
        f"both inside {inside} of {len(x)}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fit", help="run the fits and store what the covariance needs")
    f.add_argument("dir")
    f.add_argument("--runs", type=int, default=3, help="runs drawn per variant (fitted run-major; the ships depend on it)")
    f.add_argument("--variants", default=",".join(CONSTANT_SPEED))
    f.add_argument("--cases", default="case1,case2,case3")
    f.add_argument("--seed", type=int, default=2015)
    f.add_argument("--like", help="fit only the (variant, case, run) stored in this directory (pair a --quiet run)")
    f.add_argument("--no-sensor-noise", action="store_true", help="the waves kept, the IMU noise and bias off")
    f.add_argument("--sea-scale", type=float, default=1.0, help="the sea's forces times this")
    f.add_argument("--own-sea", action="store_true", help="the base disturbance without its component common to the DOFs")
    f.add_argument("--no-waves", action="store_true", help="the IMU noise and bias kept, the waves off")
    f.add_argument("--no-phi", action="store_true", help="the recordings without their roll angle column")
    f.add_argument("--quiet", action="store_true", help="no waves, no sensor noise (the same ships): the structure's bias")
    f.add_argument("--keep-jacobian", action="store_true", help="store the fit's whole Jacobian J too (about 4 MB a fit)")
    r = sub.add_parser("repeat", help="one ship and case on fresh seas: the interval's own calibration")
    r.add_argument("--variant", default="base")
    r.add_argument("--run", type=int, default=0)
    r.add_argument("--case", default="case1")
    r.add_argument("--realizations", type=int, default=16)
    r.add_argument("--runs", type=int, default=4, help="runs drawn per variant (the ships depend on it, as in `fit`)")
    r.add_argument("--seed", type=int, default=2015)
    r.add_argument("--sea-seed", type=int, default=777)
    r.add_argument("--sea-scale", type=float, default=1.0)
    r.add_argument("--no-sensor-noise", action="store_true", help="the sea alone")
    r.add_argument("--fresh-sensor", action="store_true", help="the IMU noise and bias drawn afresh on every sea too")
    r.add_argument("--store", help="keep each converged fit's Jacobian, residual and final point in this directory")
    r.add_argument("--vary", choices=("all",) + ROLES, default="all", help="a fresh sea for this role's dataset only")
    r.add_argument("--held-sea", type=int, default=0, help="with --vary ROLE: the other datasets' sea (this realization's)")
    r.add_argument("--freeze-noise", action="store_true", help="every fit on the held sea's fit's whiteners and weights")
    g = sub.add_parser("analyse", help="z-scores and coverage of covariance estimators on stored fits")
    g.add_argument("dir")
    g.add_argument("--quiet-dir", help="a `fit --quiet` of the same runs: split each error into bias and noise")
    g.add_argument("--part", action="append", help="NAME=DIR: fits with one noise source, against --quiet-dir")
    s = sub.add_parser("sea_analyse", help="a `repeat --store` directory: the spread against the sandwich's meats")
    s.add_argument("dir", help="a `repeat --store` directory, or several (comma-separated) of the same ship")
    v = sub.add_parser("vary_analyse", help="`repeat --vary` of each role and all: is the error a sum of the datasets' parts?")
    v.add_argument("prefix", help="the stores are PREFIX_nominal, PREFIX_calibration, PREFIX_loaded and PREFIX_all")
    a = ap.parse_args()
    {"fit": fit, "repeat": repeat, "analyse": analyse, "sea_analyse": sea_analyse, "vary_analyse": vary_analyse}[a.cmd](a)


if __name__ == "__main__":
    main()
