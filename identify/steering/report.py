"""The report of ``shiptrial steering``: text, JSON document and plots (written atomically by the caller's
output directory)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from identify.steering.api import Z95, ModelResult, SteeringResult, nomoto_parameters
from identify.steering.models import RHO
from identify.steering.residuals import residual_tests

UNITS = {"v": ("m/s", 1.0), "r": ("deg/s", 180 / np.pi), "psi": ("deg", 180 / np.pi)}
LABEL = {"nomoto1": "Nomoto 1st order", "nomoto2": "Nomoto 2nd order", "state-space": "state space [v, r, psi]"}


def _tests(r: ModelResult, max_lag: int) -> list[dict]:
    f = r.fit
    out = []
    for i, d in enumerate(f.records):
        entry = {"record": d.source}
        for kind, e in (("prediction", f.e_pred[i]), ("simulation", f.e_sim[i])):
            tests = residual_tests(e, d.delta, d.channels, max_lag)
            entry[kind] = {c: {k: t.as_dict() for k, t in v.items()} for c, v in tests.items()}
        out.append(entry)
    return out


def _params(r: ModelResult) -> dict:
    return {k: {"value": e.value, "std": e.std, "ci95": list(e.interval)} for k, e in nomoto_parameters(r.fit).items()}


def model_document(r: ModelResult, max_lag: int = 20) -> dict:
    """One fit as JSON: the failure, or parameters with intervals, likelihood, AIC, fit and residual tests."""
    doc = {"model": r.model, "estimator": r.estimator, "ok": r.ok}
    if not r.ok:
        doc["failure"] = r.failure
        return doc
    f = r.fit
    doc.update(
        {
            "nomoto": _params(r),
            "parameters": {k: {"value": f.p[k], "std": f.std[k]} for k in f.free},
            "neg_log_likelihood": f.neg_log_lik,
            "nu": f.nu,
            "aic": f.aic,
            "n_obs": f.n_obs,
            "fit_percent_simulation": dict(zip(f.records[0].channels, np.mean(f.fit_percent(True), axis=0).tolist())),
            "fit_percent_prediction": dict(zip(f.records[0].channels, np.mean(f.fit_percent(False), axis=0).tolist())),
            "residual_tests": _tests(r, max_lag),
        }
    )
    return doc


def document(res: SteeringResult) -> dict:
    """The whole report as a JSON-able dict."""
    return {
        "ship": res.ship,
        "L_m": res.L,
        "V_mps": res.V,
        "V_source": res.speed_source,
        "records": res.sources,
        "model": res.model,
        "estimator": res.estimator,
        "chosen": model_document(res.main),
        "aic_table": [
            {
                "model": r.model,
                "estimator": r.estimator,
                "channels": list(r.channels),
                "ok": r.ok,
                "aic": r.fit.aic if r.ok else None,
                "nu": r.fit.nu if r.ok else None,
                "failure": r.failure or None,
            }
            for r in res.results
        ],
        "per_run": [dict(model_document(r), record=src) for r, src in zip(res.per_run, res.sources)],
        "cross_validation": _cross_document(res),
        "warnings": res.warnings,
        "notes": res.notes,
    }


def _cross_document(res: SteeringResult) -> dict | None:
    if res.split is None:
        return None
    parts = [
        {
            "part": part,
            "estimator": e,
            "ok": f.ok,
            "aic": f.aic,
            "nu": f.nu,
            "n_obs": f.n_obs,
            "nomoto": {k: {"value": x.value, "std": x.std} for k, x in nomoto_parameters(f).items()} if f.ok else None,
        }
        for (part, e), f in res.part_fits.items()
    ]
    rows = [
        {
            "data_part": r.data_part,
            "model_part": r.model_part,
            "estimator": r.estimator,
            "ok": r.fit is not None and r.fit.converged,
            "aic": r.fit.aic if r.fit is not None and r.fit.converged else None,
            "nu": r.fit.nu if r.fit is not None else None,
            "refitted": list(r.fit.free) if r.fit is not None else None,
            "fit_percent_simulation": r.fit.fit_percent(True)[0] if r.fit is not None and r.fit.converged else None,
            "failure": r.failure or None,
        }
        for r in res.cross_rows
    ]
    return {"split_s": list(res.split), "parts": parts, "cross": rows}


def _cross_text(res: SteeringResult) -> list[str]:
    if res.split is None:
        return []
    a, b = res.split
    lines = [f"split at {a:g}" + (f"-{b:g}" if b != a else "") + " s (window left out); each part on its own:"]
    for (part, e), f in res.part_fits.items():
        if f.ok:
            nm = nomoto_parameters(f)
            lines.append(
                f"  part {part} {e.upper():3s} AIC {f.aic:10.1f} nu {f.nu:3d}  "
                + ", ".join(f"{k} {x.value:.3f} +- {1.96 * x.std:.3f}" for k, x in nm.items())
            )
        else:
            lines.append(f"  part {part} {e.upper():3s} FAILED")
    wind = any(q.role == "wind" for f in res.part_fits.values() for q in f.structure.params)
    lines.append(
        f"cross-validation (dynamics and delay held, biases, {'wind ' if wind else ''}and initial state refitted by OE; "
        "lower AIC generalises better):"
    )
    for r in res.cross_rows:
        head = f"  part {r.data_part} data, model from part {r.model_part} {r.estimator.upper():3s}"
        if r.fit is not None and r.fit.converged:
            fp = ", ".join(f"{c} {x:.1f} %" for c, x in zip(r.fit.records[0].channels, r.fit.fit_percent(True)[0]))
            lines.append(f"{head}: AIC {r.fit.aic:10.1f} nu {r.fit.nu:3d}, simulated fit {fp}")
        else:
            lines.append(f"{head}: FAILED ({r.failure})")
    return lines


def _dimensional(r: ModelResult, res: SteeringResult) -> list[str]:
    """The gain and time constants in seconds at the trial speed (K = K' V / L, T = T' L / V), the rudder delay
    and offset: the figures an autopilot is tuned with."""
    est = nomoto_parameters(r.fit)
    tv = res.L / res.V
    K = est["K'"].value / tv
    bits = [f"K = {K:.4g} 1/s"]
    bits += [f"{k[:-1]} = {e.value * tv:.3g} s" for k, e in est.items() if k.startswith("T")]
    extra = f"; rudder delay T_D = {r.fit.p.get('T_D', 0.0):.2f} s"
    return [f"    at V = {res.V:.3g} m/s: " + ", ".join(bits) + extra] + _offset_text(r)


def _offset_text(r: ModelResult) -> list[str]:
    """The fitted rudder offsets delta_0, one per record, each named by its record: the free parameters that
    steering.json's ``parameters`` holds (``delta_0@i`` of record i when pooled, ``delta_0`` for one record), not
    the starting value a pooled fit keeps unused beside them."""
    f = r.fit
    names = [Path(d.source).name for d in f.records]
    bits = []
    for k in f.free:
        base, _, at = k.partition("@")
        if base == "delta_0":
            name = names[int(at)] if at else names[0]
            bits.append(f"{name} {np.degrees(f.p[k]):.2f} deg")
    return [f"    rudder offset delta_0 ({'per record' if len(bits) > 1 else 'the record'}): " + ", ".join(bits)] if bits else []


def _noise_corr_text(r: ModelResult) -> list[str]:
    """The process noise's correlation rho = tanh(atanh_rho_q) (Källström's R1(1,2)) with its 95 % interval, mapped
    through tanh from the parameter's (monotone, so the interval is rho's)."""
    if RHO not in r.fit.free:
        return []
    z, sd = r.fit.p[RHO], r.fit.std[RHO]
    head = f"    process-noise correlation rho {np.tanh(z):.2f}"
    if not np.isfinite(sd):
        return [head + " (at a bound, or a rate's noise negligible: no interval)"]
    return [head + f"  95 % [{np.tanh(z - Z95 * sd):.2f}, {np.tanh(z + Z95 * sd):.2f}] (R1(1,2) / sqrt(R1(1,1) R1(2,2)))"]


def _aic_text(res: SteeringResult) -> list[str]:
    """One AIC table per set of fitted channels: likelihoods of different data (the state-space model also fits
    the sway v) do not compare."""
    lines = []
    pooled = "pooled records" if len(res.sources) > 1 else "one record"
    for ch in dict.fromkeys(r.channels for r in res.results):
        rows = [r for r in res.results if r.channels == ch]
        lines.append(f"AIC on {', '.join(ch)} (lower is better; {pooled}):")
        ok = [r for r in rows if r.ok]
        best = min(ok, key=lambda r: r.fit.aic) if len(ok) > 1 else None
        for r in rows:
            if r.ok:
                lines.append(
                    f"  {LABEL[r.model]:24s} {r.estimator.upper():3s} AIC {r.fit.aic:12.1f}  nu {r.fit.nu:3d}"
                    + ("  <- best" if r is best else "")
                )
            else:
                lines.append(f"  {LABEL[r.model]:24s} {r.estimator.upper():3s} failed: {r.failure}")
    return lines


def _fmt_params(r: ModelResult) -> list[str]:
    return [
        f"    {k:5s} {e.value:9.3f}  95 % [{e.interval[0]:.3f}, {e.interval[1]:.3f}]" for k, e in nomoto_parameters(r.fit).items()
    ]


def text(res: SteeringResult) -> str:
    """The human-readable report."""
    m = res.main
    lines = [
        f"steering dynamics of {res.ship}: L = {res.L:g} m, V = {res.V:.3g} m/s ({res.speed_source}); primed with L/V = {res.L / res.V:.3g} s",
        f"records: {', '.join(Path(s).name for s in res.sources)}",
        f"{LABEL[res.model]}, {'maximum likelihood' if res.estimator == 'ml' else 'output error'} "
        + ("(pooled: dynamics shared, biases and initial state per record)" if len(res.sources) > 1 else ""),
    ]
    if m.ok:
        lines += _fmt_params(m) + _dimensional(m, res) + _noise_corr_text(m)
        side = "starboard" if nomoto_parameters(m.fit)["K'"].value > 0 else "port"
        lines.append(f"    (a positive delta turns the ship to {side})")
        f = m.fit
        for i, d in enumerate(f.records):
            sim, pred = f.fit_percent(True)[i], f.fit_percent(False)[i]
            lines.append(
                f"  fit {Path(d.source).name}: "
                + ", ".join(f"{c} {s:.1f} % simulated / {p:.1f} % predicted" for c, s, p in zip(d.channels, sim, pred))
            )
        for t in _tests(m, 20):
            for kind in ("prediction", "simulation"):
                bits = [
                    f"{c} {'white' if v['whiteness']['passed'] else 'NOT white'}"
                    f" ({v['whiteness']['lags_outside']}/{v['whiteness']['lags']} lags out),"
                    f" {'uncorrelated' if v['rudder']['passed'] else 'CORRELATED'} with rudder"
                    f" ({v['rudder']['lags_outside']}/{v['rudder']['lags']})"
                    for c, v in t[kind].items()
                ]
                why = " (with process noise in the model, simulation residuals carry it: not expected white)"
                tail = why if kind == "simulation" and m.estimator == "ml" else ""
                lines.append(f"  {kind} residuals {Path(t['record']).name}: " + "; ".join(bits) + tail)
    else:
        lines.append(f"  FAILED: {m.failure}")
    lines += _aic_text(res)
    lines += _cross_text(res)
    for r, src in zip(res.per_run, res.sources):
        lines.append(f"per record {Path(src).name}:")
        lines += _fmt_params(r) if r.ok else [f"    FAILED: {r.failure}"]
    lines += [f"warning: {w}" for w in res.warnings]
    lines += [f"note: {n}" for n in res.notes]
    return "\n".join(lines)


def write_plots(res: SteeringResult, out: Path) -> list[Path]:
    """Per record: measured, simulated and predicted outputs with the rudder; residual ACF and rudder CCF with
    +-2 sigma bands, prediction and simulation. PNGs written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from primitives.io import atomic_savefig

    m = res.main
    if not m.ok:
        return []
    f = m.fit
    paths = []
    for i, d in enumerate(f.records):
        stem = f"record{i + 1}"
        fig, axes = plt.subplots(len(d.channels) + 1, 1, figsize=(9, 2.2 * (len(d.channels) + 1)), sharex=True)
        axes[0].step(d.t, np.degrees(d.delta), where="post", color="k")
        axes[0].set_ylabel("delta [deg]")
        for j, c in enumerate(d.channels):
            unit, k = UNITS[c]
            ax = axes[j + 1]
            ax.plot(d.t, k * d.y[:, j], ".", ms=3, label="measured")
            ax.plot(d.t, k * f.y_sim[i][:, j], "-", label="simulated")
            ax.plot(d.t, k * (d.y[:, j] - f.e_pred[i][:, j]), "--", lw=0.8, label="predicted")
            ax.set_ylabel(f"{c} [{unit}]")
        axes[1].legend(fontsize=7)
        axes[-1].set_xlabel("t [s]")
        fig.suptitle(f"{Path(d.source).name}: {LABEL[m.model]}, {m.estimator.upper()}", fontsize=9)
        paths.append(atomic_savefig(fig, out / f"{stem}_fit.png", dpi=100))
        plt.close(fig)
        fig, axes = plt.subplots(2, 2 * len(d.channels), figsize=(3 * 2 * len(d.channels), 5), squeeze=False)
        for row, (kind, e) in enumerate((("prediction", f.e_pred[i]), ("simulation", f.e_sim[i]))):
            tests = residual_tests(e, d.delta, d.channels)
            for j, (c, tt) in enumerate(tests.items()):
                for q, key in enumerate(("whiteness", "rudder")):
                    t = tt[key]
                    ax = axes[row, 2 * j + q]
                    ax.bar(t.lags, t.values, width=0.6)
                    ax.axhline(t.band, ls="--", c="r", lw=0.8)
                    ax.axhline(-t.band, ls="--", c="r", lw=0.8)
                    ax.set_title(f"{kind} {c}: {'ACF' if key == 'whiteness' else 'CCF rudder'}", fontsize=8)
        fig.tight_layout()
        paths.append(atomic_savefig(fig, out / f"{stem}_residuals.png", dpi=100))
        plt.close(fig)
    return paths
