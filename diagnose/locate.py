"""Locate a mismatch: which DOF, when (CUSUM, the podded-ship MSc thesis (5.1)) and under which conditions.

Conditions are correlations of the open-loop residual with signals that betray a physical
cause: heading (an earth-fixed current or wind rotates with psi), input sign and size
(offsets, asymmetry), lagged input changes (delay), speed (thrust loss), |v| and |r|
(nonlinear damping) and measured wind. Residual whiteness (Ljung-Box) and input
cross-correlation tests of the one-step prediction errors follow Källström (1977).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from diagnose.model import Prepared
from primitives.regressors import predictor_regressors
from primitives.ship import DOFS, ShipProfile


def cusum(eps: np.ndarray, d: float, l: float) -> np.ndarray:
    """Dead-zone CUSUM (5.1): g = max(0, g + s), s = |eps| - d if |eps| >= d else -l."""
    s = np.where(np.abs(eps) >= d, np.abs(eps) - d, -l)
    g = np.empty(len(eps))
    acc = 0.0
    for k, sk in enumerate(s):
        acc = max(0.0, acc + sk)
        g[k] = acc
    return g


def alarm_windows(g: np.ndarray, h: float) -> list[tuple[int, int]]:
    """Sample windows (start of the rise, end of the excursion) where g crossed h."""
    out = []
    k, n = 0, len(g)
    while k < n:
        if g[k] > h:
            s = k
            while s > 0 and g[s - 1] > 0:
                s -= 1
            e = k
            while e < n - 1 and g[e + 1] > 0:
                e += 1
            out.append((s, e))
            k = e + 1
        else:
            k += 1
    return out


def ljung_box(x: np.ndarray, lags: int = 20) -> tuple[float, float]:
    """Q = N(N+2) sum rho_k^2 / (N-k), chi^2(lags) p-value."""
    x = x - x.mean()
    n = len(x)
    den = float(x @ x) or 1.0
    rho = np.array([x[:-k] @ x[k:] / den for k in range(1, lags + 1)])
    q = n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1)))
    return float(q), float(stats.chi2.sf(q, lags))


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if np.std(a) < 1e-12 or np.std(b) < 1e-12:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def locate(profile: ShipProfile, preps: list[Prepared], res: list[np.ndarray], theta: np.ndarray, sigma: np.ndarray) -> dict:
    """Where, when and under which conditions the baseline misfits. ``res``: (N+1, 3) per recording."""
    r_all = np.concatenate([r[1:] for r in res])
    rms = np.sqrt(np.mean(r_all**2, axis=0))
    ratio = rms / sigma
    worst = int(np.argmax(ratio))
    windows = []
    for p, r in zip(preps, res):
        for i in range(3):
            g = cusum(r[:, i], 1.5 * sigma[i], 0.2 * sigma[i])
            for s, e in alarm_windows(g, 10 * sigma[i]):
                seg = None
                if p.rec.segments is not None:
                    seg = list(dict.fromkeys(p.rec.segments[s : e + 1])) or None
                t0 = float(p.rec.t[0])  # times from the run's start: a logger's epoch stamps mean nothing to a reader
                windows.append(
                    {
                        "recording": p.rec.source,
                        "dof": DOFS[i],
                        "t_start": float(p.rec.t[s]) - t0,
                        "t_end": float(p.rec.t[e]) - t0,
                        "run_start_stamp": t0,
                        "peak_cusum": float(g[s : e + 1].max() / sigma[i]),
                        "segment": seg,
                    }
                )
    windows.sort(key=lambda w: -w["peak_cusum"])
    # misfit per manoeuvre segment (when the recording labels them)
    seg_sq: dict[str, list] = {}
    for p, r in zip(preps, res):
        if p.rec.segments is None:
            continue
        for k, lab in enumerate(p.rec.segments[1:], start=1):
            seg_sq.setdefault(str(lab), []).append(r[k] ** 2)
    segments = sorted(
        (
            {"segment": k, **{DOFS[i]: float(np.sqrt(np.mean(np.array(v)[:, i])) / sigma[i]) for i in range(3)}}
            for k, v in seg_sq.items()
        ),
        key=lambda s: -max(s[d] for d in DOFS),
    )
    # conditions
    sig: dict[str, list[np.ndarray]] = {}

    def add(name: str, arr: np.ndarray) -> None:
        sig.setdefault(name, []).append(np.asarray(arr, float)[:-1])

    for p in preps:
        add("cos psi", np.cos(p.psi))
        add("sin psi", np.sin(p.psi))
        add("speed u", p.y[:, 0])
        add("|v|", np.abs(p.y[:, 1]))
        add("|r|", np.abs(p.y[:, 2]))
        add("v|v|", p.y[:, 1] * np.abs(p.y[:, 1]))
        add("r|r|", p.y[:, 2] * np.abs(p.y[:, 2]))
        for j, nm in enumerate(profile.inputs):
            x = p.inputs[:, j]
            add(f"{nm}", x)
            add(f"sign {nm}", np.sign(x - np.median(x)))
            dx = np.concatenate([[0.0], np.diff(x)])
            add(f"change of {nm} (lag 1-5)", np.convolve(dx, np.ones(5), mode="full")[: len(x)])
        if p.wind_body is not None:
            add("wind along", p.wind_body[0])
            add("wind across", p.wind_body[1])
    sig_cat = {k: np.concatenate(v) for k, v in sig.items() if len(v) == len(preps)}
    conditions = {}
    for i in range(3):
        corr = {k: _corr(r_all[:, i], v) for k, v in sig_cat.items()}
        cs = sorted(((abs(c), k, c) for k, c in corr.items()), reverse=True)
        conditions[DOFS[i]] = [{"signal": k, "correlation": c} for _a, k, c in cs[:4]]
    # one-step prediction errors: whiteness and cross-correlation with inputs (Källström 1977)
    eps_all, x_all = [], []
    for p in preps:
        phi, target = predictor_regressors(profile, p.y, p.inputs[:-1], p.psi, terms=profile.model)
        eps = target - np.stack([phi[:, profile.model.dof_slice(i)] @ theta[profile.model.dof_slice(i)] for i in range(3)], -1)
        eps_all.append(eps)
        x_all.append(p.inputs[:-1])
    eps = np.concatenate(eps_all)
    x = np.concatenate(x_all)
    tests = _tests(eps, x, profile.inputs)
    oe_tests = _tests(r_all, x, profile.inputs)  # the open-loop (output-error) residuals
    band = 2.58 / np.sqrt(len(eps))
    return {
        "rms_over_noise": dict(zip(DOFS, ratio.tolist())),
        "worst_dof": DOFS[worst],
        "cusum_windows": windows[:10],
        "segments": segments,
        "conditions": conditions,
        "one_step_tests": tests,
        "output_error_tests": oe_tests,
        "ccf_band_99": band,
    }


def _tests(eps: np.ndarray, x: np.ndarray, names: tuple[str, ...]) -> dict:
    """Ljung-Box whiteness and input cross-correlation (lags 0-20, 99 % band) per DOF."""
    n = len(eps)
    band = 2.58 / np.sqrt(n)
    out = {}
    for i in range(3):
        q, pv = ljung_box(eps[:, i])
        cc = []
        e = eps[:, i] - eps[:, i].mean()
        for j, nm in enumerate(names):
            xs = x[:, j] - x[:, j].mean()
            den = np.sqrt((xs @ xs) * (e @ e)) or 1.0
            vals = [float(xs[: n - k] @ e[k:] / den) for k in range(0, 21)]
            cc.append(
                {"input": nm, "max_abs_ccf": float(np.max(np.abs(vals))), "lags_outside_band": int(np.sum(np.abs(vals) > band))}
            )
        out[DOFS[i]] = {"ljung_box_q": q, "whiteness_p": pv, "cross_correlation": cc}
    return out
