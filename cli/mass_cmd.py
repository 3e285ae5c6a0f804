"""``shiptrial mass``: mass change and centre-of-gravity height from roll (seed 003, Linder et al. 2015)."""

from __future__ import annotations

from pathlib import Path

import typer

from primitives.io import dumps


def register(app: typer.Typer) -> None:
    @app.command("mass")
    def mass(
        nominal: Path = typer.Argument(..., help="nominal run CSV (t, delta, p, a_s, r), no extra load"),
        calibration: Path = typer.Argument(..., help="calibration run CSV with the known load of --known-load"),
        loaded: Path = typer.Argument(..., help="run CSV with the unknown load"),
        known_load: str = typer.Option(..., "--known-load", help="calibration load KG@M: kg at body-frame height m (z down), e.g. 0.2@-0.256"),
        profile: Path | None = typer.Option(None, "--profile", help="roll profile TOML (default: Our Lass II 1:24)"),
        method: str = typer.Option("oe", "--method", help="oe (ours: output error on p, a_s, r), improved (refined IV), paper-iv, or ls"),
        z_f: float | None = typer.Option(None, "--z-f", help="centre-of-rotation offset prior [m] (default: the profile's)"),
        json_out: bool = typer.Option(False, "--json", help="print the estimate as JSON"),
    ) -> None:
        """Estimate the loaded run's extra mass and its CoG height, with 95 % confidence intervals."""
        from cli.options import validate_mass_options
        from diagnose.rollmass.api import estimate_from_files

        validate_mass_options(z_f=z_f)
        e = estimate_from_files(nominal, calibration, loaded, known_load, profile, method, z_f)
        (mlo, mhi), (zlo, zhi) = e.ci()
        if json_out:
            typer.echo(dumps({"method": e.method, "m": e.m, "m_ci95": [mlo, mhi], "zbar_m": e.zbar_m, "zbar_m_ci95": [zlo, zhi],
                              "corr": e.corr, "params": e.params, "warnings": e.warnings}))
        else:
            typer.echo(f"method {e.method}: mass change {e.m:.4f} kg (95 % CI {mlo:.4f} .. {mhi:.4f})")
            typer.echo(f"CoG height of the load {e.zbar_m:+.4f} m body frame, z down (95 % CI {zlo:+.4f} .. {zhi:+.4f}); "
                       f"correlation {e.corr:+.2f}")
            for w in e.warnings:
                typer.echo(f"warning: {w}")
        if not e.converged:
            raise typer.Exit(1)

    @app.command("mass-sim")
    def mass_sim(
        out: Path = typer.Argument(..., help="directory for nominal.csv, calibration.csv, loaded.csv"),
        case: str = typer.Option("case1", "--case", help="Table 2 case: case1, case2, case3"),
        seed: int = typer.Option(0, "--seed"),
        profile: Path | None = typer.Option(None, "--profile", help="roll profile TOML (default: Our Lass II 1:24)"),
    ) -> None:
        """Simulate the basin experiment of one Table 2 case into three recordings (example input of `mass`)."""
        from cli.options import validate_mass_sim_options
        from diagnose.rollmass.model import load_profile
        from diagnose.rollmass.recording import write_roll_csv
        from diagnose.rollmass.simulate import Noise, simulate_case
        from primitives.errors import UserError
        from primitives.io import atomic_output_dir

        validate_mass_sim_options(out=out, seed=seed)
        prof = load_profile(profile)
        if case not in prof.raw["cases"]:
            raise UserError(f"--case {case!r}: choose one of {', '.join(prof.raw['cases'])}")
        recs = simulate_case(prof, case, Noise.from_profile(prof), seed)
        truth = {d["name"]: d for d in prof.raw["dataset"]}
        with atomic_output_dir(out) as tmp:  # the three datasets appear together or not at all
            for role, rec in zip(("nominal", "calibration", "loaded"), recs):
                d = truth[rec.name]
                write_roll_csv(rec, tmp / f"{role}.csv", {"dataset": rec.name, "load_kg": f"{d['load_kg']:g}", "load_height_m": f"{d['load_height']:g}"})
        for role in ("nominal", "calibration", "loaded"):
            typer.echo(f"wrote {out / f'{role}.csv'}")
        c = truth[recs[1].name]
        typer.echo(f"calibration load: --known-load {c['load_kg']:g}@{c['load_height']:g}")
