"""``shiptrial design``: D/A/E-optimal primitive mix, rounding, Monte Carlo check, report."""

from __future__ import annotations

from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("design")
    def design(
        ship: str = typer.Option("model-ship", "--ship", help="built-in profile name or a .toml/.json profile file"),
        criterion: str = typer.Option("D", "--criterion", help="D, A or E"),
        mean_subtraction: str = typer.Option("complete", "--mean-subtraction",
                                             help="instrument mean removal: none, batchwise (7.53) or complete (7.57)"),
        trial_length: float | None = typer.Option(None, "--trial-length", help="trial length in seconds (default: every primitive once)"),
        monte_carlo: int = typer.Option(500, "--monte-carlo", help="Monte Carlo runs per design (0 skips the evaluation)"),
        mc_samples: int = typer.Option(1000, "--mc-samples", help="samples per Monte Carlo experiment (thesis: 1000 = 125 s)"),
        seed: int = typer.Option(0, "--seed", help="seed of every random draw (starts, Monte Carlo)"),
        out: Path | None = typer.Option(None, "--out", help="directory for report.md, design.json and figures (default: write no files)"),
        json_out: bool = typer.Option(False, "--json", help="print the report JSON"),
        sensitivity: bool = typer.Option(False, "--sensitivity", help="add the model-ship sensitivity study (zig-zag period, sway, noisy moments)"),
        psi_switch: float | None = typer.Option(None, "--psi-switch", help="model-ship zig-zag switching heading in rad (default 0.5)"),
        min_frac: float | None = typer.Option(None, "--min-frac", help="minimum share of every primitive"),
        max_frac: float | None = typer.Option(None, "--max-frac", help="maximum share of every primitive"),
        noisy_moments: int = typer.Option(0, "--noisy-moments", help="estimate the moments from this many noisy simulations (0: noise-free)"),
        scheduler: str | None = typer.Option(None, "--scheduler",
                                             help="Dask scheduler address for the Monte Carlo (default: $SHIPTRIAL_SCHEDULER, else all local cores)"),
    ) -> None:
        """Choose the mix of manoeuvres that maximises information, and check it by Monte Carlo."""
        from cli.options import validate_design_options
        from expdesign.api import default_library, run_design
        from expdesign.errors import DesignError
        from expdesign.montecarlo import evaluate_designs_parallel
        from expdesign.report import report_dict, write_report
        from expdesign.sensitivity import THESIS_SHARES, sensitivity_study
        from primitives.ship import load_profile

        validate_design_options(criterion=criterion, mean_subtraction=mean_subtraction, trial_length=trial_length,
                                monte_carlo=monte_carlo, mc_samples=mc_samples, seed=seed, out=out, psi_switch=psi_switch,
                                min_frac=min_frac, max_frac=max_frac, noisy_moments=noisy_moments)
        profile = load_profile(ship)
        lib = default_library(profile, psi_switch)
        thesis = THESIS_SHARES if profile.primitive_dictionary == "model-ship" else None
        d = run_design(profile, lib, criterion=criterion, mean_subtraction=mean_subtraction, trial_length_s=trial_length,
                       min_frac=min_frac, max_frac=max_frac, seed=seed, disturbed_realisations=noisy_moments,
                       references={"thesis": thesis} if thesis else None)
        mc = cfg = None
        if monte_carlo:
            names = [p.name for p in lib if p.kind == "informative"]
            designs = {"optimized": d.weights, "random": "random", "uniform": {n: 1.0 / len(names) for n in names}}
            if profile.primitive_dictionary == "model-ship" and set(THESIS_SHARES) <= set(names):
                designs["thesis"] = THESIS_SHARES  # the shares section 9.1.1 reports, for comparison
            mc = evaluate_designs_parallel(profile, designs, runs=monte_carlo, seed=seed, scheduler=scheduler, primitives=lib,
                                           n_samples=mc_samples, mean_subtraction=mean_subtraction)
            cfg = {"runs": monte_carlo, "n_samples": mc_samples, "n_segments": 5, "seed": seed, "sample_time": profile.sample_time,
                   "mean_subtraction": mean_subtraction}
        sens = None
        if sensitivity:
            if profile.primitive_dictionary != "model-ship":
                raise DesignError("--sensitivity studies the model-ship dictionary tau1-tau11; use --ship model-ship")
            sens = sensitivity_study(profile, seed=seed)
        doc = report_dict(d, mc, cfg, sens, thesis)
        paths = {}
        if out is not None:
            from primitives.io import atomic_output_dir

            with atomic_output_dir(out) as tmp:  # a failed report never leaves a mix of old and new files
                paths = {k: out / p.relative_to(tmp) for k, p in write_report(tmp, doc, d, mc, thesis).items()}
        if json_out:
            typer.echo(dumps(doc))
            return
        typer.echo(f"{profile.name}: {d.criterion}-optimal mix ({d.mean_subtraction} mean subtraction)")
        for n, w in d.weights.items():
            if w > 0.005:
                typer.echo(f"  {n:8s} {100 * w:5.1f} %   {d.rounded[n]:3d} x {d.unit_s[n]:.1f} s")
        typer.echo(f"efficiency vs equal shares {d.efficiency_vs_uniform:.3f}; convex certificate >= {d.efficiency_bound or 0:.4f}")
        for label, eff in d.references.items():
            typer.echo(f"the {label}'s shares reach {eff:.3f} of this design's {d.criterion}-efficiency")
        if mc:
            for n, r in mc.items():
                s = r.summary()
                p = "n/a" if s["param_rmse_p50"] is None else f"{s['param_rmse_p50']:.3g} ({100 * s['frac_param_rmse_below_1_5']:.0f} % < 1.5)"
                typer.echo(f"  MC {n:9s} param RMSE p50 {p}; sim RMSE p50 {s['sim_rmse_p50']:.3g} "
                           f"({100 * s['frac_sim_rmse_below_0_15']:.0f} % < 0.15)")
        if paths:
            typer.echo(f"wrote {paths['markdown']} and {paths['json']}")
