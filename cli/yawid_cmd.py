"""``shiptrial yawid``: yaw dynamics of a podded ship from a recording (the podded-ship MSc thesis, chapter 4)."""

from __future__ import annotations

from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("yawid")
    def yawid(
        recording: Path = typer.Argument(
            ..., help="CSV with t, r, u, v (+ v_dot, phi for --model full) and tau_r or n1, delta1, n2, delta2"
        ),
        model: str = typer.Option("full", "--model", help="full (2.17, 9 parameters) or simplified (2.18, 5)"),
        ship: str = typer.Option("naval-vessel", "--ship", help="4-DOF podded profile: start values and pod model"),
        prefilter: float | None = typer.Option(
            None, "--prefilter", help="ours: low-pass the measured inputs at this many Hz (default: as measured)"
        ),
        json_out: bool = typer.Option(False, "--json", help="print the estimate as JSON"),
    ) -> None:
        """Estimate the lumped yaw parameters I_r, M_v, A, N_... of (2.17)/(2.18) by output error."""
        from cli.options import check_input_file
        from identify.yawid.api import identify_file
        from identify.yawid.model import LABELS
        from primitives.validate import in_range, one_of

        check_input_file(recording, "RECORDING", "a yaw recording CSV (t, r, u, v, v_dot, phi, tau_r)", "recording")
        one_of(model, "--model", ("full", "simplified"))
        if prefilter is not None:
            in_range(prefilter, "--prefilter", 1e-3, 50.0, "Hz (a low-pass cut-off below the recording's Nyquist frequency)")

        fit, start = identify_file(recording, model, ship, prefilter)
        est = fit.estimate()
        start = {k: start[k] for k in est}
        if json_out:
            typer.echo(
                dumps(
                    {
                        "model": model,
                        "estimate": est,
                        "start": start,
                        "converged": bool(fit.ok[0]),
                        "fit_percent": float(fit.fit_percent[0]),
                        "residual_rms": float(fit.rms[0]),
                        "notes": list(fit.notes),
                    }
                )
            )
        else:
            typer.echo(
                f"{model} model: fit {fit.fit_percent[0]:.1f} %, residual RMS {1e3 * fit.rms[0]:.2f} mrad/s, "
                f"{'converged' if fit.ok[0] else 'NOT converged'} in {fit.iterations} iterations"
            )
            for k, v in est.items():
                typer.echo(f"  {LABELS[k]:10s} {v:12.4g}   (start {start[k]:.4g})")
            for note in fit.notes:
                typer.echo(f"note: {recording}: {note}")
        if not fit.ok[0]:
            raise typer.Exit(1)

    @app.command("yawid-sim")
    def yawid_sim(
        out: Path = typer.Argument(..., help="CSV to write"),
        seed: int = typer.Option(0, "--seed", help="noise seed"),
        noise: float = typer.Option(1.0, "--noise", help="multiple of Table 4.1's noise"),
        force: bool = typer.Option(
            False, "--force", help="replace an OUT file that no yawid-sim wrote (default: refuse, naming the file)"
        ),
    ) -> None:
        """Simulate the 10-minute forward-only identification run of the naval vessel (example input of `yawid`)."""
        from identify.yawid.api import simulate_file
        from primitives.validate import in_range, whole

        whole(seed, "--seed", 0, 2**63 - 1)
        in_range(noise, "--noise", 0.0, 100.0, "x Table 4.1's noise levels")
        wrote = simulate_file(out, seed, noise, force=force, option="OUT")  # refuses OUT before simulating
        typer.echo(f"wrote {wrote}")
