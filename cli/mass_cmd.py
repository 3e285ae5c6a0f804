"""``shiptrial mass``: mass change and centre-of-gravity height from roll (Linder et al. 2015).

Heights are said one way everywhere: body-frame z in metres, origin at the waterline amidships,
positive down (a load on deck has a negative z)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from primitives.io import dumps

if TYPE_CHECKING:
    from identify.rollmass.estimate import MassEstimate


def register(app: typer.Typer) -> None:
    @app.command("mass")
    def mass(
        nominal: Path = typer.Argument(
            ..., help="nominal run CSV (t, delta, p, a_s, r; optional u, surge speed m/s), no extra load"
        ),
        calibration: Path = typer.Argument(..., help="calibration run CSV with a known load (--known-load or its header)"),
        loaded: Path = typer.Argument(..., help="run CSV with the unknown load"),
        known_load: str | None = typer.Option(
            None,
            "--known-load",
            help="calibration load KG@Z: kg at z m (z positive down from the "
            "waterline, a load on deck is negative), e.g. 0.2@-0.256; default: the calibration file's header",
        ),
        profile: Path | None = typer.Option(
            None,
            "--profile",
            help="roll profile TOML (default: Our Lass II 1:24); "
            "speed and IMU z come from the recordings' headers when they have them",
        ),
        method: str | None = typer.Option(
            None,
            "--method",
            help="oe (output error on p, a_s, r; default), improved (refined IV), paper-iv (Linder et al. 2015 IV), or ls",
        ),
        z_f: float | None = typer.Option(
            None,
            "--z-f",
            help="roll-centre prior z_f in m, minus the roll centre's depth below the waterline: -0.03 puts it 3 cm below (z = zbar + z_f, Linder et al. 2015 (12); default: the profile's)",
        ),
        json_out: bool = typer.Option(False, "--json", help="print the estimate as JSON"),
    ) -> None:
        """Estimate the loaded run's extra mass and its z (CoG of the load), with 95 % confidence intervals (Linder et al. 2015)."""
        from cli.options import validate_mass_options
        from identify.rollmass.api import estimate_from_files

        validate_mass_options(z_f=z_f)
        e = estimate_from_files(nominal, calibration, loaded, known_load, profile, method, z_f)
        if not e.converged:
            _no_estimate(e, json_out)
        (mlo, mhi), (zlo, zhi) = e.ci()
        if json_out:
            typer.echo(
                dumps(
                    {
                        "method": e.method,
                        "m": e.m,
                        "m_ci95": [mlo, mhi],
                        "z_m": e.zbar_m,
                        "z_m_ci95": [zlo, zhi],
                        # the intervals' Satterthwaite degrees of freedom (t_{0.975, nu} standard errors); null: 1.96
                        "m_dof": e.m_dof,
                        "z_m_dof": e.zbar_m_dof,
                        "z_convention": "body frame, m, positive down from the waterline",
                        "corr": e.corr,
                        "params": e.params,
                        "warnings": e.warnings,
                        "notes": e.notes,
                    }
                )
            )
        else:
            for n in e.notes:
                typer.echo(f"note: {n}")
            typer.echo(f"method {e.method}: mass change {e.m:.4f} kg (95 % CI {mlo:.4f} .. {mhi:.4f}{_by(e.m_dof)})")
            where = "above" if e.zbar_m < 0 else "below"
            typer.echo(
                f"load z {e.zbar_m:+.4f} m, i.e. {abs(e.zbar_m):.3f} m {where} the waterline (z positive down; "
                f"95 % CI {zlo:+.4f} .. {zhi:+.4f}{_by(e.zbar_m_dof)}); correlation {e.corr:+.2f}"
            )
            for w in e.warnings:
                typer.echo(f"warning: {w}")

    @app.command("mass-sim")
    def mass_sim(
        out: Path = typer.Argument(..., help="directory for nominal.csv, calibration.csv, loaded.csv"),
        case: str = typer.Option("case1", "--case", help="Table 2 case: case1, case2, case3"),
        seed: int = typer.Option(0, "--seed"),
        profile: Path | None = typer.Option(None, "--profile", help="roll profile TOML (default: Our Lass II 1:24)"),
    ) -> None:
        """Simulate the basin experiment of one Table 2 case into three recordings (example input of `mass`)."""
        from cli.options import validate_mass_sim_options
        from identify.rollmass.model import load_profile
        from identify.rollmass.recording import write_roll_csv
        from identify.rollmass.simulate import Noise, simulate_case
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
                meta = {
                    "ship": prof.name,
                    "role": role,
                    "dataset": rec.name,
                    "speed_m_s": f"{prof.known.U:g}",
                    "imu_z_m": f"{prof.known.zbar_s:g}",
                }
                if role != "loaded":
                    meta.update({"load_kg": f"{d['load_kg']:g}", "load_z_m": f"{d['load_height']:g}"})
                write_roll_csv(rec, tmp / f"{role}.csv", meta)
        for role in ("nominal", "calibration", "loaded"):
            typer.echo(f"wrote {out / f'{role}.csv'}")
        c = truth[recs[1].name]
        typer.echo(f"calibration load: --known-load {c['load_kg']:g}@{c['load_height']:g}")


def _no_estimate(e: MassEstimate, json_out: bool) -> None:
    """A fit that did not converge is a failure, never a number: its notes and warnings, no mass or z,
    exit 1 (the project's rule; the numbers of a stopped fit look like an answer)."""
    msg = f"the {e.method} fit did not converge: no estimate is given"
    if json_out:
        typer.echo(dumps({"method": e.method, "converged": False, "error": msg, "warnings": e.warnings, "notes": e.notes}))
    else:
        for n in e.notes:
            typer.echo(f"note: {n}")
        for w in e.warnings:
            typer.echo(f"warning: {w}")
        typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(1)


def _by(dof: float) -> str:
    """How the interval was made, where it is not 1.96 standard errors: Student's t with the meat's
    Satterthwaite degrees of freedom (oe, ``sandwich.LoadMoments.dof``)."""
    return f", Student's t with {dof:.0f} degrees of freedom" if dof < float("inf") else ""
