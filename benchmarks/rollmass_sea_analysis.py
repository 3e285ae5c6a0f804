"""Stop 51's analysis of ``bench_rollmass_coverage.py repeat --store`` (one ship fitted on many seas): the load's spread
over the seas against the sandwich from the fitted residual, the leverage-corrected one the fit reports
(:func:`identify.rollmass.sandwich.load_cov`) and the one from the sea's own response at the quiet fit's point
(docs/mass-accuracy.md, stop 51). Run through ``bench_rollmass_coverage.py sea_analyse DIR[,DIR...]``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from identify.rollmass import sandwich as sw


def leveraged(z: dict, C: np.ndarray) -> np.ndarray:
    """``C`` (the load's 2x2) with the fit's stored leverage factors (:func:`sandwich.load_cov`'s scaling)."""
    s = sw.leverage_scale(z["rho"])
    return C * np.outer(s, s)


def _sea_fits(dirs: str) -> list[dict]:
    """The fits ``repeat --store`` kept (one ``.npz`` per converged sea) in the comma-separated ``dirs`` (the same
    ship on several ``--sea-seed``)."""
    fits = []
    for d in dirs.split(","):
        found = sorted(Path(d).glob("sea*.npz"))
        if not found:
            raise SystemExit(f"{d}: no sea*.npz (not a `repeat --store` directory); give the directory `repeat --store` wrote")
        fits += [dict(np.load(p)) for p in found]
    return fits


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
    covs["fitted, leverage"] = [leveraged({"rho": r}, c) for r, c in zip(rho, covs["fitted (i)"])]
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


def _influence(J: np.ndarray, r: np.ndarray, lengths, a: np.ndarray) -> list[np.ndarray]:
    """Each dataset's per-sample influence ``g_t = sum_channels (J_t a)_c r_tc`` of a residual ``r`` on one load
    parameter (``a`` its column of ``(J^T J)^-1``): ``g.sum()`` is :func:`score_sums`'s share."""
    out, i = [], 0
    for n in lengths:
        out.append((J[i : i + 3 * n] @ a * r[i : i + 3 * n]).reshape(n, 3).sum(axis=1))
        i += 3 * n
    return out


def dataset_split(fits: list[dict]) -> dict[str, np.ndarray]:
    """Stop 60's per-dataset split of the mass over one ``repeat --store`` configuration (``--vary``): each dataset's
    share of the linear map from the sea's own response ``e_q`` to the mass, ``s_d = a^T J_d^T e_d``, through each
    sea's own map (``J`` and ``a`` at its fit's end, its whitener and weights in ``e_q``: ``own``) and through one
    fixed map (the first sea's ``J`` and ``a``; only the whitener and weights in ``e_q`` still the sea's: ``fixed``),
    and each dataset's Newey-West meat of the mass (the fit's window, no leverage factor) from the fitted residual
    (``meat_f``, the reported sandwich's share) and from ``e_q`` (``meat_e``; at 4 times the window ``meat_e4``, over the whole record at weight 1 ``meat_e_all``): arrays (seas, datasets)."""
    J0 = fits[0]["J"]
    a0 = np.linalg.inv(J0.T @ J0)[:, -2]
    out: dict[str, list] = {"own": [], "fixed": [], "meat_f": [], "meat_e": [], "meat_e4": [], "meat_e_all": []}
    for z in fits:
        J, lengths, lags = z["J"], z["lengths"], int(z["lags"])
        a = np.linalg.inv(J.T @ J)[:, -2]
        ge, gf = _influence(J, z["e_q"], lengths, a), _influence(J, z["f"], lengths, a)
        out["own"].append([g.sum() for g in ge])
        out["fixed"].append(score_sums(J0, z["e_q"], lengths, a0))
        out["meat_e"].append([sw.bartlett_meat(g[:, None], lags)[0, 0] for g in ge])
        out["meat_f"].append([sw.bartlett_meat(g[:, None], lags)[0, 0] for g in gf])
        out["meat_e4"].append([sw.bartlett_meat(g[:, None], 4 * lags)[0, 0] for g in ge])
        out["meat_e_all"].append([g.sum() ** 2 for g in ge])  # the whole record at weight 1: s_d^2
    return {k: np.array(v) for k, v in out.items()}


def _print_split(fits: list[dict]) -> None:
    """:func:`dataset_split` in g: per dataset the sd over the seas of ``s_d`` (own and fixed map) against the root
    mean meats, the datasets' correlations over the seas, and the sd of the sum against independent datasets'."""
    d = dataset_split(fits)
    for name in ("own", "fixed"):
        X = d[name]
        c = np.corrcoef(X.T)[np.triu_indices(X.shape[1], 1)]
        print(
            f"  split ({name} map): sd of s_d over the seas {np.round(X.std(axis=0, ddof=1) * 1e3, 2)} g, mean "
            f"{np.round(X.mean(axis=0) * 1e3, 2)} g; corr (0-1, 0-2, 1-2) {c.round(2)}; sd of the sum "
            f"{X.sum(axis=1).std(ddof=1) * 1e3:.2f} g, of independent ones {np.sqrt(X.var(axis=0, ddof=1).sum()) * 1e3:.2f} g"
        )
    print(
        f"  split meats (NW, the fit's window): fitted residual {np.round(np.sqrt(d['meat_f'].mean(axis=0)) * 1e3, 2)} g "
        f"(sum {np.sqrt(d['meat_f'].sum(axis=1).mean()) * 1e3:.2f}), true response e {np.round(np.sqrt(d['meat_e'].mean(axis=0)) * 1e3, 2)} g "
        f"(sum {np.sqrt(d['meat_e'].sum(axis=1).mean()) * 1e3:.2f}), e at 4x the window {np.round(np.sqrt(d['meat_e4'].mean(axis=0)) * 1e3, 2)} g, "
        f"e over the whole record {np.round(np.sqrt(d['meat_e_all'].mean(axis=0)) * 1e3, 2)} g"
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
    _print_split(fits)
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


def vary_analyse(a: argparse.Namespace) -> None:
    """Stop 60: ``repeat --store PREFIX_ROLE --vary ROLE`` for the three roles and ``--vary all`` (one ship, one sea
    seed, the held sea realization 0's). Realization ``k`` of ``--vary all`` draws each dataset's sea as realization
    ``k`` of its one-role configuration does, so if the estimate's error were a sum of each dataset's part, the all-sea
    estimate would be ``sum_roles x_role,k - 2 x_0`` (``x_0`` the held sea's fit, the same in all four). Prints the
    one-role spreads and their root sum of squares against the all-sea spread, the all-sea estimates against that
    additive prediction, and per role its share ``s_d`` (:func:`dataset_split`, own map) in the all-sea fits against the
    one-role fits (the same sea of that dataset: what the other datasets' seas do to its map)."""
    roles = ("nominal", "calibration", "loaded")
    fits = {v: _sea_fits(f"{a.prefix}_{v}") for v in roles + ("all",)}
    x = {v: np.array([[float(z["m"]), float(z["z"])] for z in fs]) for v, fs in fits.items()}
    if len({len(v) for v in x.values()}) != 1 or any(not np.array_equal(x[v][0], x["all"][0]) for v in roles):
        raise SystemExit(f"{a.prefix}_*: the four configurations must hold the same seas with realization 0 held in each")
    single = np.array([x[v].std(axis=0, ddof=1) for v in roles])
    pred = sum(x[v] for v in roles) - 2 * x["all"][0]
    d = x["all"] - pred
    print(
        f"{a.prefix}: {len(d)} seas; spread (mass g, height mm) one role's sea "
        + ", ".join(f"{v} {np.round(s * 1e3, 2)}" for v, s in zip(roles, single))
    )
    print(
        f"  all seas {np.round(x['all'].std(axis=0, ddof=1) * 1e3, 2)}, root sum of the one-role variances "
        f"{np.round(np.sqrt((single**2).sum(axis=0)) * 1e3, 2)}, of the additive prediction {np.round(pred.std(axis=0, ddof=1) * 1e3, 2)}"
    )
    slope = [np.polyfit(pred[:, j], x["all"][:, j], 1)[0] for j in range(2)]
    print(
        f"  all seas minus the additive prediction: mean {np.round(d[1:].mean(axis=0) * 1e3, 2)}, rms {np.round(np.sqrt((d[1:] ** 2).mean(axis=0)) * 1e3, 2)} "
        f"(the {len(d) - 1} fresh seas); corr with the prediction {np.round([np.corrcoef(pred[:, j], x['all'][:, j])[0, 1] for j in range(2)], 3)}, slope {np.round(slope, 2)}"
    )
    s_all = dataset_split(fits["all"])["own"]
    for i, v in enumerate(roles):
        s_one = dataset_split(fits[v])["own"][:, i]
        print(
            f"  {v}'s s_d (mass): sd {s_all[:, i].std(ddof=1) * 1e3:.2f} g with every sea fresh, {s_one.std(ddof=1) * 1e3:.2f} g with its own alone; "
            f"corr {np.corrcoef(s_all[:, i], s_one)[0, 1]:+.3f}, rms difference {np.sqrt(((s_all[:, i] - s_one) ** 2).mean()) * 1e3:.2f} g"
        )
