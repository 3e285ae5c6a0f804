"""``shiptrial sweep CONFIG.toml``: design sweeps locally or on a Dask cluster."""

from __future__ import annotations

import os
from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("sweep")
    def sweep(
        config: Path = typer.Argument(
            ..., help="sweep TOML file ([sweep] ships, criteria, mean_subtraction, library, speeds, seed)"
        ),
        out: Path = typer.Option(Path("sweep.csv"), "--out", help="table to write (.csv, or .parquet with pyarrow)"),
        plot: Path | None = typer.Option(None, "--plot", help="summary plot PNG (default: beside the table)"),
        scheduler: str | None = typer.Option(
            None, "--scheduler", help="Dask scheduler address (default: $SHIPTRIAL_SCHEDULER, else all local cores)"
        ),
        json_out: bool = typer.Option(False, "--json", help="print the rows as JSON"),
        keep_partial: bool = typer.Option(
            False, "--keep-partial", help="on Ctrl-C, write the finished cells to NAME.partial.csv (default: write nothing)"
        ),
        force: bool = typer.Option(
            False, "--force", help="replace a table or plot file that no sweep wrote (default: refuse, naming the file)"
        ),
    ) -> None:
        """Run a design sweep (ships x speeds x criteria x mean-subtraction modes) into one tidy table."""
        from cli.options import validate_sweep_options
        from expdesign.sweep import failed_cells, load_sweep, plot_summary, run_sweep, ship_warnings, write_table

        validate_sweep_options(config=config, out=out, plot=plot, force=force, partial=keep_partial)
        cells = load_sweep(config)
        warnings = ship_warnings(cells)
        for w in warnings:  # a model.json's findings the designs leave out, as every command given the file says
            typer.echo(f"warning: {w}", err=True)
        res = run_sweep(cells, scheduler or os.environ.get("SHIPTRIAL_SCHEDULER"))
        rows = res.finished()
        if res.interrupted:
            typer.echo(f"interrupted: {len(rows)} of {len(cells)} cells finished", err=True)
            if not keep_partial:
                typer.echo("nothing written (pass --keep-partial to keep the finished cells)", err=True)
                raise typer.Exit(130)
            out = out.with_name(f"{out.stem}.partial{out.suffix}")  # marked partial in its name: never taken for a full sweep
        table = write_table(rows, out, force=force, option="--out")  # checked before the run too: refused before any work
        try:
            fig = plot_summary(rows, plot or out.with_suffix(".png"), force=force, option="--plot")
        except OSError:  # a full disk after the table: the finished table is kept (hours of cells), and said so
            typer.echo(f"wrote {table} (the table; its plot was not written)", err=True)
            raise
        failed = [r for r in rows if r.get("error")]
        if json_out:
            typer.echo(
                dumps({"rows": rows, "table": str(table), "plot": str(fig), "interrupted": res.interrupted, "warnings": warnings})
            )
        else:
            typer.echo(
                f"{len(rows)} of {len(cells)} cells done{' (interrupted: PARTIAL table)' if res.interrupted else ''}; "
                f"{len(failed)} failed"
            )
            typer.echo(f"wrote {table}\nwrote {fig}")
        if res.interrupted:
            raise typer.Exit(130)
        if failed:
            typer.echo(f"error: {len(failed)} of {len(cells)} cells failed:", err=True)
            for line in failed_cells(rows):
                typer.echo(f"  {line}", err=True)
            raise typer.Exit(1)
