"""The diagnosis pipeline: simulate, locate, name, model and refit, show (issue 6)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from diagnose.candidates import Candidate, build_library, thrust_signal
from diagnose.locate import locate
from diagnose.model import AugmentedModel, Prepared, fit, fit_percent, noise_std, prepare
from diagnose.recording import Recording, RecordingError
from diagnose.search import select
from primitives.ship import DOFS, ShipProfile


@dataclass
class Diagnosis:
    profile: ShipProfile
    theta: np.ndarray  # baseline parameters (profile set, file, or fitted with --fit-on)
    model: AugmentedModel
    P: np.ndarray  # final parameters [theta | augmentations]
    findings: list[dict]
    untestable: list[dict]
    fit_before: dict[str, float]
    fit_after: dict[str, float]
    fit_on: str  # "validation" or "diagnosed"
    location: dict
    baseline_source: str
    sigma: np.ndarray
    preps: list[Prepared]
    val_preps: list[Prepared]
    screened: list[dict] = field(default_factory=list)
    fit_before_diag: dict[str, float] = field(default_factory=dict)
    fit_after_diag: dict[str, float] = field(default_factory=dict)
    elapsed_s: float = 0.0

    @property
    def explained(self) -> bool:
        """No finding and residuals at the noise level: the model explains the data."""
        return not self.findings and max(self.location["rms_over_noise"].values()) < 2.0

    @property
    def unexplained_dofs(self) -> list[str]:
        """DOFs whose final residual is still well above the noise (more than twice)."""
        r = np.concatenate([p.y[1:] - self.model.simulate(p, self.P)[0][1:] for p in self.preps])
        return [dof for i, dof in enumerate(DOFS) if np.sqrt(np.mean(r[:, i] ** 2)) > 2.0 * max(self.sigma[i], 1e-12)]


def _fits(model: AugmentedModel, preps: list[Prepared], P: np.ndarray) -> dict[str, float]:
    y = np.concatenate([p.y for p in preps])
    yh = np.concatenate([model.simulate(p, P)[0] for p in preps])
    return dict(zip(DOFS, fit_percent(y, yh).tolist()))


def _noise_scale(y: np.ndarray) -> np.ndarray:
    """Residual scale per output: the noise where there is noise; quantised real data get a
    floor (2 % of the signal)."""
    return np.maximum(noise_std(y), 0.02 * np.std(y, axis=0))


def fit_baseline(profile: ShipProfile, theta0: np.ndarray, recs: list[Recording]) -> np.ndarray:
    """Output-error fit of every baseline parameter on the --fit-on recordings."""
    preps = [prepare(profile, r, i) for i, r in enumerate(recs)]
    model = AugmentedModel(profile, theta0, [], n_rec=len(preps))
    w = 1.0 / _noise_scale(np.concatenate([r.y for r in recs]))
    P, _cov, _rss = fit(model, preps, model.p0(), list(range(model.n_base)) + model.x0_params(), w, max_iter=30, tol=1e-7)
    return P[: model.n_base]


def describe(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, free: list[int]) -> dict:
    """Physical parameters of a kept candidate (keys fixed by the issue) with standard deviations."""
    idx = model.slot_of[c.key]
    pos = [free.index(j) for j in idx]
    sd = np.sqrt(np.clip(np.diag(cov)[pos], 0, None)) if len(cov) else np.full(len(idx), np.nan)
    vals = P[idx]
    prof = model.profile
    if c.effect == "current":
        cn, ce = vals
        spd = float(np.hypot(cn, ce))
        sub = cov[np.ix_(pos, pos)]
        g_s = np.array([cn, ce]) / max(spd, 1e-12)
        g_d = np.array([-ce, cn]) / max(spd**2, 1e-12)
        return {"speed_mps": spd, "toward_deg": float(np.degrees(np.arctan2(ce, cn)) % 360.0),
                "speed_std": float(np.sqrt(max(g_s @ sub @ g_s, 0))), "toward_std_deg": float(np.degrees(np.sqrt(max(g_d @ sub @ g_d, 0)))),
                "north_mps": float(cn), "east_mps": float(ce)}
    if c.effect == "actuator_delay":
        return {"delay_s": float(vals[0]), "delay_std": float(sd[0]), "samples": float(vals[0] / prof.sample_time)}
    if c.effect == "input_offset":
        name = prof.inputs[c.slots[0].index]
        out = {"input": name, "offset": float(vals[0]), "offset_std": float(sd[0])}
        if name in ("delta",) or name.startswith("alpha"):
            out["offset_deg"] = float(np.degrees(vals[0]))
        return out
    if c.effect == "sensor_bias":
        return {"signal": "uvr"[c.slots[0].index], "bias": float(vals[0]), "bias_std": float(sd[0])}
    if c.effect in ("quadratic_damping", "missing_coupling"):
        return {"term": c.slots[0].term, "value": float(vals[0]), "value_std": float(sd[0]), "dof": DOFS[c.dof]}
    if c.effect == "thrust_loss":
        th = model.theta0
        tsig = thrust_signal(prof)
        base = [k for k, (i, t, *_r) in enumerate(model.base) if i == 0 and t in (tsig, f"{tsig}^2", f"{tsig}*|{tsig}|")]
        out = {"coefficient": float(vals[0]), "coefficient_std": float(sd[0]), "term": c.slots[0].term}
        if base and th[base[0]] != 0 and tsig == "tau_x":
            out["thrust_loss_per_mps"] = float(-vals[0] / th[base[0]])
        return out
    if c.effect == "inertia_change":
        s = float(vals[0])
        return {"scale": s, "scale_std": float(sd[0]), "inertia_ratio": float(1.0 / (1.0 + s)) if s > -1 else None, "dof": DOFS[c.dof]}
    return {s.name: float(v) for s, v in zip(c.slots, vals)} | {f"{s.name}_std": float(e) for s, e in zip(c.slots, sd)}


def run(
    recordings: list[Recording],
    profile: ShipProfile,
    *,
    theta: np.ndarray | None = None,
    fit_on: list[Recording] | None = None,
    validate: list[Recording] | None = None,
    max_rounds: int = 5,
) -> Diagnosis:
    """Diagnose ``recordings`` against ``profile`` (parameters ``theta`` or the simulation set)."""
    t0 = time.perf_counter()
    if not recordings:
        raise RecordingError("no recording given: pass at least one CSV or .dat file")
    ts = profile.sample_time
    for r in list(recordings) + list(fit_on or []) + list(validate or []):
        r.inputs_for(profile.inputs)
        if abs(r.sample_time - ts) > 1e-6 * ts:
            raise RecordingError(f"{r.source}: sample time {r.sample_time:g} s differs from the ship's {ts:g} s; "
                                 f"resample the recording or add '# sample_time: {ts:g}'")
    theta0 = profile.params(theta if theta is not None else None)
    source = "profile"
    if fit_on:
        theta0 = fit_baseline(profile, theta0, fit_on)
        source = "fitted on " + ", ".join(r.source for r in fit_on)
    cands, untestable = build_library(profile, recordings)
    preps = [prepare(profile, r, i) for i, r in enumerate(recordings)]
    model = AugmentedModel(profile, theta0, cands, n_rec=len(preps))
    y_all = np.concatenate([r.y for r in recordings])
    sigma = noise_std(y_all)
    scale = _noise_scale(y_all)
    w = 1.0 / scale
    P0 = model.p0()
    res0 = [p.y - model.simulate(p, P0)[0] for p in preps]
    location = locate(profile, preps, res0, theta0, scale)
    result = select(model, preps, w, max_rounds=max_rounds, base_free=list(range(model.n_base)) if fit_on else None)
    findings = []
    for st in result.steps:
        c = st.candidate
        gain = st.dof_gain
        dof = DOFS[c.dof] if c.dof is not None else DOFS[int(np.argmax(gain))]
        params = describe(c, model, result.P, result.cov, result.free)
        findings.append({
            "effect": c.effect, "dof": dof, "key": c.key, "parameters": params,
            "f_statistic": float(st.f_stat), "p_value": float(st.p_value), "delta_bic": float(st.delta_bic),
            "cv_gain": float(st.cv_gain), "rss_drop": float((st.rss_before - st.rss_after) / st.rss_before),
            "rss_drop_per_dof": dict(zip(DOFS, (gain / max(st.rss_before, 1e-300)).tolist())),
            "signature_correlation": float(st.correlation), "description": c.description,
        })
    val_preps = [prepare(profile, r) for r in validate] if validate else []
    fit_on_name = "validation" if val_preps else "diagnosed"
    P0x = P0.copy()
    P0x[model.x0_params()] = result.P[model.x0_params()]  # the initial state is not physics: same in both
    fbd, fad = _fits(model, preps, P0x), _fits(model, preps, result.P)
    fb, fa = (_fits(model, val_preps, P0x), _fits(model, val_preps, result.P)) if val_preps else (dict(fbd), dict(fad))
    for f in findings:
        f["evidence"] = _evidence(f, location, fb, fa, fit_on_name)
    return Diagnosis(profile, theta0, model, result.P, findings, untestable, fb, fa, fit_on_name,
                     location, source, sigma, preps, val_preps, result.screened, fbd, fad, time.perf_counter() - t0)


SIGNATURE = {"current": ["cos psi", "sin psi"], "wind": ["wind along", "wind across"], "actuator_delay": ["change of"],
             "input_offset": ["sign", ""], "thrust_loss": ["speed u"], "quadratic_damping": ["|v|", "|r|", "v|v|", "r|r|"],
             "missing_coupling": ["|r|", "speed u", "|v|"], "sensor_bias": [""], "inertia_change": ["change of"]}


def _evidence(f: dict, location: dict, fb: dict, fa: dict, where: str) -> str:
    dof = f["dof"]
    conds = location["conditions"].get(dof, [])
    keys = SIGNATURE.get(f["effect"], [])
    hit = next((c for c in conds if any(k and k in c["signal"] for k in keys)), None)
    parts = []
    if hit:
        parts.append(f"the {dof} residual follows {hit['signal']} (correlation {hit['correlation']:+.2f})")
    parts.append(f"adding it explains {100 * f['rss_drop']:.0f} % of the weighted residual (F = {f['f_statistic']:.1f}, "
                 f"p = {f['p_value']:.2g}) and lowers the held-out residual by {100 * f['cv_gain']:.0f} %")
    parts.append(f"{dof} fit on the {where} run(s) {fb[dof]:.0f} % -> {fa[dof]:.0f} %")
    return "; ".join(parts)
