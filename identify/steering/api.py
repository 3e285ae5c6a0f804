"""Library entry points of ``shiptrial steering``: start values, the fits of every model and estimator,
the transfer-function parameters with intervals, and the AIC table."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from identify.steering.estimate import Fit, SteeringData, fit
from identify.steering.mappings import canonical_to_nomoto, nomoto_to_canonical
from identify.steering.models import Structure
from identify.steering.recording import read_records
from primitives.errors import UserError
from primitives.ship import ShipProfile, load_profile

MODELS = ("nomoto1", "nomoto2", "state-space")
ESTIMATORS = ("oe", "ml")
Z95 = 1.959963984540054


def yaw_rate(data: SteeringData) -> np.ndarray:
    """The record's yaw rate [rad/s]: measured r, else the time derivative of the heading."""
    ch = data.channels
    if "r" in ch:
        return data.y[:, ch.index("r")]
    psi = data.y[:, ch.index("psi")]
    return np.gradient(psi, data.t)


def first_reading(x: np.ndarray) -> float:
    """The first finite value of ``x`` (0 when there is none): an initial-state start value."""
    ok = np.isfinite(x)
    return float(x[ok][0]) if ok.any() else 0.0


def first_order_start(records: list[SteeringData], L: float, V: float) -> dict[str, float]:
    """K', T', delta_0 of Nomoto's first-order model by least squares on the differenced yaw rate of every
    record, (r_{k+1} - r_k) / h_k = -r_k / T + (K/T)(delta_k + delta_0), and each record's first yaw rate and
    heading (``r_0@i``, ``psi_0@i``): the output-error fit's start."""
    X, b = [], []
    for d in records:
        r = yaw_rate(d)
        h = np.diff(d.t)
        ok = np.isfinite(r[:-1]) & np.isfinite(r[1:])
        X.append(np.column_stack([r[:-1], d.delta[:-1], np.ones(len(h))])[ok])
        b.append(((r[1:] - r[:-1]) / h)[ok])
    a, kb, c = np.linalg.lstsq(np.concatenate(X), np.concatenate(b), rcond=None)[0]
    T = -1.0 / a if a < 0 else 2.0 * L / V
    K = kb * T if np.isfinite(kb * T) and kb != 0 else -V / L
    out = {
        "K'": K * L / V,
        "T'": float(np.clip(T * V / L, 0.05, 50.0)),
        "delta_0": float(np.clip(c / kb, -0.1, 0.1)) if kb else 0.0,
    }
    for i, d in enumerate(records):
        sfx = f"@{i}" if len(records) > 1 else ""
        out["r_0" + sfx] = first_reading(yaw_rate(d))
        out["psi_0" + sfx] = first_reading(d.y[:, d.channels.index("psi")]) if "psi" in d.channels else 0.0
        if sfx:
            out["delta_0" + sfx] = out["delta_0"]
    return out


def start_values(st: Structure, nomoto1: dict[str, float]) -> dict[str, float]:
    """Start values of ``st`` from a first-order model's K', T', biases and initial states (T1' + T2' - T3' = T')."""
    p = {q.name: 0.0 for q in st.params}
    p.update(nomoto1)
    if st.name != "nomoto1":
        p.pop("K'", None)
        p.pop("T'", None)
    if st.name == "nomoto2":
        T = abs(nomoto1["T'"])
        ph = nomoto_to_canonical(nomoto1["K'"], 1.35 * T, 0.25 * T, 0.6 * T)
        p.update(zip(("phi_1", "phi_2", "phi_4", "phi_5"), ph))
    elif st.name == "state-space":
        from identify.steering.mappings import SSPA_DERIVATIVES

        p.update({k: SSPA_DERIVATIVES[k] for k in ("Yv", "Yr", "Nv", "Nr", "Yd", "Nd")})
    return p


def _select(data: SteeringData, channels: tuple[str, ...]) -> SteeringData:
    if data.channels == channels:
        return data
    cols = [data.channels.index(c) for c in channels]
    return SteeringData(data.t, data.delta, data.y[:, cols], channels, data.source)


def _starts(st: Structure, records: list[SteeringData], L: float, V: float) -> list[dict[str, float]]:
    """Start values: the first-order least-squares start refined by output error of Nomoto's first-order model,
    mapped to ``st`` (T1' + T2' - T3' = T'), and that start refined by output error of ``st`` itself."""
    s1 = first_order_start(records, L, V)
    ch1 = tuple(c for c in st.channels if c != "v")
    st1 = Structure("nomoto1", L, V, ch1)
    oe1 = fit(st1, [_select(d, ch1) for d in records], start_values(st1, s1), "oe")
    # a first-order fit whose lag went to zero (the delay T_D taking its place when the record is sampled as slowly
    # as the ship's time constant) maps to second-order time constants of zero and a start no fit recovers from
    if oe1.converged and 0.05 <= oe1.p["T'"] <= 50.0:
        s1.update({k: v for k, v in oe1.p.items() if k.split("@")[0] in ("K'", "T'", "delta_0", "r_0", "psi_0", "T_D")})
    start = start_values(st, s1)
    if st.name == "nomoto1":
        return [start]
    oe = fit(st, records, start, "oe")
    return [start] + ([{**start, **{k: oe.p[k] for k in oe.free}}] if oe.converged else [])


def _better(f: Fit, best: Fit | None) -> bool:
    if best is None:
        return True
    return bool(f.converged and np.isfinite(f.neg_log_lik) and (not best.converged or not f.neg_log_lik >= best.neg_log_lik))


def fit_model(
    data: SteeringData | list[SteeringData],
    L: float,
    V: float,
    model: str,
    estimator: str,
    start: dict[str, float] | None = None,
    accel: dict[str, float] | None = None,
    wind: bool = False,
    log_x: float = 0.0,
    noise_corr: bool = False,
) -> Fit:
    """One model by one estimator on one record or several pooled (dynamics shared, biases and initial state per
    record). Without ``start``: from each start of :func:`_starts` (maximum likelihood: at two process-noise
    levels each), the best likelihood among the converged fits. ``accel``: the state-space model's theta_1..theta_4
    (``th1``..``th4``; default Källström's Table 3.1). ``wind``: estimate the heading-dependent wind (nomoto2,
    state-space); ``log_x``: the sway log's distance forward of midship [m]; ``noise_corr``: estimate the correlation
    of the two rate equations' process noise, R1(1,2) (nomoto2, state-space; see :class:`Structure`)."""
    records = [data] if isinstance(data, SteeringData) else list(data)
    if any("psi" not in d.channels for d in records):
        # without heading the initial heading is a free parameter nothing measures, and the rudder offset
        # and the rate gyro's bias are the same input to r: the information matrix is singular
        raise ValueError("a steering fit needs the heading psi in every record (the yaw rate alone leaves it undetermined)")
    channels = fitted_channels(records[0].channels, model)
    records = [_select(d, channels) for d in records]
    st = Structure(model, L, V, channels, **({"accel": accel} if accel else {}), wind=wind, log_x=log_x, noise_corr=noise_corr)
    starts = [start] if start is not None else _starts(st, records, L, V)
    best = None
    for s0 in starts:
        for lq in (-3.0, 3.0) if estimator == "ml" else (0.0,):
            s = dict(s0)
            s.update({q.name: lq for q in st.params if q.name.startswith("ln_q")})
            f = fit(st, records, s, estimator)
            best = f if _better(f, best) else best
    return best


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


def fitted_channels(channels: tuple[str, ...], model: str) -> tuple[str, ...]:
    """The measured channels a model is fitted to: the Nomoto forms have no sway, so ``v`` is left out."""
    return tuple(c for c in channels if model == "state-space" or c != "v")


@dataclass
class ModelResult:
    """One model by one estimator on the pooled records (fitted to ``channels``), or the reason it failed."""

    model: str
    estimator: str
    fit: Fit | None
    failure: str = ""
    channels: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.fit is not None and self.fit.ok and not self.failure


@dataclass
class SteeringResult:
    """What ``shiptrial steering`` reports: every model/estimator on the pooled records (the AIC table), the
    chosen one's parameters with intervals, per-record fits when there are several, residual tests, warnings."""

    ship: str
    L: float
    V: float
    speed_source: str
    starboard_sign: float
    sources: list[str]
    model: str
    estimator: str
    results: list[ModelResult]
    per_run: list[ModelResult]
    warnings: list[str]
    notes: list[str]
    split: tuple[float, float] | None = None
    part_fits: dict | None = None  # (part, estimator) -> Fit
    cross_rows: list | None = None  # identify.steering.crossval.CrossRow

    @property
    def main(self) -> ModelResult:
        return next(r for r in self.results if r.model == self.model and r.estimator == self.estimator)


def _try_fit(records, L, V, model, estimator, wind: bool = False, log_x: float = 0.0, noise_corr: bool = False) -> ModelResult:
    ch = fitted_channels(records[0].channels, model)
    two = model != "nomoto1"  # the wind and the noise correlation are terms of the second-order models only
    try:
        f = fit_model(records, L, V, model, estimator, wind=wind and two, log_x=log_x, noise_corr=noise_corr and two)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
        return ModelResult(model, estimator, None, f"{type(exc).__name__}: {exc}", ch)
    if not f.converged:
        return ModelResult(model, estimator, f, f"did not converge ({f.message})", ch)
    if not f.ok:
        names = ", ".join(f.undetermined) or "the information matrix is singular"
        return ModelResult(model, estimator, f, f"parameters not determined by these records ({names})", ch)
    if not all(np.isfinite(e.value) for e in nomoto_parameters(f).values()):
        return ModelResult(model, estimator, f, "complex time constants (an oscillatory yaw mode): no Nomoto form", ch)
    return ModelResult(model, estimator, f, channels=ch)


def fastest_time_constant_s(r: ModelResult) -> float | None:
    """The smallest positive time constant of a fit, in seconds (None without one)."""
    if not r.ok:
        return None
    st = r.fit.structure
    Ts = [e.value * st.L / st.V for k, e in nomoto_parameters(r.fit).items() if k.startswith("T") and k != "T3'"]
    Ts = [T for T in Ts if np.isfinite(T) and T > 0]
    return min(Ts) if Ts else None


# Measured on the simulated Sea Splendour (tests/physics/sea_splendour.py, T2 = 14.4 s; `python
# benchmarks/bench_steering.py --seeds 50 --parts sea --sample-times 20,25`): the ratio of the sampling interval to
# the fastest *identified* time constant (slow sampling biases that estimate upward: median fitted T2 15.7 s at 15 s,
# 19.4 s at 20 s, 20.6 s at 25 s, 20.8 s at 30 s) above which the second-order intervals were found too narrow.
COARSE_RATIO = 0.5  # the rule (Källström's experiment 1): slower than half the fastest time constant
POOR_RATIO = 1.1  # 25 and 30 s sampling (fitted ratio about 1.2 and 1.45): T2' held the truth in 84 %


def sampling_warning(records: list[SteeringData], r: ModelResult) -> str | None:
    """Källström's experiment 1 (T = 30 s against T2 of about 14 s): a record sampled slower than half the fastest
    identified time constant is warned, with what such sampling did to the intervals on the simulated Sea Splendour
    (50 noise seeds): usable up to about one time constant, the fast mode poorly resolved beyond."""
    Tf = fastest_time_constant_s(r)
    h = max(float(np.median(np.diff(d.t))) for d in records)
    if Tf is None or h <= COARSE_RATIO * Tf:
        return None
    head = (
        f"sampled every {h:g} s, {h / Tf:.2g} times the fastest identified time constant ({Tf:.3g} s of the {r.model} "
        f"{r.estimator} model)"
    )
    if h <= POOR_RATIO * Tf:
        return (
            f"{head}: coarse. On a simulated tanker read at about this ratio (Källström's Sea Splendour, 15-20 s "
            "against T2 = 14.4 s, 50 noise seeds) the 95 % intervals of K', T1', T2', T3' held the truth in 92-96 % "
            f"of records; sampling every {0.5 * Tf:.2g} s or faster narrows them"
        )
    return (
        f"{head}: the fast mode is poorly resolved (and slow sampling lengthens its estimate). On the simulated Sea "
        "Splendour read every 25-30 s (1.7-2.1 times its T2 of 14.4 s, 50 noise seeds) the 95 % intervals of T2' "
        "(and T3' at 30 s) held the truth in only 84-86 % of records and those of T1', T3' were 6-10 times as wide as "
        "at 15 s: "
        f"do not rely on the second-order intervals; sample every {0.5 * Tf:.2g} s or faster"
    )


NOT_MODELLED = (
    "not modelled unless asked for: heading-dependent wind (Källström's theta_9, theta_10, phi_3) only with --wind "
    "(then refitted with the biases and initial state in the --split cross-validation); correlated process noise "
    "(Källström's R1(1,2)) only with --noise-corr; the sway log is taken at midship unless --log-x gives its lever arm"
)


def delay_warning(records: list[SteeringData], r: ModelResult) -> str | None:
    """The rudder delay T_D is bounded by the shortest sampling interval (Källström's T_D = T (1 - |sin theta|));
    a fitted delay at that bound is the bound's value, not the ship's: the true delay may be longer."""
    if r.fit is None or "T_D" not in r.fit.free:
        return None
    h_min = min(float(d.h.min()) for d in records)
    T_D = r.fit.p["T_D"]
    if T_D >= h_min * (1 - 1e-3):
        return (
            f"the rudder delay T_D = {T_D:.3g} s of the {r.model} {r.estimator} model sits at its upper bound, the shortest "
            f"sampling interval ({h_min:g} s): the delay may be longer than the model can express (the rest is absorbed "
            "by the other parameters), and it has no interval; sample faster to resolve it"
        )
    return None


def identify_records(
    records: list[SteeringData],
    L: float,
    V: float,
    model: str = "nomoto2",
    estimator: str = "ml",
    *,
    ship: str = "",
    speed_source: str = "",
    starboard_sign: float = 0.0,
    notes: list[str] | None = None,
    wind: bool = False,
    log_x: float = 0.0,
    noise_corr: bool = False,
) -> SteeringResult:
    """Every structure (Nomoto 1 and 2, and the state-space model when asked for) by OE and ML on the pooled
    records, the chosen one per record too when there are several; ``wind``, ``log_x`` and ``noise_corr`` as in
    :func:`fit_model` (the wind and the noise correlation for the second-order and state-space models only)."""
    if model not in MODELS:
        raise ValueError(f"model {model!r}: one of {', '.join(MODELS)}")
    models = ("nomoto1", "nomoto2") + (("state-space",) if model == "state-space" else ())
    results = [_try_fit(records, L, V, m, e, wind, log_x, noise_corr) for m in models for e in ESTIMATORS]
    per_run = [_try_fit([d], L, V, model, estimator, wind, log_x, noise_corr) for d in records] if len(records) > 1 else []
    notes = list(notes or []) + [NOT_MODELLED]
    res = SteeringResult(
        ship,
        L,
        V,
        speed_source,
        starboard_sign,
        [d.source for d in records],
        model,
        estimator,
        results,
        per_run,
        [],
        notes,
    )
    if model == "state-space":
        res.notes.append(
            "state-space model: the acceleration derivatives theta_1..theta_4 are held at Källström's Table 3.1 values "
            "(SSPA, a 255 000 tdw tanker); the command has no option for another hull's values: the library takes "
            "them (identify.steering.api.fit_model(..., accel={'th1': ..., 'th4': ...}))"
        )
    res.warnings += [w for w in (sampling_warning(records, res.main), delay_warning(records, res.main)) if w]
    if res.main.ok and starboard_sign:
        K = nomoto_parameters(res.main.fit)["K'"].value
        if np.sign(K) != np.sign(starboard_sign):
            res.warnings.append(
                f"K' = {K:.3g}: a positive delta turns this ship to {'starboard' if K > 0 else 'port'}, but the profile's "
                f"[helm] starboard_sign is {starboard_sign:+g}: check the rudder column's sign"
            )
    return res


def parse_split(text: str) -> tuple[float, float]:
    """``--split S`` (split at S seconds) or ``S1:S2`` (leave the window S1-S2 out, as Källström left out his
    course change 1158-1732 s)."""
    try:
        a, _, b = text.partition(":")
        s1 = float(a)
        s2 = float(b) if b else s1
    except ValueError:
        raise UserError(f"--split {text!r}: give seconds, S or S1:S2 (e.g. 1158:1732)") from None
    if not (np.isfinite(s1) and np.isfinite(s2) and 0 <= s1 <= s2):
        raise UserError(f"--split {text!r}: need 0 <= S1 <= S2, finite seconds")
    return s1, s2


def split_parts(records: list[SteeringData], split: tuple[float, float]) -> tuple[SteeringData, SteeringData]:
    """The two parts of the one record, each with at least 10 readings."""
    from identify.steering.crossval import split_indices, split_record

    if len(records) != 1:
        raise UserError("--split needs exactly one recording (it splits one record at a course change)")
    t = records[0].t
    i1, i2 = split_indices(t, *split)
    sizes = (i1, len(t) - i2)
    for i, n in enumerate(sizes):
        if n < 10:
            raise UserError(
                f"--split {split[0]:g}:{split[1]:g}: part {i + 1} has {n} readings; "
                f"the record runs {t[0]:g}-{t[-1]:g} s, split inside it"
            )
    return split_record(records[0], *split)


def add_cross_validation(
    res: SteeringResult, records: list[SteeringData], split: tuple[float, float], wind: bool = False
) -> None:
    """Identify each part of the (single) record and cross-validate (Källström's Tables 3.5-3.8); ``wind``: with the
    heading-dependent wind in the parts' models (second order), refitted on the other part with the nuisance."""
    from identify.steering.crossval import cross_validate

    p1, p2 = split_parts(records, split)
    res.split = split
    model = res.model if res.model != "state-space" else "nomoto2"
    res.part_fits, res.cross_rows = cross_validate((p1, p2), res.L, res.V, model, wind and model != "nomoto1")


def identify_files(
    paths: list[str | Path],
    ship: str | ShipProfile,
    model: str = "nomoto2",
    estimator: str = "ml",
    split: str | None = None,
    wind: bool = False,
    log_x: float = 0.0,
    noise_corr: bool = False,
) -> SteeringResult:
    """Read the recordings, take L from the profile and V from the recorded forward speed (the profile's cruise
    speed when no recording has ``u``), and identify (``wind``, ``log_x``, ``noise_corr``: :func:`fit_model`)."""
    profile = ship if isinstance(ship, ShipProfile) else load_profile(ship)
    records, speeds, notes = [], [], []
    for p in paths:
        recs, u, n = read_records(p)
        records += recs
        speeds += [u] if u is not None else []
        notes += [f"{Path(p).name}: {x}" for x in n]
    chans = {d.channels for d in records}
    if len(chans) > 1:
        raise UserError(
            f"the recordings measure different channels ({' / '.join(','.join(c) for c in chans)}); give records with the same columns"
        )
    if not (np.isfinite(log_x) and abs(log_x) <= 0.5 * float(profile.length_m)):
        raise UserError(
            f"--log-x {log_x:g}: the sway log's distance forward of midship in metres, within half the ship's length "
            f"({0.5 * float(profile.length_m):g} m for {profile.name!r}); negative aft"
        )
    if model == "state-space" and "v" not in records[0].channels:
        raise UserError(
            f"--model state-space needs the sway velocity: add column 'v' [m/s] to {paths[0]}, or use nomoto1/nomoto2"
        )
    if speeds:
        V, src = float(np.mean(speeds)), "mean recorded forward speed u"
    else:
        V, src = float(profile.cruise_speed_mps), "the profile's cruise speed (no 'u' column)"
    cut = parse_split(split) if split is not None else None
    if cut is not None:
        split_parts(records, cut)  # refused before any fit
    res = identify_records(
        records,
        float(profile.length_m),
        V,
        model,
        estimator,
        ship=profile.name,
        speed_source=src,
        starboard_sign=float(profile.helm.starboard_sign) if profile.actuator == "rudder_propeller" else 0.0,
        notes=notes,
        wind=wind,
        log_x=log_x,
        noise_corr=noise_corr,
    )
    if cut is not None:
        add_cross_validation(res, records, cut, wind)
    return res
