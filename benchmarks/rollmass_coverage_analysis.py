"""``bench_rollmass_coverage.py analyse``: covariance estimators re-evaluated on the stored fits of ``fit`` (the
z-scores of mass and height per variant and case, their spread and 95 % coverage; with ``--quiet-dir`` each error split
into the structure's bias and the noise's part)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.special import stdtrit

from benchmarks.rollmass_sea_analysis import leveraged
from identify.rollmass import sandwich as sw


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
    """The covariance the fit reported: the plain sandwich at its window (``lags``: 5 s before stop 62, 20 s since),
    leverage-corrected where the fit stored ``rho``."""
    C = _cov(z, int(z["lags"]))
    return leveraged(z, C) if "rho" in z else C


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
    z0 = fits[0][3]
    # the sample time: stored since stop 62 (the captured window became the interval's 20 s); before, the window
    # was SANDWICH_LAG_S = 5 s
    T = float(z0["T"]) if "T" in z0 else 5.0 / float(z0["lags"])
    own = f"NW {float(z0['lags']) * T:g} s"  # the fits' own window, as they reported it
    print(f"{len(fits)} stored fits; sample time {T:g} s, the fits' window {own[3:]}\n")
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
        rows += _rows(fits, f"{own} leverage", lambda z: leveraged(z, _cov(z, int(z["lags"]))))
    if all("nu" in z for *_, z in fits):  # Bell & McCaffrey's t_{0.975, nu} for 1.96 (sandwich.load_dof)
        rows += _rows(fits, f"{own} lev t_nu", lambda z: leveraged(z, _cov(z, int(z["lags"]))), lambda z: stdtrit(z["nu"], 0.975))
    print()
    _table(rows, by_case=False)
    if all("nu" in z for *_, z in fits):
        _dof_table(fits)
    print()
    _table([r for r in rows if r[0] in (own, f"{own} leverage", f"{own} lev t_nu")], by_case=True)
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
        sd = np.sqrt(np.diag(leveraged(z, _cov(z, int(z["lags"])))))
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
