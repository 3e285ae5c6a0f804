"""The robust design's part of the design-ratio report: each mix's D-efficiency over the prior's
draws (local and robust side by side) and the Monte Carlo against truths drawn from the prior."""

from __future__ import annotations

from typing import Any

# where the D-efficiencies come from, said beside every table of them (report and plan output)
PROVENANCE = (
    "Measured on the profile's own model at parameter draws around it (simulated): robustness to parameter "
    "error in this model, not evidence about a real ship or about model-structure error."
)


def robust_lines(doc: dict[str, Any]) -> list[str]:
    """Plain-text lines (terminal and Markdown alike) of ``doc['robust']`` and ``doc['prior_monte_carlo']``."""
    r = doc.get("robust")
    if not r:
        return []
    prior = r["prior"]
    lines = [
        f"D-efficiency over parameter draws ({prior['source']}; {r['evaluated_on']}; the robust mix optimised "
        f"on {r['draws_used']} draws; each draw against its own D-optimal mix, certified to {r['optimum_certificate']:.5f}):"
    ]
    for label, s in r["d_efficiency"].items():
        what = {"rounded": "rounded to whole units", "local-D rounded": "local-D rounded"}.get(label, f"{label} mix")
        lines.append(f"  {what:24s} median {s['median']:.3f}   10th percentile {s['p10']:.3f}   worst {s['min']:.3f}")
    lines += [f"  left out: {d}" for d in r["dropped"]]
    lines.append(PROVENANCE)
    mc = doc.get("prior_monte_carlo")
    if mc:
        lines.append(
            f"Monte Carlo against truths drawn from the prior ({doc.get('prior_truths_drawn', 'fresh draws')}; the "
            "estimator's model structure with the drawn values); "
            "parameter-error fraction = rms of (estimate - truth) / truth:"
        )
        for label, s in mc.items():
            p50 = "n/a" if s["param_error_p50"] is None else f"{s['param_error_p50']:.3f}"
            p90 = "n/a" if s["param_error_p90"] is None else f"{s['param_error_p90']:.3f}"
            below = "n/a" if s["frac_param_error_below_0_3"] is None else f"{100 * s['frac_param_error_below_0_3']:.1f} %"
            vr = s.get("validation_rmse_p50")
            val = "" if vr is None else f"; validation RMSE u, v, r median {vr[0]:.3g}, {vr[1]:.3g}, {vr[2]:.3g}"
            lines.append(
                f"  {label:10s} median {p50}   90th percentile {p90}   < 0.3 in {below} "
                f"of {s['runs']} runs over {s['truths']} truths; failed (diverged) {s['failed']}{val}"
            )
            lines += [f"    {n}" for n in s.get("notes", [])]
    return lines


def robust_markdown(doc: dict[str, Any]) -> list[str]:
    """The report.md section (empty for a local design)."""
    lines = robust_lines(doc)
    if not lines:
        return []
    return ["", "## Robust design", "", *(f"    {x}" if x.startswith("  ") else x for x in lines)]
