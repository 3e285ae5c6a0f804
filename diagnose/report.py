"""Outputs of a diagnosis: plain-language text, JSON, residual plots and the refitted model file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from diagnose.api import Diagnosis
from diagnose.model_file import model_dict
from primitives.io import atomic_savefig, atomic_write_text, to_jsonable
from primitives.ship import DOFS

UNITS = {"u": "m/s", "v": "m/s", "r": "rad/s"}


def _pm(p: dict, key: str, fmt: str = ".2g", scale: float = 1.0) -> str:
    """`` +- std`` of a parameter (1 std, the finding's ``interval``), empty without one."""
    sd = p.get(key)
    return f" +- {scale * sd:{fmt}}" if isinstance(sd, int | float) and np.isfinite(sd) else ""


def sentence(f: dict) -> str:
    """One plain-language sentence per finding."""
    p, e = f["parameters"], f["effect"]
    if e == "current":
        what = (f"the ship meets a current of {p['speed_mps']:.3g}{_pm(p, 'speed_std')} m/s toward "
                f"{p['toward_deg']:03.0f}{_pm(p, 'toward_std_deg', '.0f')} deg")
    elif e == "actuator_delay":
        what = f"the actuators act {p['delay_s']:.2g}{_pm(p, 'delay_std')} s late ({p['samples']:.1f} samples)"
    elif e == "input_offset":
        extra = (f" ({p['offset_deg']:.2f}{_pm(p, 'offset_std', '.2f', float(np.degrees(1.0)))} deg)"
                 if "offset_deg" in p else "")
        what = (f"input {p['input']} has a neutral offset of {p['offset']:.3g}{_pm(p, 'offset_std')}{extra}: the ship "
                f"acts on {p['input']} - offset")
    elif e == "sensor_bias":
        what = f"the measured {p['signal']} reads {p['bias']:+.3g}{_pm(p, 'bias_std')} {UNITS[p['signal']]} too high"
    elif e == "quadratic_damping":
        what = f"the {f['dof']} motion has nonlinear damping {p['term']} (coefficient {p['value']:.3g} per sample)"
    elif e == "missing_coupling":
        what = f"the {f['dof']} motion is coupled through {p['term']} (coefficient {p['value']:.3g} per sample)"
    elif e == "thrust_loss" and "loss_percent" in p:
        pct = p["loss_percent"]
        what = (f"the thrust is {pct:.0f}{_pm(p, 'loss_percent_std', '.1f')} % lower than the model's" if pct is not None
                else f"the thrust term {p['term']} changes by {p['coefficient']:.3g}")
    elif e == "thrust_loss":
        what = f"the thrust falls with speed ({p['term']} coefficient {p['coefficient']:.3g})"
    elif e == "resistance_change":
        pct = p["resistance_change_pct"]
        what = (f"the hull resistance ({p['term']}) is {pct:+.0f} % off the model's" if pct is not None
                else f"the resistance term {p['term']} changes by {p['coefficient']:.3g}")
    elif e == "inertia_change":
        what = f"the {f['dof']} inertia is {p['inertia_ratio']:.2f} x the model's (increments scaled by {1 + p['scale']:.3f})"
    elif e == "wind":
        what = "the relative wind pushes the ship (drag coefficients " + ", ".join(
            f"{k.split('_')[1]} {v:.3g}" for k, v in p.items() if "_std" not in k) + ")"
    else:
        what = f"{e} in {f['dof']}: " + ", ".join(f"{k} {v:.3g}" for k, v in p.items() if isinstance(v, float))
    plaus = f" Plausible for this ship: {f['plausibility']}." if f.get("plausibility") else ""
    return f"{what}: {f['evidence']}.{plaus}"


def per_run_lines(d: Diagnosis) -> list[str]:
    """The per-run table: fit before -> after per channel on each held-out run."""
    if not d.per_run:
        return []
    lines = [f"Per run ({d.per_run_method}), fit before -> after [%]:"]
    w = max(len(r["run"]) for r in d.per_run)
    lines.append(f"  {'run':{w}s}  " + "  ".join(f"{k:>17s}" for k in DOFS))
    for r in d.per_run:
        cells = [f"{r['before'][k]:7.1f} -> {r['after'][k]:6.1f}" for k in DOFS]
        lines.append(f"  {r['run']:{w}s}  " + "  ".join(f"{c:>17s}" for c in cells))
    return lines


def interval_lines(findings: list[dict]) -> list[str]:
    """What the +- figures cover (one line; the JSON ``interval`` of each finding says the same)."""
    iv = next((f["interval"] for f in findings if f.get("interval")), None)
    return [f"  (+- is {iv['covers']}.)"] if iv else []


def to_text(d: Diagnosis) -> str:
    lines = [f"Diagnosis of {', '.join(p.rec.source for p in d.preps)} against ship {d.profile.name!r} ({d.baseline_source})"]
    for p in d.preps + d.val_preps:
        if p.rec.notes:
            lines.append(f"Recording {p.rec.source}: " + "; ".join(p.rec.notes) + ".")
    loc = d.location
    lines.append("Where: residual / noise " + ", ".join(f"{k} {v:.1f}" for k, v in loc["rms_over_noise"].items())
                 + f"; worst {loc['worst_dof']}.")
    for w in loc["cusum_windows"][:3]:
        seg = f" (segments {', '.join(w['segment'][:6])})" if w["segment"] else ""
        lines.append(f"  CUSUM alarm (5.1) on {w['dof']} from {w['t_start']:.1f} s to {w['t_end']:.1f} s{seg}")
    if loc.get("segments"):
        top = loc["segments"][:3]
        lines.append("  worst manoeuvre segments (residual / noise): " + "; ".join(
            f"{s['segment']} " + "/".join(f"{s[d]:.1f}" for d in DOFS) for s in top) + " (surge/sway/yaw)")
    for label, key in (("simulation", "output_error_tests"), ("one-step prediction", "one_step_tests")):
        tests = loc[key]
        white = ", ".join(f"{k} p={v['whiteness_p']:.2g}" for k, v in tests.items())
        cc = [f"{k}~{c['input']}" for k, v in tests.items() for c in v["cross_correlation"] if c["lags_outside_band"] > 2]
        lines.append(f"  {label} errors: whiteness (Ljung-Box) {white}; input cross-correlation outside the "
                     f"99 % band: {', '.join(cc) if cc else 'none'}")
    if d.explained:
        lines.append("Findings: none. The model explains the data: no candidate physics improves the fit "
                     "significantly and on held-out data.")
    elif not d.findings and d.structure:
        lines.append("Findings: none that is a condition of these runs (only baseline structure, below).")
    elif not d.findings:
        worst = max(d.location["rms_over_noise"].items(), key=lambda kv: kv[1])
        lines.append(f"Findings: none, but the model does NOT explain the data (the {worst[0]} residual is {worst[1]:.0f} x "
                     "the noise): no candidate improves the fit significantly and on held-out data, so the cause lies "
                     "outside the library or these recordings cannot separate it (see the screened candidates in the JSON).")
    else:
        lines.append("Findings (strongest first):")
        for i, f in enumerate(d.findings, 1):
            lines.append(f"  {i}. [{f['effect']}] {sentence(f)}")
        lines += interval_lines(d.findings)
    if d.structure:
        lines.append("Baseline structure (the --fit-on reference runs show it too, so it is the model's shape, not a "
                     "condition of these runs; kept in the refitted model):")
        for i, f in enumerate(d.structure, 1):
            lines.append(f"  {i}. [{f['effect']}] {sentence(f)}")
    for u in d.untestable:
        extra = f" ({u['dof']} {u['term']})" if "term" in u else ""
        lines.append(f"Cannot be tested: {u['effect']}{extra}: {u['reason']}.")
    said = {f["key"] for f in d.findings + d.structure} | {r["key"] for r in d.rejected}  # already reported above or below
    weak: dict[str, dict] = {}
    for c in d.screened[-1]["candidates"] if d.screened else []:  # the last round: after every kept effect
        if c["key"] not in said and c["p_value"] < 1e-3:
            weak[c["key"]] = c
    if weak:
        top = sorted(weak.values(), key=lambda c: c["p_value"])[:3]
        lines.append("Not kept (left over after the findings; significant on the estimation data but too weak or not confirmed on held-out blocks): " + "; ".join(
            f"{c['key']} (p = {c['p_value']:.1g}, held-out {100 * c['heldout_gain']:+.0f} %, "
            f"{c['runs_improved']} held-out runs better, estimate "
            + ", ".join(f"{e:.3g}" for e in c["estimate"]) + ")" for c in top) + ".")
    for text in dict.fromkeys(f"Rejected: {r['key']}: {r['reason']}." for r in d.rejected):
        lines.append(text)
    for n in d.notes:
        lines.append(f"Note: {n}.")
    if d.refit_parameters:
        lines.append("Baseline parameters refitted with the findings (bounded, regularised towards the profile): "
                     + ", ".join(d.refit_parameters) + ".")
    left = d.unexplained_dofs if d.findings or d.structure else []
    if left:
        lines.append(f"Still above the noise after the findings: {', '.join(left)} (more physics is missing than the library names).")
    lines += per_run_lines(d)
    lines.append(f"Pooled over the {d.fit_on} run(s) (summary only), before -> after: " + ", ".join(
        f"{k} {d.fit_before[k]:.1f} % -> {d.fit_after[k]:.1f} %" for k in DOFS))
    return "\n".join(lines)


def to_json(d: Diagnosis, model_path: str | None) -> dict:
    return to_jsonable({
        "ship": d.profile.name,
        "baseline": d.baseline_source,
        "recordings": [{"source": p.rec.source, "role": role, "samples": p.rec.n_samples, "sample_time": p.rec.sample_time,
                        "notes": p.rec.notes} for role, ps in (("diagnosed", d.preps), ("validation", d.val_preps)) for p in ps],
        "explained": d.explained,
        "still_unexplained_dofs": d.unexplained_dofs,
        "findings": d.findings,
        "structure": d.structure,
        "untestable": d.untestable,
        "fit_before": d.fit_before,
        "fit_after": d.fit_after,
        "fit_on": d.fit_on,
        "fit_before_diagnosed": d.fit_before_diag,
        "fit_after_diagnosed": d.fit_after_diag,
        "location": d.location,
        "noise_std": dict(zip("uvr", d.sigma.tolist())),
        "model": model_path,
        "per_run": d.per_run,
        "per_run_method": d.per_run_method,
        "rejected": d.rejected,
        "notes": d.notes,
        "refit_parameters": d.refit_parameters,
        "screened": d.screened,
        "elapsed_s": d.elapsed_s,
    })


def write_model(d: Diagnosis, path: str | Path) -> Path:
    return atomic_write_text(path, json.dumps(model_dict(d), indent=2))


def write_plots(d: Diagnosis, out: str | Path) -> list[Path]:
    """Residual plots before/after per recording (diagnosed and validation), PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    paths = []
    p0 = d.model.p0()
    p0[d.model.x0_params()] = d.P[d.model.x0_params()]  # baseline with the fitted initial states
    for kind, preps in (("diagnosed", d.preps), ("validation", d.val_preps)):
        for n, p in enumerate(preps):
            before = p.y - d.model.simulate(p, p0)[0]
            after = p.y - d.model.simulate(p, d.P)[0]
            fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
            win = max(1, int(round(5.0 / p.rec.sample_time)))
            kern = np.ones(win) / win
            for i, ax in enumerate(axes):
                for res, lab, col in ((before, "before", "tab:red"), (after, "after", "tab:blue")):
                    ax.plot(p.rec.t, res[:, i], lw=0.5, color=col, alpha=0.35)
                    ax.plot(p.rec.t, np.convolve(res[:, i], kern, mode="same"), lw=1.5, color=col,
                            label=f"{lab} (5 s mean)")
                ax.set_ylabel(f"{'uvr'[i]} residual [{UNITS['uvr'[i]]}]")
                ax.grid(alpha=0.3)
            axes[0].legend(loc="upper right")
            axes[0].set_title(f"{kind}: {Path(p.rec.source).name}")
            axes[-1].set_xlabel("t [s]")
            fig.tight_layout()
            paths.append(atomic_savefig(fig, out / f"residuals_{kind}_{n + 1}.png", dpi=110))
            plt.close(fig)
    return paths


def write_all(d: Diagnosis, out: str | Path, final_dir: str | Path | None = None) -> dict[str, Path]:
    """Every output into ``out``; ``final_dir`` is where ``out`` will be moved (diagnosis.json
    names the model file at its final place when ``out`` is a temporary directory)."""
    out = Path(out)
    model_path = write_model(d, out / "model.json")
    paths = {"model": model_path}
    atomic_write_text(out / "report.txt", to_text(d) + "\n")
    atomic_write_text(out / "diagnosis.json", json.dumps(to_json(d, str(Path(final_dir or out) / "model.json")), indent=2))
    paths["report"] = out / "report.txt"
    paths["json"] = out / "diagnosis.json"
    for i, p in enumerate(write_plots(d, out)):
        paths[f"plot{i + 1}"] = p
    return paths

