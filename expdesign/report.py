"""Design-ratio report: JSON document, Markdown text and PNG figures (Figs 9.1-9.3 style)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from expdesign.api import Design
from expdesign.estimators import OE_TOL
from expdesign.mc_parallel import MCEvaluation
from expdesign.mc_result import PARAM_THRESHOLD, SIM_THRESHOLD, THESIS_FRACTIONS, MCResult
from expdesign.robust_report import robust_markdown
from primitives.io import atomic_savefig, atomic_write_bytes, atomic_write_text, dumps, figure_png


def _certificate_line(doc: dict[str, Any], cert: dict[str, Any]) -> str:
    """The certificate bullet: the equivalence theorem's bound for a local criterion, the bayes-D
    bound on its relaxed matrices, none for maximin-D."""
    if doc["criterion"] == "bayes-D":
        return (
            f"- bayes-D efficiency on the relaxed matrices ({cert['relaxation']}) against the bayes-D optimum "
            f">= {_f(doc['efficiency_bound'], '{:.4f}')}."
        )
    if doc["criterion"] == "maximin-D":
        return "- maximin-D: no efficiency bound (SLSQP on the epigraph form; each draw's own optimum is certified)."
    return (
        f"- Convex certificate (equivalence theorem, {cert['relaxation']}): max over feasible designs of the "
        f"directional term = {_f(cert.get('max_over_feasible'), '{:.5g}')} vs p = {cert['n_params']}; "
        f"guaranteed efficiency of the convex solution >= {_f(doc['efficiency_bound'], '{:.4f}')}."
    )


def report_dict(
    design: Design, mc: MCEvaluation | None, sensitivity: list[dict] | None = None, thesis: dict[str, float] | None = None
) -> dict[str, Any]:
    """The design.json document. Monte Carlo numbers count finished runs only; a partial
    evaluation (interrupted, lost worker) is marked partial with the runs each design finished."""
    d = design.to_dict()
    d["monte_carlo"] = mc_section(mc) if mc else None
    if mc:
        cfg = mc.config.to_dict()
        cfg.pop("runs")  # the requested count: the runs that finished are in each design's summary
        d["monte_carlo_config"] = {
            **cfg,
            "runs_requested": mc.config.runs,
            "sample_time": mc.sample_time,
            "engine": mc.engine,
            "elapsed_s": round(mc.elapsed_s, 3),
            "runs_per_s": round(sum(mc.runs_finished.values()) / max(mc.elapsed_s, 1e-9), 2),
            "open_choices": open_choices(mc),
        }
        d["monte_carlo_status"] = {
            "complete": mc.complete,
            "partial": not mc.complete,
            "interrupted": mc.interrupted,
            "errors": list(mc.errors),
            "runs_finished": mc.runs_finished,
        }
        d["monte_carlo_thesis"] = THESIS_FRACTIONS
        d["monte_carlo_notes"] = {k: v.notes for k, v in mc.results.items() if v.notes}
    if thesis:
        d["thesis_shares"] = thesis
    if sensitivity is not None:
        d["sensitivity"] = sensitivity
    return d


def mc_section(mc: MCEvaluation) -> dict[str, Any]:
    """Per design: the summary (runs finished, diverged, percentiles, fractions, digest) and the
    per-parameter table (bias, spread, fraction within tolerance)."""
    out = {}
    for k, r in mc.results.items():
        out[k] = {**r.summary(), **_parameters(r)}
        if r.reference is not None:
            out[k]["reference"].update(_parameters(r.reference))
    return out


def _parameters(r: MCResult) -> dict[str, Any]:
    table = r.parameter_table()
    worst = min(table, key=lambda row: row["frac_within_tolerance"]) if table else None
    return {"parameters": table, "limiting_parameter": worst["parameter"] if worst else None}


ESTIMATOR_TEXT = {
    "iv": "IV (the thesis's estimator, section 9.1.2)",
    "oe": "output error: each run's IV estimate refined by Levenberg-Marquardt on the simulated output (maximum "
    "likelihood for white measurement noise); the IV figures of the same runs are given beside",
}


def open_choices(mc: MCEvaluation) -> list[dict[str, str]]:
    """What Ljungberg (2022) section 9.1 leaves open, with the value this evaluation used."""
    cfg, dist = mc.config, mc.disturbances
    order = (
        "blocks played back to back in one experiment"
        if cfg.protocol == "continuous"
        else "each block a separate sub-experiment from its primitive's nominal state"
    )
    if cfg.protocol != "continuous":
        sequence = "fixed (irrelevant: each block restarts)"
    elif cfg.order in ("library", "given"):
        which = "library order (tau1, tau2, ...)" if cfg.order == "library" else "the order the shares were given in"
        sequence = (
            f"fixed designs: {which} in every run, one sequence as the thesis's optimized input; "
            "random design: signals and order drawn per run from SeedSequence(seed, (run, 0))"
        )
    else:
        sequence = "drawn per run from SeedSequence(seed, (run, 0)) for every design"
    noise = (
        f"current per-sample std {dist.get('current_sample_std', 0):.3g} m/s, measurement std "
        f"{', '.join(f'{x:.3g}' for x in dist.get('measurement_std', ()))} (u, v, r)"
    )
    # what section 9.1 says holds for the thesis's model ship, whatever the profile is called
    thesis_ship = mc.library == "thesis-model-ship"
    if thesis_ship:
        noise = "N(0, 0.025) read as a variance: " + noise
    amplitudes = (
        "tau1-tau11 built to reach the states of section 9.1.1 (feed-forward forces of the true model; zig-zags "
        "switch at the --psi-switch heading, default 0.5 rad). Sway held against the yaw rate (v < 0 while r > 0), as in "
        "the thesis's spirals (v > 0 while r -> -0.6, l. 12441-12449) and as the model ship's two stern azimuth "
        "thrusters make it (Delta x = -0.39 m, tunnel thruster unused, l. 12610, 12632-12634: tau_n = -0.39 tau_y; "
        "our zig-zag forces have tau_y/tau_n = -2.5)"
        if thesis_ship
        else "the primitives of the design's library, as built"
    )
    return [
        {"choice": "experiment protocol", "value": f"{cfg.protocol}: {order}"},
        {"choice": "signal amplitudes", "value": amplitudes},
        {"choice": "primitive order", "value": sequence},
        {
            "choice": "settling between primitives",
            "value": f"{cfg.settle} samples of the forces holding the next start state"
            + (" (none: the next input starts at once)" if not cfg.settle else " (added to the experiment length)"),
        },
        {
            "choice": "minimum sub-experiment",
            "value": f"{cfg.min_block} samples (shorter blocks dropped below half, raised above)",
        },
        {"choice": "block longer than its primitive", "value": "the primitive's input repeats from its start"},
        {
            "choice": "experiment length",
            "value": f"{cfg.n_samples} samples; random design {cfg.n_segments} segments of {cfg.n_samples // cfg.n_segments}",
        },
        {"choice": "noise", "value": noise},
        {
            "choice": "estimator",
            "value": ESTIMATOR_TEXT[cfg.estimator]
            + (
                f" (at most {cfg.oe_iterations} steps per run, stopped when the next step is shorter than {OE_TOL**0.5:g} standard error). "
                "The thesis's estimator is the IV one (l. 12502-12531); its regressors hold the noisy velocities (errors in "
                "variables, section 2.4), which costs the IV estimate variance, most for Yur (sway noise std 0.158 against sway "
                "of at most 0.2 m/s)"
                if cfg.estimator == "oe"
                else ""
            ),
        },
        {
            "choice": "IV instruments",
            "value": f"simulated with the profile's instrument set (model ship: Table 9.1 nominal, "
            f"Ljungberg (2022)), then re-simulated with the estimate up to {cfg.iv_iterations} times (per run, until the "
            f"estimate changes < 0.1 %: the refinement of the thesis's simulation studies, l. 3726-3728 and 8825-8827; its "
            f"real-data study used one step, l. 9776-9778); mean subtraction {cfg.mean_subtraction}",
        },
        {
            "choice": "parameter error",
            "value": "per run, sqrt(mean over the parameters of ((estimate - true)/|true|)^2): errors "
            "normalized by the true value as in Table 6.2 (l. 9027), then their RMSE (l. 12542-12543, Fig. 9.1)",
        },
        {
            "choice": "validation input",
            "value": f"multisine surge and yaw, smoothed binary sway (seed {cfg.validation_seed}), "
            f"{cfg.n_samples} samples, noise-free true output",
        },
    ]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def ratios_png(design: Design, thesis: dict[str, float] | None = None) -> bytes:
    """Bar chart: optimized, convex-relaxation and rounded shares per primitive (+ thesis), as
    PNG bytes (110 dpi, :func:`primitives.io.figure_png`)."""
    plt = _plt()
    names = list(design.weights)
    x = np.arange(len(names))
    series = [("optimized", design.weights), ("convex relaxation", design.convex_weights), ("rounded", design.rounded_fractions)]
    if thesis:
        series.append(("thesis (7.57)", thesis))
    wdt = 0.8 / len(series)
    fig, ax = plt.subplots(figsize=(9, 3.6))
    for i, (lab, w) in enumerate(series):
        ax.bar(x + (i - (len(series) - 1) / 2) * wdt, [100 * w.get(n, 0.0) for n in names], wdt, label=lab)
    ax.set_xticks(x, names)
    ax.set_ylabel("share of trial time (%)")
    ax.set_title(f"{design.profile}: {design.criterion}-optimal mix, mean subtraction {design.mean_subtraction}")
    ax.legend(fontsize=8)
    # fixed margins (0.75 in left, 0.15 right, 0.4 top, 0.45 bottom): tight_layout measured every label again
    fig.subplots_adjust(left=0.75 / 9, right=1 - 0.15 / 9, top=1 - 0.4 / 3.6, bottom=0.45 / 3.6)
    try:
        return figure_png(fig, 110)
    finally:
        plt.close(fig)


def plot_ratios(design: Design, path: Path, thesis: dict[str, float] | None = None) -> None:
    """:func:`ratios_png` written to ``path`` (atomically)."""
    atomic_write_bytes(path, ratios_png(design, thesis))


def _ylabel(r: MCResult) -> str:
    return f"{r.name}\n{len(r.runs)} runs" + (f", {int(r.diverged.sum())} diverged" if r.diverged.any() else "")


def plot_mc(mc: dict[str, MCResult], path_param: Path, path_dof: Path, path_norm: Path) -> None:
    """Histograms of the normalized parameter RMSE (Fig. 9.1, truncated at 5), the per-DOF
    simulation RMSE (Fig. 9.2, truncated at 1, 0.25, 0.15) and its norm (Fig. 9.3, at 0.5), over
    the runs that did not diverge (their count is in each panel's label)."""
    plt = _plt()
    names = list(mc)
    fig, axes = plt.subplots(len(names), 1, figsize=(7, 1.9 * len(names)), sharex=True, squeeze=False)
    for ax, n in zip(axes[:, 0], names):
        r = mc[n]
        if r.theta0 is None:
            ax.text(0.5, 0.5, "parameter RMSE not defined (predictor differs from model)", ha="center", transform=ax.transAxes)
        else:
            ax.hist(np.minimum(r.param_rmse[~r.diverged], 5.0), bins=50, range=(0, 5))
            ax.axvline(PARAM_THRESHOLD, color="k", ls="--", lw=1)
        ax.set_ylabel(_ylabel(r), fontsize=7)
    axes[-1, 0].set_xlabel(f"normalized parameter RMSE (truncated at 5; dashed: {PARAM_THRESHOLD})")
    fig.tight_layout()
    atomic_savefig(fig, path_param, dpi=110)
    plt.close(fig)

    caps = (1.0, 0.25, 0.15)
    fig, axes = plt.subplots(len(names), 3, figsize=(10, 1.9 * len(names)), squeeze=False)
    for i, n in enumerate(names):
        r = mc[n]
        for j, (lab, cap) in enumerate(zip("uvr", caps)):
            axes[i, j].hist(np.minimum(r.sim_rmse[~r.diverged, j], cap), bins=40, range=(0, cap))
            if i == 0:
                axes[i, j].set_title(f"RMSE of {lab} (truncated at {cap})", fontsize=9)
        axes[i, 0].set_ylabel(_ylabel(r), fontsize=7)
    fig.tight_layout()
    atomic_savefig(fig, path_dof, dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(len(names), 1, figsize=(7, 1.9 * len(names)), sharex=True, squeeze=False)
    for ax, n in zip(axes[:, 0], names):
        r = mc[n]
        ax.hist(np.minimum(r.sim_norm[~r.diverged], 0.5), bins=50, range=(0, 0.5))
        ax.axvline(SIM_THRESHOLD, color="k", ls="--", lw=1)
        ax.set_ylabel(_ylabel(r), fontsize=7)
    axes[-1, 0].set_xlabel(f"norm of cross-validation simulation RMSE (truncated at 0.5; dashed: {SIM_THRESHOLD})")
    fig.tight_layout()
    atomic_savefig(fig, path_norm, dpi=110)
    plt.close(fig)


def sensitivity_summary(rows: list[dict[str, Any]]) -> str:
    """Plain-language reading of the sensitivity rows: how far each choice moves the shares."""
    from expdesign.sensitivity import tv_distance

    base = next(
        (
            r
            for r in rows
            if r["psi_switch"] == 0.5
            and r["v_scale"] == 1.0
            and not r["realisations"]
            and r.get("mean_subtraction", "complete") == "complete"
        ),
        None,
    )
    if base is None:
        return ""

    def spread(sel):
        d = [tv_distance(r["weights"], base["weights"]) for r in rows if sel(r) and r is not base]
        return f"{max(d):.2f}" if d else "n/a"

    period = spread(lambda r: r["v_scale"] == 1.0 and not r["realisations"] and r.get("mean_subtraction") == "complete")
    sway = spread(lambda r: r["v_scale"] != 1.0)
    noisy = spread(lambda r: r["realisations"] > 0)
    ms = spread(lambda r: r.get("mean_subtraction") == "batchwise")
    return (
        f"Largest change of the shares against the default (psi_switch 0.5 rad, thesis sway amplitudes against the "
        f"yaw rate, noise-free moments), as total-variation distance: zig-zag period {period}, sway force during the "
        f"zig-zags {sway}, noisy instead of noise-free moments {noisy}, batchwise instead of complete mean "
        f"subtraction {ms}. Default choices and why: the sway amplitudes of section 9.1.1 held against the yaw rate "
        f"(a ship drifts outwards in a turn; in-phase sway or none moves the mix to tau7/tau8 and away from the "
        f"thesis), psi_switch 0.5 rad (the period barely matters), noise-free moments (deterministic and within a "
        f"few points of the noisy estimate). Default mix distance to the thesis: {base['tv_to_thesis']:.2f}."
    )


def _f(x: Any, fmt: str = "{:.3g}") -> str:
    return "n/a" if x is None else fmt.format(x)


def markdown(doc: dict[str, Any], figures: dict[str, str]) -> str:
    """The human report."""
    lines = [
        f"# Design-ratio report: {doc['profile']}",
        "",
        f"Criterion **{doc['criterion']}**, instrument mean subtraction **{doc['mean_subtraction']}** "
        f"({'(7.57), non-convex' if doc['mean_subtraction'] == 'complete' else '(7.18)/(7.53), convex'}), "
        f"trial length {doc['trial_length_s']:.1f} s.",
        "",
        *([f"**Warning:** {w}" for w in doc.get("warnings") or []] + ([""] if doc.get("warnings") else [])),
        "## Shares",
        "",
        "| primitive | optimized % | convex relaxation % | rounded units | unit s | rounded % |"
        + (" thesis % |" if doc.get("thesis_shares") else ""),
        "|---|---|---|---|---|---|" + ("---|" if doc.get("thesis_shares") else ""),
    ]
    for n, w in doc["weights"].items():
        row = (
            f"| {n} | {100 * w:.1f} | {100 * doc['convex_weights'][n]:.1f} | {doc['rounded'][n]} | "
            f"{doc['unit_s'][n]:.2f} | {100 * doc['rounded_fractions'][n]:.1f} |"
        )
        if doc.get("thesis_shares"):
            row += f" {100 * doc['thesis_shares'].get(n, 0.0):.0f} |"
        lines.append(row)
    cert = doc["certificate"]
    lines += [
        "",
        f"- log|det Gamma| of the design: {doc['logdet']:.4g}; efficiency vs equal shares: "
        f"{doc['efficiency_vs_uniform']:.3f} (criterion {doc['criterion']}, > 1 is better).",
        _certificate_line(doc, cert),
        f"- Rounding to whole units (pieces between natural split points) keeps {100 * doc['rounding_efficiency']:.1f} % "
        f"efficiency (loss {100 * doc['rounding_efficiency_loss']:.2f} %).",
        *[
            f"- The {k}'s shares reach {v:.3f} of this design's {doc['criterion']}-efficiency (same moments)."
            for k, v in (doc.get("reference_efficiency") or {}).items()
        ],
        f"- Solver notes: {'; '.join(doc['solver_notes'])}.",
    ]
    if doc.get("starts"):
        lines += [
            "",
            "### Starts of the non-convex solver",
            "",
            "| start | objective at start | objective at end | success |",
            "|---|---|---|---|",
        ]
        for s in doc["starts"]:
            lines.append(
                f"| {s['start']}{' (winner)' if s['start'] == doc['winner'] else ''} | {_f(s['start_objective'], '{:.5g}')} | "
                f"{_f(s['end_objective'], '{:.5g}')} | {s['success']} |"
            )
    if figures.get("ratios"):
        lines += ["", f"![shares]({figures['ratios']})"]
    lines += robust_markdown(doc)
    if doc.get("monte_carlo"):
        lines += mc_markdown(doc, figures)
    if doc.get("sensitivity"):
        lines += [
            "",
            "## Sensitivity of the (7.57) shares to modelling choices",
            "",
            "The thesis defines tau1-tau11 only by the states they produce (section 9.1.1); the zig-zag period, the sway "
            "force held during zig-zags and whether the moments come from noise-free or noisy data are our choices. "
            "TV = total-variation distance to the thesis's shares (0 = identical, 1 = disjoint).",
            "",
            "| variant | TV to thesis | best single primitive | shares > 0.5 % |",
            "|---|---|---|---|",
        ]
        for r in doc["sensitivity"]:
            sh = ", ".join(f"{k} {100 * v:.0f}%" for k, v in r["weights"].items() if v > 0.005)
            lines.append(f"| {r['variant']} | {r['tv_to_thesis']:.2f} | {r['best_single'] or '-'} | {sh} |")
        lines += ["", sensitivity_summary(doc["sensitivity"])]
    return "\n".join(lines) + "\n"


def _md_cell(text: str) -> str:
    """A table cell: a '|' in a name (X|u|u) would end the cell."""
    return text.replace("|", r"\|")


def _limiting(s: dict[str, Any], tol: float) -> str:
    worst = next(p for p in s["parameters"] if p["parameter"] == s["limiting_parameter"])
    return (
        f"{s['estimator']} {_md_cell(worst['parameter'])} ({_pc(worst['frac_within_tolerance'])} of the runs within {tol}, "
        f"spread {_f(worst['spread'])})"
    )


def _pc(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:.1f} %"


def _ours_vs_thesis(mc: dict[str, Any], kind: str) -> str:
    key = "frac_param_rmse_below_1_5" if kind == "param" else "frac_sim_rmse_below_0_15"
    parts = []
    for n in THESIS_FRACTIONS:
        if n in mc:
            ref = mc[n].get("reference")
            parts.append(
                f"{n} thesis {_pc(THESIS_FRACTIONS[n][kind])}, ours {_pc(mc[n][key])} ({mc[n]['estimator']})"
                + (f", {_pc(ref[key])} ({ref['estimator']})" if ref else "")
            )
    return "; ".join(parts)


def mc_markdown(doc: dict[str, Any], figures: dict[str, str]) -> list[str]:
    """Monte Carlo section: status, protocol, results beside the thesis's, per-parameter tables,
    the choices Ljungberg (2022) leaves open, and the figures with both sets of numbers."""
    cfg, st, mc = doc["monte_carlo_config"], doc["monte_carlo_status"], doc["monte_carlo"]
    eng = cfg["engine"]
    lines = ["", "## Monte Carlo evaluation (section 9.1.2)", ""]
    if st["partial"]:
        why = "interrupted" if st["interrupted"] else "tasks failed: " + "; ".join(st["errors"][:3])
        lines += [
            f"**PARTIAL RESULT ({why}).** Runs finished per design: "
            + ", ".join(f"{k} {v} of {cfg['runs_requested']}" for k, v in st["runs_finished"].items())
            + ". Every number below counts the finished runs only.",
            "",
        ]
    lines += [
        f"Protocol **{cfg['protocol']}**; {cfg['runs_requested']} runs requested per design, {cfg['n_samples']} samples "
        f"({cfg['n_samples'] * cfg['sample_time']:.0f} s) per experiment, seed {cfg['seed']}, disturbances from the profile, "
        f"mean subtraction {cfg['mean_subtraction']}, estimator {cfg.get('estimator', 'iv')}. Random design: 1 of the primitives for each of {cfg['n_segments']} "
        f"segments. Computed on {eng['name']} ({eng['workers']} workers x {eng['threads_per_worker']} threads, "
        f"{eng['tasks']} tasks) in {cfg['elapsed_s']:.1f} s ({cfg['runs_per_s']:.0f} runs/s).",
        "",
        "| design | runs | diverged | param RMSE p50 | param RMSE < 1.5 | thesis | sim RMSE p50 | sim RMSE < 0.15 | thesis |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for n, s in mc.items():
        th = THESIS_FRACTIONS.get(n, {})
        rows = [(f"{n} ({s['estimator']})", s)]
        if s.get("reference"):
            rows.append((f"{n} ({s['reference']['estimator']}, thesis's estimator)", s["reference"]))
        for label, x in rows:
            lines.append(
                f"| {label} | {x['runs']} | {x['diverged']} | {_f(x['param_rmse_p50'])} | "
                f"{_pc(x['frac_param_rmse_below_1_5'])} | {_pc(th.get('param'))} | {_f(x['sim_rmse_p50'])} | "
                f"{_pc(x['frac_sim_rmse_below_0_15'])} | {_pc(th.get('sim'))} |"
            )
    lines += [
        "",
        "Percentiles are over the runs that did not diverge; a diverged run (estimate not finite or its validation "
        "simulation exploding) counts as above both thresholds. Thesis column: section 9.1.2 (500 runs); the thresholds "
        "1.5 and 0.15 are the thesis's model-ship ones, for other ships compare the medians.",
    ]
    for n, notes in (doc.get("monte_carlo_notes") or {}).items():
        lines.append(f"- {n}: {'; '.join(notes)}")
    for n, s in mc.items():
        if s.get("parameters"):
            tol = s["parameters"][0]["tolerance"]
            lines += [
                "",
                f"### Parameters, {n} design, {s['estimator']} (normalized error (estimate - true)/|true|)",
                "",
                f"| parameter | true | bias | spread (std) | median abs error | within {tol} |"
                + (f" {s['reference']['estimator']}: spread | within {tol} |" if s.get("reference") else ""),
                "|---|---|---|---|---|---|" + ("---|---|" if s.get("reference") else ""),
            ]
            ref = {p["parameter"]: p for p in (s.get("reference") or {}).get("parameters", [])}
            for p in s["parameters"]:
                r = ref.get(p["parameter"])
                lines.append(
                    f"| {_md_cell(p['parameter'])} | {p['true']:.3g} | {_f(p['bias'])} | {_f(p['spread'])} | "
                    f"{_f(p['median_abs_error'])} | {_pc(p['frac_within_tolerance'])} |"
                    + (f" {_f(r['spread'])} | {_pc(r['frac_within_tolerance'])} |" if r else "")
                )
            lines += ["", "Limiting parameter: " + "; ".join(_limiting(x, tol) for x in (s, s.get("reference")) if x) + "."]
    lines += ["", "### Choices Ljungberg (2022) leaves open, and the values used", ""]
    lines += [f"- {c['choice']}: {c['value']}" for c in cfg["open_choices"]]
    caps = {
        "param": ("Normalized parameter RMSE (Fig. 9.1)", _ours_vs_thesis(mc, "param") + " (share below 1.5)"),
        "dof": (
            "Simulation RMSE per DOF (Fig. 9.2)",
            "the thesis gives histograms only; our medians per DOF: "
            + "; ".join(f"{n} " + ", ".join(f"{k} {_f(v)}" for k, v in s["sim_rmse_dof_p50"].items()) for n, s in mc.items()),
        ),
        "norm": ("Norm of the simulation RMSE (Fig. 9.3)", _ours_vs_thesis(mc, "sim") + " (share below 0.15)"),
    }
    for key, (cap, numbers) in caps.items():
        if figures.get(key):
            lines += ["", f"![{cap}]({figures[key]})", "", f"{cap}: {numbers}."]
    return lines


def write_report(
    out: Path, doc: dict[str, Any], design: Design, mc: dict[str, MCResult] | None, thesis: dict[str, float] | None = None
) -> dict[str, Path]:
    """Write design.json, report.md and the PNG figures into ``out``; returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    figs = {"ratios": "ratios.png"}
    plot_ratios(design, out / figs["ratios"], thesis)
    if mc:
        figs.update(param="mc_param_rmse.png", dof="mc_sim_rmse_dof.png", norm="mc_sim_rmse_norm.png")
        plot_mc(mc, out / figs["param"], out / figs["dof"], out / figs["norm"])
    paths = {k: out / v for k, v in figs.items()}
    paths["json"] = atomic_write_text(out / "design.json", dumps(doc) + "\n")
    paths["markdown"] = atomic_write_text(out / "report.md", markdown(doc, figs))
    return paths
