"""Outputs of a diagnosis: plain-language text, JSON, residual plots and the refitted model file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from diagnose.api import Diagnosis
from diagnose.candidates import STEADY_WIND
from diagnose.describe import includes_no_effect
from diagnose.model_file import model_dict
from diagnose.perrun import FIT_FLOOR, fit_str, short_label
from primitives.io import atomic_savefig, atomic_write_text, to_jsonable
from primitives.ship import DOFS

UNITS = {"u": "m/s", "v": "m/s", "r": "rad/s"}
# what the report's measures mean, printed once at its end (a trials engineer reads no code)
GLOSSARY = [
    "How to read this report:",
    "  fit % = NRMSE fit of the simulated output, 100 (1 - |recorded - simulated| / |recorded - its mean|): 100 % is "
    "perfect, 0 % no better than the run's mean, negative worse than the mean (unbounded; below -999 % it is shown as "
    "'< -999 %': the simulation diverges from the run; 'n/a': the simulation diverged, no finite fit).",
    "  residual = recorded - simulated (also in the plots); residual / noise = its RMS over the estimated measurement-"
    "noise std of the channel: about 1 when the model explains the data.",
    "  CUSUM alarm (5.1) = the dead-zone cumulative sum (eq. 5.1 of the podded-ship MSc thesis) over |residual| beyond 1.5 noise std "
    "crossed 10 noise std: the residual stays large over that window (times in s from the run's start).",
    "  'per sample' coefficient = a hull term's velocity increment over one sample of {ts:g} s per unit of the term in "
    "SI units (m/s, rad/s, rad); divide by {ts:g} s for an acceleration.",
    "  pooled fit = one fit over all samples of the runs together: each run weighs by its spread and the differences "
    "between the runs' means count as spread the model reproduces, so it can exceed every single run's fit.",
]


def _cell(v: float) -> str:
    """A fit % in a table: bounded below, a diverged (non-finite) one said as fit_str says it."""
    return "n/a" if not np.isfinite(v) else "< -999" if v < FIT_FLOOR else f"{v:.1f}"


def heldout_change(gain: float) -> str:
    """A held-out relative drop of the residual (``heldout_gain``) as the change of that residual."""
    if not np.isfinite(gain) or gain < -9.99:  # the residual grew more than tenfold
        return "held-out residual more than 10 x larger (the linearised model diverges on the held-out data)"
    return f"held-out residual {-100 * gain:+.0f} %"


def _criterion(f: dict, unit: str) -> str:
    """The held-out criterion a refitted candidate failed (``Verdict.failed_criterion``), in words;
    ``unit``: what a fold is (a validation run, a left-out run or block)."""
    aic, imp, n, drop = f["heldout_delta_aic"], f["runs_improved"], f["n_folds"], f["worst_fit_drop"]
    tally = f"held-out AIC {aic:+.1f}, {imp}/{n} {unit}s better"
    return {
        "penalty": f"its held-out gain is too small for the penalty of its parameters (held-out AIC {aic:+.1f}, "
        "must be negative)",
        "too_few_improved": f"it improves only {imp} of {n} {unit}s (more than half must improve)",
        "channel_much_worse": f"one channel of a {unit} loses {drop:.1f} points of fit, more than the {f['much_worse']:g} allowed "
        f"({tally})",
        "run_misfit_rises": f"a {unit}'s weighted misfit rises by {100 * f['worst_run_rise']:.1f} %, more than the "
        f"{100 * f['run_rise']:g} % allowed ({tally})",
        "no_pooled_gain": f"the pooled held-out misfit does not fall (gain {100 * f['heldout_gain']:+.2f} %; {tally})",
    }[f["criterion"]]


def rejection(r: dict) -> str:
    """The search's reason for rejecting a candidate (a ``rejected`` entry), said as the
    criterion that failed, worded from the entry's fields."""
    if str(r.get("implausible", "")).startswith("no delay found"):
        return r["implausible"]
    f = r.get("failed")
    if not f:
        return r["reason"]
    if r.get("judged_on") == "validation":
        return f"not confirmed on the validation runs: {_criterion(f, 'validation run')}"
    return "not confirmed on the held-out data (each left-out run or block refitted from the refitted model): " + _criterion(
        f, "left-out fold"
    )


def _pm(p: dict, key: str, fmt: str = ".2g", scale: float = 1.0) -> str:
    """`` +- std`` of a parameter (1 std, the finding's ``interval``), empty without one."""
    sd = p.get(key)
    return f" +- {scale * sd:{fmt}}" if isinstance(sd, int | float) and np.isfinite(sd) else ""


def effect_name(f: dict) -> str:
    """The finding's name in the report: its effect, a wind that was not recorded said so."""
    return "wind (not recorded)" if f.get("key") == STEADY_WIND else f["effect"]


def _effect(f: dict) -> str:
    """The finding's effect in words, each figure with its +- (1 std)."""
    p, e = f["parameters"], f["effect"]
    if e == "current":
        return (
            f"the ship meets a current of {p['speed_mps']:.3g}{_pm(p, 'speed_std')} m/s toward "
            f"{p['toward_deg']:03.0f}{_pm(p, 'toward_std_deg', '.0f')} deg"
        )
    if e == "actuator_delay":
        return f"the actuators act {p['delay_s']:.2g}{_pm(p, 'delay_std')} s late ({p['samples']:.1f} samples)"
    if e == "input_offset":
        extra = f" ({p['offset_deg']:.2f}{_pm(p, 'offset_std', '.2f', float(np.degrees(1.0)))} deg)" if "offset_deg" in p else ""
        return (
            f"input {p['input']} has a neutral offset of {p['offset']:.3g}{_pm(p, 'offset_std')}{extra}: the ship "
            f"acts on {p['input']} - offset"
        )
    if e == "sensor_bias":
        return f"the measured {p['signal']} reads {p['bias']:+.3g}{_pm(p, 'bias_std')} {UNITS[p['signal']]} too high"
    if e in ("quadratic_damping", "missing_coupling"):
        how = "has nonlinear damping" if e == "quadratic_damping" else "is coupled through"
        return f"the {f['dof']} motion {how} {p['term']} (coefficient {p['value']:.3g}{_pm(p, 'value_std', '.2g')} per sample)"
    if e == "thrust_loss" and p.get("loss_percent") is not None:
        return f"the thrust is {p['loss_percent']:.0f}{_pm(p, 'loss_percent_std', '.1f')} % lower than the model's"
    if e == "thrust_loss" and "loss_percent" in p:
        return f"the thrust term {p['term']} changes by {p['coefficient']:.3g}{_pm(p, 'coefficient_std')}"
    if e == "thrust_loss":
        return f"the thrust falls with speed ({p['term']} coefficient {p['coefficient']:.3g}{_pm(p, 'coefficient_std')})"
    if e == "resistance_change":
        pct = p["resistance_change_pct"]
        return (
            f"the hull resistance ({p['term']}) is {pct:+.0f}{_pm(p, 'resistance_change_pct_std', '.0f')} % off the model's"
            if pct is not None
            else f"the resistance term {p['term']} changes by {p['coefficient']:.3g}{_pm(p, 'coefficient_std')}"
        )
    if e == "inertia_change":
        ratio = (
            f"{p['inertia_ratio']:.2f}{_pm(p, 'inertia_ratio_std', '.2f')} x the model's"
            if p.get("inertia_ratio") is not None
            else "not a finite multiple of the model's"
        )
        return f"the {f['dof']} inertia is {ratio} (increments scaled by {1 + p['scale']:.3f}{_pm(p, 'scale_std', '.3f')})"
    if e == "wind":
        acc = [
            (k, u) for k, u in (("surge", "m/s^2"), ("sway", "m/s^2"), ("yaw", "rad/s^2")) if p.get(f"wind_accel_{k}") is not None
        ]
        means = (
            "; its mean acceleration of the ship over the diagnosed runs: "
            + ", ".join(f"{k} {p[f'wind_accel_{k}']:.3g}{_pm(p, f'wind_accel_{k}_std', '.2g')} {u}" for k, u in acc)
            if acc
            else ""
        )
        if f.get("key") == STEADY_WIND:
            return (
                f"a steady wind that was not recorded pushes the ship: {p['speed_mps']:.3g}{_pm(p, 'speed_std')} m/s from "
                f"{p['from_deg']:03.0f}{_pm(p, 'from_std_deg', '.0f')} deg, the speed a loaded tanker of these main "
                "particulars would feel (Blendermann's loaded-tanker loads on its freeboard's areas, C_B 0.80 for its mass): "
                "a ship with more side area above water (a superstructure, containers) or a finer hull feels a weaker wind, by "
                "the square root of the area and mass ratios, and its load's shape over the wind angle is a "
                "tanker's; the mean accelerations that follow rest on the shape only ("
                f"surge load x {p['surge_scale']:.2f}{_pm(p, 'surge_scale_std', '.2f')}, yaw arm "
                f"{p['yaw_arm_over_length']:+.2f}{_pm(p, 'yaw_arm_over_length_std', '.2f')} L){means}"
            )
        return (
            "the recorded wind pushes the ship (Blendermann's loads scaled per DOF by "
            + ", ".join(
                f"{k.split('_', 1)[1]} {v:.3g}{_pm(p, k + '_std', '.2g')}"
                for k, v in p.items()
                if "_std" not in k and not k.startswith("wind_accel_")
            )
            + "; areas from the main particulars as a loaded tanker's)"
            + means
        )
    if e == "roll_coupling":
        return "the roll angle phi feeds the " + " and the ".join(
            f"{dof} motion (coefficient {p[k]:.3g}{_pm(p, k + '_std', '.3g')} per sample)"
            for k, dof in (("phi_sway", "sway"), ("phi_yaw", "yaw"))
            if k in p
        )
    return f"{e} in {f['dof']}: " + ", ".join(
        f"{k} {v:.3g}{_pm(p, k + '_std', '.2g')}" for k, v in p.items() if isinstance(v, float) and "_std" not in k
    )


def sentence(f: dict) -> str:
    """One plain-language sentence per finding; an effect whose 95 % interval includes none is said
    to be, and when a held-out run confirms it anyway (:func:`diagnose.describe.indistinct`), that
    its size is not resolved."""
    what = _effect(f)
    if includes_no_effect(f) and f.get("heldout_confirmed"):
        what += (
            " (its size is not resolved: the 95 % interval, model error included, holds no effect too; named because a "
            "held-out run confirms it, its residual falling by more than the noise with it added)"
        )
    elif includes_no_effect(f):
        what += " (the 95 % interval includes no effect)"
    plaus = f" Plausible for this ship: {f['plausibility']}." if f.get("plausibility") else ""
    return f"{what}: {f['evidence']}.{plaus}"


def per_run_lines(d: Diagnosis) -> list[str]:
    """The per-run table: fit before -> after per channel on each held-out run."""
    if not d.per_run:
        return []
    lines = [f"Per run ({d.per_run_method}), fit before -> after [%]:"]
    w = max(len(short_label(r["run"])) for r in d.per_run)
    lines.append(f"  {'run':{w}s}  " + "  ".join(f"{k:>17s}" for k in DOFS))
    for r in d.per_run:
        cells = [f"{_cell(r['before'][k]):>7s} -> {_cell(r['after'][k]):>6s}" for k in DOFS]
        lines.append(f"  {short_label(r['run']):{w}s}  " + "  ".join(f"{c:>17s}" for c in cells))
    return lines


def interval_lines(findings: list[dict]) -> list[str]:
    """What the +- figures cover (one line; the JSON ``interval`` of each finding says the same)."""
    iv = next((f["interval"] for f in findings if f.get("interval")), None)
    return [f"  (+- is {iv['covers']}.)"] if iv else []


def gain_sources(d: Diagnosis) -> list[str]:
    """Where the held-out gain of the per-run table comes from, per validation run: the baseline
    as given, the baseline refitted (its share), then each finding added in the search's order
    (the fits the search recorded, by simulation, when it added them), then the final model."""
    kept = [f for f in d.findings + d.structure if f.get("heldout_per_run")]
    # the search scores leave-one-out folds by a linearised refit, the table by simulation: not comparable
    if not d.per_run or not kept or d.fit_on != "validation":
        return []
    by_run = [{r["run"]: r for r in f["heldout_per_run"]} for f in kept]
    if any(set(b) != {r["run"] for r in d.per_run} for b in by_run):
        return []

    def fits(row: dict, key: str) -> str:
        return "/".join(_cell(row[key][k]) for k in DOFS)

    lines = [f"Where the gain comes from ({d.per_run_method}; fit % surge/sway/yaw; each finding as the search added it):"]
    last = "final (magnitudes refitted by maximum likelihood)" if d.magnitudes_refitted else "final"
    for r in d.per_run:
        start = "baseline refitted" if d.refit_parameters else "before the first finding (no baseline parameter refitted)"
        steps = [f"baseline as given {fits(r, 'before')}", f"{start} {fits(by_run[0][r['run']], 'before')}"]
        steps += [f"+ {f['key']} {fits(b[r['run']], 'after')}" for f, b in zip(kept, by_run)]
        lines.append(f"  {short_label(r['run'])}: " + " -> ".join(steps) + f" -> {last} {fits(r, 'after')}")
    return lines


def location_lines(d: Diagnosis) -> list[str]:
    """Where the model misses: residual / noise per channel, CUSUM alarms, worst segments, residual tests."""
    loc = d.location
    lines = [
        "Where: residual / noise "
        + ", ".join(f"{k} {v:.1f}" for k, v in loc["rms_over_noise"].items())
        + f"; worst {loc['worst_dof']}."
    ]
    for w in loc["cusum_windows"][:3]:
        seg = f" (segments {', '.join(w['segment'][:6])})" if w["segment"] else ""
        run = f" of {Path(w['recording']).name}" if len(d.preps) > 1 else ""
        lines.append(
            f"  CUSUM alarm (5.1) on {w['dof']} from {w['t_start']:.1f} s to {w['t_end']:.1f} s after the start{run}{seg}"
        )
    if loc.get("segments"):
        top = loc["segments"][:3]
        lines.append(
            "  worst manoeuvre segments (residual / noise): "
            + "; ".join(f"{s['segment']} " + "/".join(f"{s[d]:.1f}" for d in DOFS) for s in top)
            + " (surge/sway/yaw)"
        )
    for label, key in (("simulation", "output_error_tests"), ("one-step prediction", "one_step_tests")):
        tests = loc[key]
        white = ", ".join(f"{k} p={v['whiteness_p']:.2g}" for k, v in tests.items())
        cc = [f"{k}~{c['input']}" for k, v in tests.items() for c in v["cross_correlation"] if c["lags_outside_band"] > 2]
        lines.append(
            f"  {label} errors: whiteness (Ljung-Box) {white}; input cross-correlation outside the "
            f"99 % band: {', '.join(cc) if cc else 'none'}"
        )
    return lines


def finding_lines(d: Diagnosis) -> list[str]:
    """The findings, the baseline structure and what could not be tested."""
    lines = []
    if d.cannot_tell:
        lines.append(f"Findings: none named; {d.cannot_tell}. No model.json written: no diagnosed model to give.")
    elif d.explained:
        lines.append(
            "Findings: none. The model explains the data: no candidate physics improves the fit "
            "significantly and on held-out data."
        )
    elif not d.findings and d.structure:
        lines.append("Findings: none that is a condition of these runs (only baseline structure, below).")
    elif not d.findings:
        worst = max(d.location["rms_over_noise"].items(), key=lambda kv: kv[1])
        lines.append(
            f"Findings: none, but the model does NOT explain the data (the {worst[0]} residual is {worst[1]:.0f} x "
            "the noise): no candidate improves the fit significantly and on held-out data, so the cause lies "
            "outside the library or these recordings cannot separate it (the screened candidates: --json, or "
            "diagnosis.json with --out DIR)."
        )
    else:
        lines.append("Findings (strongest first):")
        for i, f in enumerate(d.findings, 1):
            lines.append(f"  {i}. [{effect_name(f)}] {sentence(f)}")
        lines += interval_lines(d.findings)
    if d.structure:
        lines.append(
            "Baseline structure (the --fit-on reference runs show it too, so it is the model's shape, not a "
            "condition of these runs; kept in the refitted model):"
        )
        for i, f in enumerate(d.structure, 1):
            lines.append(f"  {i}. [{effect_name(f)}] {sentence(f)}")
    for u in d.untestable:
        extra = f" ({u['dof']} {u['term']})" if "term" in u else ""
        lines.append(f"Cannot be tested: {u['effect']}{extra}: {u['reason']}.")
    return lines


def leftover_lines(d: Diagnosis) -> list[str]:
    """Candidates left over (significant but not kept), the rejected ones with their reasons, notes."""
    lines = []
    said = {f["key"] for f in d.findings + d.structure} | {r["key"] for r in d.rejected}  # already reported above or below
    weak: dict[str, dict] = {}
    for c in d.screened[-1]["candidates"] if d.screened else []:  # the last round: after every kept effect
        if c["key"] not in said and c["p_value"] < 1e-3:
            weak[c["key"]] = c
    if weak:
        top = sorted(weak.values(), key=lambda c: c["p_value"])[:3]
        lines.append(
            "Not kept (left over after the findings; significant on the estimation data but too weak or not confirmed on held-out blocks): "
            + "; ".join(
                f"{c['key']} (p = {c['p_value']:.1g}, {heldout_change(c['heldout_gain'])}, "
                f"{c['runs_improved']} held-out runs better, estimate " + ", ".join(f"{e:.3g}" for e in c["estimate"]) + ")"
                for c in top
            )
            + "."
        )
    for text in dict.fromkeys(f"Rejected: {r['key']}: {rejection(r)}." for r in d.rejected):
        lines.append(text)
    for n in d.notes:
        lines.append(f"Note: {n}.")
    return lines


def recording_line(rec) -> str:
    """The report's line of a recording's notes. A note worded to stand alone on stderr names the recording
    itself (the ``# ship:`` header note: 'run.csv: header ...'); the line names it once (stop 62: 'Recording
    run.csv: run.csv: header ...')."""
    lead = f"{rec.source}: "
    return f"Recording {rec.source}: " + "; ".join(n.removeprefix(lead) for n in rec.notes) + "."


def to_text(d: Diagnosis) -> str:
    lines = [f"Diagnosis of {', '.join(p.rec.source for p in d.preps)} against ship {d.profile.name!r} ({d.baseline_source})"]
    for p in d.preps + d.val_preps:
        if p.rec.notes:
            lines.append(recording_line(p.rec))
    lines += location_lines(d) + finding_lines(d) + leftover_lines(d)
    if d.refit_parameters:
        lines.append(
            "Baseline parameters refitted with the findings (bounded, regularised towards the profile): "
            + ", ".join(d.refit_parameters)
            + "."
        )
    left = d.unexplained_dofs if d.findings or d.structure else []
    if left:
        lines.append(
            f"Still above the noise after the findings: {', '.join(left)} (more physics is missing than the library names)."
        )
    lines += per_run_lines(d)
    lines += gain_sources(d)
    lines.append(
        f"Pooled over the {d.fit_on} run(s) (summary only), before -> after: "
        + ", ".join(f"{k} {fit_str(d.fit_before[k], decimals=1)} -> {fit_str(d.fit_after[k], decimals=1)}" for k in DOFS)
    )
    lines += [g.format(ts=d.profile.sample_time) for g in GLOSSARY]
    return "\n".join(lines)


def to_json(d: Diagnosis, model_path: str | None) -> dict:
    return to_jsonable(
        {
            "ship": d.profile.name,
            "baseline": d.baseline_source,
            "recordings": [
                {
                    "source": p.rec.source,
                    "role": role,
                    "samples": p.rec.n_samples,
                    "sample_time": p.rec.sample_time,
                    "notes": p.rec.notes,
                }
                for role, ps in (("diagnosed", d.preps), ("validation", d.val_preps))
                for p in ps
            ],
            "explained": d.explained,
            "cannot_tell": d.cannot_tell,
            "unpinned_runs": [{"run": src, "sd_noise_units": sd, "limit_noise_units": lim} for src, sd, lim in d.unpinned],
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
            "magnitudes_refitted": d.magnitudes_refitted,
            "screened": d.screened,
            "elapsed_s": d.elapsed_s,
        }
    )


def write_model(d: Diagnosis, path: str | Path) -> Path:
    return atomic_write_text(path, json.dumps(model_dict(d), indent=2))


def running_mean(x: np.ndarray, win: int) -> np.ndarray:
    """Centred mean over ``win`` samples that shrinks at the ends (no zero padding: a zero-padded
    convolution pulls the ends towards 0 and draws a jump there)."""
    x = np.asarray(x, float)
    if win <= 1 or len(x) == 0:
        return x.copy()
    c = np.concatenate([[0.0], np.cumsum(x)])
    k = np.arange(len(x))
    lo = np.maximum(k - (win - 1) // 2, 0)
    hi = np.minimum(k + win // 2 + 1, len(x))
    return (c[hi] - c[lo]) / (hi - lo)


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
            t = p.rec.t - p.rec.t[0]  # from the run's start, as the CUSUM windows of the report
            for i, ax in enumerate(axes):
                for res, lab, col in ((before, "before", "tab:red"), (after, "after", "tab:blue")):
                    ax.plot(t, res[:, i], lw=0.5, color=col, alpha=0.35)
                    ax.plot(t, running_mean(res[:, i], win), lw=1.5, color=col, label=f"{lab} (5 s mean)")
                ax.set_ylabel(f"{'uvr'[i]} recorded - simulated [{UNITS['uvr'[i]]}]", fontsize=9)
                ax.grid(alpha=0.3)
            axes[0].legend(loc="upper right")
            axes[0].set_title(f"{kind}: {Path(p.rec.source).name}")
            axes[-1].set_xlabel("time from the run's start [s]")
            fig.tight_layout()
            paths.append(atomic_savefig(fig, out / f"residuals_{kind}_{n + 1}.png", dpi=110))
            plt.close(fig)
    return paths


def write_all(d: Diagnosis, out: str | Path, final_dir: str | Path | None = None) -> dict[str, Path]:
    """Every output into ``out``; ``final_dir`` is where ``out`` will be moved (diagnosis.json
    names the model file at its final place when ``out`` is a temporary directory)."""
    out = Path(out)
    # no model.json after "cannot tell": it would be the calm runs' baseline, unpinned on the
    # diagnosed runs, under a "-diagnosed" name a later command would take for a diagnosed model
    paths = {} if d.cannot_tell else {"model": write_model(d, out / "model.json")}
    model_path = None if d.cannot_tell else str(Path(final_dir or out) / "model.json")
    atomic_write_text(out / "report.txt", to_text(d) + "\n")
    atomic_write_text(out / "diagnosis.json", json.dumps(to_json(d, model_path), indent=2))
    paths["report"] = out / "report.txt"
    paths["json"] = out / "diagnosis.json"
    for i, p in enumerate(write_plots(d, out)):
        paths[f"plot{i + 1}"] = p
    return paths
