"""``shiptrial detect-prior`` and ``shiptrial detect``: has the ship changed, when, and what (seed 000 ch. 5)."""

from __future__ import annotations

from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("detect-prior")
    def detect_prior(
        nominal: list[Path] = typer.Argument(..., help="nominal recording CSV(s) of the podded ship (r, phi, the pod inputs n1, alpha1, n2, "
                                           "alpha2 or the measured pod yaw moment tau_n; optional measured sway acceleration v_dot)"),
        out: Path = typer.Option(..., "--out", help="prior model file to write (.json)"),
        model: str = typer.Option("full", "--model", help="full (2.17, needs phi) or simplified (2.18)"),
        bootstrap: int = typer.Option(64, "--bootstrap", help="the prior's parameter error from N parametric-bootstrap "
                                      "refits of the nominal data (errors in variables; one batch, seconds); 0: Gaussian "
                                      "from the fit's Jacobian (knows the noise on r only)"),
        seed: int = typer.Option(0, "--seed", help="seed of the bootstrap"),
    ) -> None:
        """Fit the yaw-row prior of seed 000 (2.17)/(2.18) on a nominal recording, for `detect`."""
        from cli.options import validate_detect_prior_options
        from diagnose.detect.api import fit_prior, save_prior

        validate_detect_prior_options(out=out, bootstrap=bootstrap, seed=seed)
        prior = fit_prior(nominal, model, bootstrap, seed)
        save_prior(prior, out)
        typer.echo(f"wrote {out}: {prior.kind} yaw row, I_r {prior.values['I_r']:.4g} kg m^2, "
                   f"residual sigma {prior.sigma:.2g} rad/s")

    @app.command("detect")
    def detect(
        recordings: list[Path] = typer.Argument(..., help="recording CSV(s) to test against the prior"),
        prior_file: Path = typer.Option(..., "--prior", help="prior model from `shiptrial detect-prior`"),
        plot: Path | None = typer.Option(None, "--plot", help="figure of the test statistic (.png, .pdf, .svg)"),
        false_alarm: float = typer.Option(0.02, "--false-alarm", help="false-alarm probability per recording"),
        min_change: float = typer.Option(0.05, "--min-change", help="smallest relative change worth an alarm (0.05 = 5 %)"),
        seed: int = typer.Option(0, "--seed", help="seed of the threshold's no-change simulation"),
        json_out: bool = typer.Option(False, "--json", help="print the verdicts as JSON"),
    ) -> None:
        """Say whether and when the ship changed and which property (yaw inertia, yaw damping, pod gain)."""
        from cli.options import validate_detect_options
        from diagnose.detect.api import detect as run_detect
        from diagnose.detect.api import load_prior, load_runs
        from diagnose.detect.api import plot as plot_stats

        validate_detect_options(plot=plot, false_alarm=false_alarm, min_change=min_change, seed=seed)
        prior = load_prior(prior_file)
        recs = load_runs(recordings)
        if prior.model_error > 0:
            # Measured (benchmarks/bench_detect.py): such priors alarm far above the design rate.
            typer.echo(f"warning: {prior_file}: the prior's structure misfits its own data (model error "
                       f"{prior.model_error:.2g}); alarms are not calibrated to --false-alarm: prefer a --model full prior",
                       err=True)
        dets = [run_detect(r, prior, false_alarm, min_change, seed) for r in recs]
        if plot is not None:
            plot_stats(dets, plot)
        if json_out:
            typer.echo(dumps({"prior": str(prior_file), "model": prior.kind, "false_alarm": false_alarm,
                              "min_change": min_change, "recordings": [d.summary() for d in dets]}))
            return
        for d in dets:
            if d.changed:
                c = d.evidence["candidates"][d.property]
                typer.echo(f"{d.source}: CHANGED at {d.alarm_s:.0f} s: {d.property.replace('_', ' ')} "
                           f"{100 * c['relative_change']:+.1f} % (+- {100 * c['std']:.1f} %)")
            else:
                typer.echo(f"{d.source}: no change detected (statistic max {max(d.evidence['statistic_max'].values()):.1f} "
                           f"< threshold {d.threshold:.1f})")
            for name, c in d.evidence["candidates"].items():
                typer.echo(f"  {name:12s} estimate {100 * c['relative_change']:+6.1f} % +- {100 * c['std']:4.1f} % (noise and "
                           f"the prior's own error), "
                           f"log-likelihood ratio {c['llr']:7.1f}")
            dz = f"{d.dead_zone_alarm_s:.0f} s" if d.dead_zone_alarm_s is not None else "none"
            typer.echo(f"  dead-zone CUSUM (5.1) alarm: {dz}")
        if plot is not None:
            typer.echo(f"wrote {plot}")
