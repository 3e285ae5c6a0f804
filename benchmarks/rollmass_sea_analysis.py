"""Stop 51's analysis of ``bench_rollmass_coverage.py repeat --store`` (one ship fitted on many seas): the load's spread
over the seas against the sandwich from the fitted residual, the leverage-corrected one the fit reports
(:func:`identify.rollmass.sandwich.load_cov`) and the one from the sea's own response at the quiet fit's point
(docs/mass-accuracy.md, stop 51). Run through ``bench_rollmass_coverage.py sea_analyse DIR[,DIR...]``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from identify.rollmass import sandwich as sw


def _leveraged(z: dict, C: np.ndarray) -> np.ndarray:
    """``C`` (the load's 2x2) with the fit's stored leverage factors (:func:`sandwich.load_cov`'s scaling)."""
    s = sw.leverage_scale(z["rho"])
    return C * np.outer(s, s)


def _sea_fits(dirs: str) -> list[dict]:
    """The fits ``repeat --store`` kept (one ``.npz`` per converged sea) in the comma-separated ``dirs`` (the same
    ship on several ``--sea-seed``)."""
    return [dict(np.load(p)) for d in dirs.split(",") for p in sorted(Path(d).glob("sea*.npz"))]


def _meat_of(J: np.ndarray, f: np.ndarray, lengths, lags: int) -> np.ndarray:
    """:func:`sandwich._meat` (the library's, so the sd reproduces the reported one)."""
    return sw._meat(J, f, list(lengths), int(lags))


def sea_analyse(a: argparse.Namespace) -> None:
    """One ship's ``repeat --store`` fits: the load's covariance over the seas against (i) the mean sandwich
    from each fit's fitted residuals (the reported interval) and (ii) the mean sandwich whose meat is built
    from the residual with the fit's own parameter error added back, ``f + J (x - xbar)`` (``xbar`` the mean
    estimate over the seas: the residual at the ship's pseudo-true parameters, linearised), i.e. without
    the projection of the disturbance onto the Jacobian's columns that the fitted residual carries."""
    fits = _sea_fits(a.dir)
    X = np.array([z["x"] for z in fits])
    xbar = X.mean(axis=0)
    load = X[:, -2:]
    emp = np.cov(load.T)
    covs = {"fitted (i)": [], "de-projected (ii)": []}
    for z, x in zip(fits, X):
        J, f, lengths, lags = z["J"], z["f"], z["lengths"], z["lags"]
        Ainv = np.linalg.inv(J.T @ J)
        for name, res in (("fitted (i)", f), ("de-projected (ii)", f + J @ (x - xbar))):
            covs[name].append((Ainv @ _meat_of(J, res, lengths, lags) @ Ainv)[-2:, -2:])
    rep = np.array([[z["m_sd"], z["z_sd"]] for z in fits])
    rho = np.array([sw.leverage_factors(z["J"], list(z["lengths"]), int(z["lags"])) for z in fits])
    covs["fitted, leverage"] = [_leveraged({"rho": r}, c) for r, c in zip(rho, covs["fitted (i)"])]
    plain = np.sqrt([np.diag(c) for c in covs["fitted (i)"]])
    print(
        f"{a.dir}: {len(fits)} seas; reported sd over the plain sandwich's {np.median(rep / plain, axis=0).round(4)}, "
        f"over the leverage-corrected one's {np.median(rep / np.sqrt([np.diag(c) for c in covs['fitted, leverage']]), axis=0).round(4)} "
        f"(median); leverage factors rho (m, z) {rho.mean(axis=0).round(3)} ({rho.min(axis=0).round(3)} .. {rho.max(axis=0).round(3)})"
    )
    print(
        f"  spread over the seas: mass {np.sqrt(emp[0, 0]) * 1000:.2f} g, height {np.sqrt(emp[1, 1]) * 1000:.2f} mm, corr {emp[0, 1] / np.sqrt(emp[0, 0] * emp[1, 1]):+.3f}"
    )
    for name, cs in covs.items():
        c = np.mean(cs, axis=0)
        print(
            f"  {name:18}: rms sd mass {np.sqrt(c[0, 0]) * 1000:.2f} g, height {np.sqrt(c[1, 1]) * 1000:.2f} mm; "
            f"spread / sd {np.sqrt(emp[0, 0] / c[0, 0]):.2f} / {np.sqrt(emp[1, 1] / c[1, 1]):.2f}"
        )
    if "e_q" in fits[0]:
        _true_disturbance(fits, emp)


def score_sums(J: np.ndarray, e: np.ndarray, lengths, a: np.ndarray) -> list[float]:
    """Each dataset's share ``a^T J_d^T e_d`` of the linear map from a residual ``e`` to one load parameter
    (``a`` its column of ``(J^T J)^-1``; datasets stacked as the fit stacks them, 3 channels a sample)."""
    out, i = [], 0
    for n in lengths:
        out.append(float((J[i : i + 3 * n].T @ e[i : i + 3 * n]) @ a))
        i += 3 * n
    return out


def _dataset_sums(fits: list[dict]) -> None:
    """Each dataset's share of the true response's map to the mass, ``a^T J_d^T e_d`` (``a`` the mass column of
    ``(J^T J)^-1``): its sd over the seas against the root of its mean lag-0 meat, and the datasets' correlation
    over the seas (independent records: near 0 unless something couples them)."""
    S, Q = [], []
    for z in fits:
        J, a = z["J"], np.linalg.inv(z["J"].T @ z["J"])[:, -2]
        s, q, i = [], [], 0
        for n in z["lengths"]:
            g = (J[i : i + 3 * n] * z["e_q"][i : i + 3 * n, None]).reshape(n, 3, -1).sum(axis=1) @ a
            s.append(g.sum())
            q.append(g @ g)
            i += 3 * n
        S.append(s)
        Q.append(q)
    S, Q = np.array(S), np.array(Q)
    c = np.corrcoef(S.T)[np.triu_indices(S.shape[1], 1)]
    print(
        f"  per dataset (mass): sd over the seas {np.round(S.std(axis=0, ddof=1) * 1000, 2)} g, lag-0 meat "
        f"{np.round(np.sqrt(Q.mean(axis=0)) * 1000, 2)} g; correlation over the seas (0-1, 0-2, 1-2) {c.round(2)}; "
        f"sd of the sum {S.sum(axis=1).std(ddof=1) * 1000:.2f} g, of independent ones {np.sqrt(S.var(axis=0, ddof=1).sum()) * 1000:.2f} g"
    )


def _true_disturbance(fits: list[dict], emp: np.ndarray) -> None:
    """With the quiet reference (``repeat --store``): (iii) the sandwich whose meat is the sea's own response in the
    residual at the quiet point, ``e = f(x_q; sea) - f(x_q; quiet)``; the linear map of that response to the load,
    ``-(J^T J)^-1 J^T e``, over the seas; and the Gauss-Newton prediction from ``x_q``, ``x_q - (J^T J)^-1 J^T f(x_q; sea)``
    against the fit's estimate (is the error linear in the residual at the quiet point?)."""
    hac, lin, pred, err = [], [], [], []
    for z in fits:
        J, lengths, lags = z["J"], z["lengths"], z["lags"]
        Ainv = np.linalg.inv(J.T @ J)
        hac.append((Ainv @ _meat_of(J, z["e_q"], lengths, lags) @ Ainv)[-2:, -2:])
        lin.append(-(Ainv @ (J.T @ z["e_q"]))[-2:])
        pred.append((z["x_q"] - Ainv @ (J.T @ z["f_sea_q"]))[-2:])
        err.append(z["x"][-2:])
    c = np.mean(hac, axis=0)
    print(
        f"  true disturbance (iii): rms sd mass {np.sqrt(c[0, 0]) * 1000:.2f} g, height {np.sqrt(c[1, 1]) * 1000:.2f} mm; "
        f"spread / sd {np.sqrt(emp[0, 0] / c[0, 0]):.2f} / {np.sqrt(emp[1, 1] / c[1, 1]):.2f}"
    )
    _dataset_sums(fits)
    lin, pred, err = np.array(lin), np.array(pred), np.array(err)
    sd_lin = lin.std(axis=0, ddof=1)
    print(
        f"  linear map of e over the seas: sd mass {sd_lin[0] * 1000:.2f} g, height {sd_lin[1] * 1000:.2f} mm; "
        f"corr with the estimates {np.corrcoef(lin[:, 0], err[:, 0])[0, 1]:+.3f}"
    )
    print(
        f"  Gauss-Newton from x_q: rms (prediction - estimate) mass {np.sqrt(((pred - err)[:, 0] ** 2).mean()) * 1000:.2f} g, "
        f"height {np.sqrt(((pred - err)[:, 1] ** 2).mean()) * 1000:.2f} mm; quiet point {fits[0]['x_q'][-2]:.4f} kg {fits[0]['x_q'][-1]:.4f} m, "
        f"mean estimate {err[:, 0].mean():.4f} kg {err[:, 1].mean():.4f} m"
    )
