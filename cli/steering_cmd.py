"""``shiptrial steering``: linear steering dynamics (Nomoto K', T') from sea-trial records by output error and
maximum likelihood (Källström 1977)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("steering")
    def steering(
        recordings: list[Path] = typer.Argument(
            ..., help="CSV (t, delta, psi, optional r, v, u; SI units, rad) or MARIN .dat; several are pooled"
        ),
        ship: str = typer.Option(..., "--ship", help="profile (name or file): length L for the prime system, rudder sign"),
        model: str = typer.Option("nomoto2", "--model", help="nomoto1, nomoto2 or state-space ([v, r, psi], needs v)"),
        estimator: str = typer.Option("ml", "--estimator", help="ml (Kalman predictor, process noise) or oe (output error)"),
        split: str | None = typer.Option(
            None, "--split", help="S or S1:S2 seconds: identify each part (window S1-S2 left out) and cross-validate"
        ),
        out: Path | None = typer.Option(
            None, "--out", help="directory for steering.json and the plots (written whole or not at all)"
        ),
        json_out: bool = typer.Option(False, "--json", help="print the report as JSON"),
        wind: bool = typer.Option(
            False,
            "--wind",
            help="also estimate a steady wind's heading-dependent force and moment (Källström's theta_9, theta_10; "
            "phi_3 of nomoto2)",
        ),
        noise_corr: bool = typer.Option(
            False,
            "--noise-corr",
            help="maximum likelihood: also estimate the correlation of the process noise on the two rate equations "
            "(Källström's R1(1,2)); nomoto2 and state-space",
        ),
        log_x: float = typer.Option(
            0.0, "--log-x", help="the sway log's distance forward of midship [m] (it reads v + X r; negative aft)"
        ),
        save_profile: Path | None = typer.Option(
            None,
            "--save-profile",
            help="write the --ship profile with the identified model in its linear sway/yaw terms (.toml) for design, "
            "plan-trial and diagnose",
        ),
        force: bool = typer.Option(
            False,
            "--force",
            help="replace a --save-profile file that no steering --save-profile wrote (default: refuse, naming the file)",
        ),
    ) -> None:
        """Identify K', T1', T2', T3' (and first-order K', T') with 95 % intervals, AIC over the models and
        estimators, residual whiteness and rudder cross-correlation for prediction and simulation."""
        from cli.options import check_input_file
        from identify.steering.api import ESTIMATORS, MODELS, identify_files
        from identify.steering.report import document, text, write_plots
        from primitives.io import atomic_output_dir, atomic_write_text, check_replaceable_dir
        from primitives.validate import one_of

        one_of(model, "--model", MODELS)
        one_of(estimator, "--estimator", ESTIMATORS)
        if split is not None:
            from identify.steering.api import parse_split

            parse_split(split)
        for r in recordings:
            check_input_file(r, "RECORDING", "a steering recording (.csv or MARIN .dat)", "recording")
        if out is not None:
            check_replaceable_dir(out)
        if save_profile is not None:
            from identify.steering.saved_profile import check_base, check_save_path
            from primitives.ship import load_profile

            # before the fits' seconds; written by write_saved_profile
            check_save_path(save_profile, force=force, option="--save-profile")
            check_base(load_profile(ship))
        res = identify_files(list(recordings), ship, model, estimator, split, wind, log_x, noise_corr)
        doc = document(res)
        saved = _saved_profile(res, ship, save_profile) if save_profile is not None and res.main.ok else None
        if out is not None:
            with atomic_output_dir(out) as tmp:
                atomic_write_text(tmp / "steering.json", dumps(doc) + "\n")
                write_plots(res, tmp)
        if json_out:
            typer.echo(dumps(doc))
        else:
            typer.echo(text(res))
            if out is not None:
                typer.echo(f"wrote {out}/steering.json and plots")
        for w in res.warnings if json_out else ():
            print(f"warning: {w}", file=sys.stderr)
        if saved is not None:
            from identify.steering.saved_profile import write_saved_profile

            write_saved_profile(saved, save_profile, force=force, option="--save-profile")
            print(f"wrote {save_profile}: {saved.source_line}", file=sys.stderr)
        if not res.main.ok:
            # one line on stderr, as every refusal: the report above (stdout) has the table of every model's result
            why = res.main.failure or "no fit"
            lost = f"--save-profile {save_profile}: nothing written; " if save_profile is not None else ""
            print(
                f"error: {lost}the {res.model} {res.estimator} fit failed: {why}; check the records' columns and signs "
                "(t, delta, psi, r), or try another --model/--estimator (the AIC table above)",
                file=sys.stderr,
            )
            raise typer.Exit(1)


def _saved_profile(res, ship: str, path: Path):
    """The --ship profile with the chosen fit written into it (identify.steering.saved_profile)."""
    from identify.steering.api import nomoto_parameters
    from identify.steering.saved_profile import steering_profile

    return steering_profile(
        res.main.fit, nomoto_parameters(res.main.fit), ship, res.V, path.stem, [Path(s).name for s in res.sources]
    )
