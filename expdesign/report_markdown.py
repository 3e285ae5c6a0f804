"""Design-ratio report, its Markdown text (report.md): the shares, the certificate, the Monte Carlo section
beside the thesis's figures (section 9.1.2), the open choices and the sensitivity table. The JSON
document and the figures are :mod:`expdesign.report`'s."""

from __future__ import annotations

from typing import Any

from expdesign.mc_result import THESIS_FRACTIONS
from expdesign.robust_report import robust_markdown


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
