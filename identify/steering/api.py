"""Library entry points of ``shiptrial steering``: start values, the fits of every model and estimator,
the transfer-function parameters with intervals, and the AIC table."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.steering.estimate import Fit, SteeringData, fit
from identify.steering.mappings import canonical_to_nomoto, nomoto_to_canonical
from identify.steering.models import Structure

MODELS = ("nomoto1", "nomoto2", "state-space")
ESTIMATORS = ("oe", "ml")
Z95 = 1.959963984540054


def _rate(data: SteeringData) -> np.ndarray:
    ch = data.channels
    if "r" in ch:
        return data.y[:, ch.index("r")]
    psi = data.y[:, ch.index("psi")]
    return np.gradient(psi, data.t)


def first_order_start(data: SteeringData, L: float, V: float) -> dict[str, float]:
    """K', T', delta_0 of Nomoto's first-order model by least squares on the differenced yaw rate
    (r_{k+1} - r_k) / h_k = -r_k / T + (K/T)(delta_k + delta_0): the output-error fit's start."""
    r = _rate(data)
    h = np.diff(data.t)
    ok = np.isfinite(r[:-1]) & np.isfinite(r[1:])
    X = np.column_stack([r[:-1], data.delta[:-1], np.ones(len(h))])[ok]
    b = ((r[1:] - r[:-1]) / h)[ok]
    a, kb, c = np.linalg.lstsq(X, b, rcond=None)[0]
    T = -1.0 / a if a < 0 else 2.0 * L / V
    K = kb * T
    if not np.isfinite(K) or K == 0:
        K = -V / L
    psi = data.y[:, data.channels.index("psi")] if "psi" in data.channels else np.array([0.0])
    first = lambda x: float(x[np.isfinite(x)][0]) if np.isfinite(x).any() else 0.0  # noqa: E731
    return {
        "K'": K * L / V,
        "T'": float(np.clip(T * V / L, 0.05, 50.0)),
        "delta_0": float(np.clip(c / kb, -0.1, 0.1)) if kb != 0 else 0.0,
        "r_0": first(r),
        "psi_0": first(psi),
    }


def _defaults(st: Structure) -> dict[str, float]:
    return {q.name: 0.0 for q in st.params}


def start_values(st: Structure, data: SteeringData, nomoto1: dict[str, float]) -> dict[str, float]:
    """Start values of ``st`` from a first-order model's K', T', delta_0, r_0, psi_0 (T1' + T2' - T3' = T')."""
    p = _defaults(st)
    p.update({k: v for k, v in nomoto1.items() if k in p})
    if st.name == "nomoto2":
        T = abs(nomoto1["T'"])
        ph = nomoto_to_canonical(nomoto1["K'"], 1.35 * T, 0.25 * T, 0.6 * T)
        p.update(zip(("phi_1", "phi_2", "phi_4", "phi_5"), ph))
    elif st.name == "state-space":
        from identify.steering.mappings import SSPA_DERIVATIVES

        p.update({k: SSPA_DERIVATIVES[k] for k in ("Yv", "Yr", "Nv", "Nr", "Yd", "Nd")})
    return p


def fit_model(data: SteeringData, L: float, V: float, model: str, estimator: str, start: dict[str, float] | None = None) -> Fit:
    """One model by one estimator. Without ``start``: the first-order least-squares start, refined by output
    error of Nomoto's first-order model, then of ``model``; maximum likelihood starts from that output-error fit
    and from three process-noise levels, and keeps the best likelihood."""
    st = Structure(model, L, V, tuple(c for c in data.channels if model == "state-space" or c != "v"))
    d = data if st.channels == data.channels else _select(data, st.channels)
    if start is None:
        s1 = first_order_start(d, L, V)
        st1 = Structure("nomoto1", L, V, st.channels if "v" not in st.channels else tuple(c for c in st.channels if c != "v"))
        d1 = d if st1.channels == d.channels else _select(d, st1.channels)
        oe1 = fit(st1, d1, start_values(st1, d1, s1), "oe")
        s1.update({k: oe1.p[k] for k in ("K'", "T'", "delta_0", "r_0", "psi_0")} if oe1.converged else {})
        start = start_values(st, d, s1)
        if model != "nomoto1" or estimator == "ml":
            oe = fit(st, d, start, "oe") if model != "nomoto1" else oe1
            if oe.converged:
                start = {**start, **{k: oe.p[k] for k in oe.free}}
    if estimator == "oe":
        return fit(st, d, start, "oe")
    best = None
    for lq in (-4.0, 0.0, 4.0):
        s = dict(start)
        s.update({q.name: lq for q in st.params if q.name.startswith("ln_q")})
        f = fit(st, d, s, "ml")
        if best is None or (f.converged and (not best.converged or f.neg_log_lik < best.neg_log_lik)):
            best = f
    return best


def _select(data: SteeringData, channels: tuple[str, ...]) -> SteeringData:
    cols = [data.channels.index(c) for c in channels]
    return SteeringData(data.t, data.delta, data.y[:, cols], channels, data.source)


@dataclass
class Estimate:
    """One transfer-function parameter with its standard error and 95 % interval (delta method)."""

    name: str
    value: float
    std: float

    @property
    def interval(self) -> tuple[float, float]:
        return self.value - Z95 * self.std, self.value + Z95 * self.std

    def covers(self, truth: float) -> bool:
        lo, hi = self.interval
        return bool(lo <= truth <= hi)


def nomoto_parameters(f: Fit) -> dict[str, Estimate]:
    """K', T' (first order) or K', T1', T2', T3' (second order, from phi_1, phi_2, phi_4, phi_5 by (4.2)-(4.3),
    standard errors by the delta method); state-space fits give the mappings of (3.6)-(3.8)."""
    if f.structure.name == "nomoto1":
        return {k: Estimate(k, f.p[k], f.std.get(k, float("nan"))) for k in ("K'", "T'")}
    if f.structure.name == "nomoto2":
        names = ("phi_1", "phi_2", "phi_4", "phi_5")

        def g(x):
            nm = canonical_to_nomoto(*x)
            return np.array([nm.K, nm.T1, nm.T2, nm.T3])
    else:
        from identify.steering.mappings import derivatives_to_nomoto

        names = ("Yv", "Yr", "Nv", "Nr", "Yd", "Nd")

        def g(x):
            nm = derivatives_to_nomoto({**f.structure.accel, **dict(zip(names, x))})
            return np.array([nm.K, nm.T1, nm.T2, nm.T3])

    x = np.array([f.p[k] for k in names])
    idx = [f.free.index(k) for k in names]
    cov = f.cov[np.ix_(idx, idx)]
    g0 = g(x)
    J = np.zeros((4, len(x)))
    for i in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[i])) if f.structure.name == "nomoto2" else 1e-8
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        J[:, i] = (g(xp) - g(xm)) / (2 * h)
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    std = np.where(var > 0, np.sqrt(np.abs(var)), np.nan)
    return {k: Estimate(k, float(v), float(s)) for k, v, s in zip(("K'", "T1'", "T2'", "T3'"), g0, std)}
