"""Design-ratio report: JSON document, Markdown text and PNG figures (Figs 9.1-9.3 style). The Markdown
text is written by :mod:`expdesign.report_markdown`; its public functions (:func:`markdown`, :func:`mc_markdown`,
:func:`sensitivity_summary`) are imported from here too."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from expdesign.api import Design
from expdesign.estimators import OE_TOL
from expdesign.mc_parallel import MCEvaluation
from expdesign.mc_result import PARAM_THRESHOLD, SIM_THRESHOLD, THESIS_FRACTIONS, MCResult
from expdesign.report_markdown import markdown, mc_markdown, sensitivity_summary  # noqa: F401 - public names callers import from here
from primitives.io import atomic_savefig, atomic_write_bytes, atomic_write_text, dumps, figure_png


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
