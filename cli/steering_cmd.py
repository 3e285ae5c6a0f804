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
        res = identify_files(list(recordings), ship, model, estimator, split)
        doc = document(res)
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
        if not res.main.ok:
            raise typer.Exit(1)
