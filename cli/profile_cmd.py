"""``shiptrial profile new``: a ship profile from main particulars (library:
:func:`primitives.particulars.build.build_profile`)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from primitives.errors import UserError
from primitives.io import atomic_write_text, check_out_file


def register(app: typer.Typer) -> None:
    sub = typer.Typer(no_args_is_help=True, help="Make ship profiles: a first model from main particulars.")
    app.add_typer(sub, name="profile")

    @sub.callback()
    def _profile() -> None:
        """Make ship profiles: a first model from main particulars."""

    @sub.command("new")
    def new(
        name: str = typer.Option(..., "--name", help="profile name, e.g. my-ship"),
        length: float = typer.Option(..., "--length", help="length between perpendiculars L, m"),
        beam: float = typer.Option(..., "--beam", help="beam B, m"),
        draught: float = typer.Option(..., "--draught", help="draught T, m"),
        block_coefficient: float = typer.Option(..., "--block-coefficient", help="block coefficient Cb (0.35-0.9)"),
        speed: float = typer.Option(..., "--speed", help="service (approach) speed, knots"),
        rudder_area: float | None = typer.Option(
            None, "--rudder-area", help="movable rudder area, m^2, both rudders of a twin-screw ship (default: DNV rule guidance)"
        ),
        propeller_diameter: float | None = typer.Option(None, "--propeller-diameter", help="screw diameter, m (default 0.6 T)"),
        pitch_ratio: float | None = typer.Option(
            None, "--pitch-ratio", help="screw pitch ratio P/D (default 0.75, or solved for --rpm)"
        ),
        rpm: float | None = typer.Option(None, "--rpm", help="shaft speed at the service speed, rpm (default: solved)"),
        mcr_kw: float | None = typer.Option(None, "--mcr-kw", help="engine maximum continuous rating, kW; checks the speed"),
        actuator: str = typer.Option(
            "rudder_propeller",
            "--actuator",
            help="rudder_propeller (single screw, one rudder), twin_screw (two screws, two rudders) or azimuth (two steerable pods)",
        ),
        out: Path = typer.Option(..., "--out", help="profile TOML to write (an existing file only with --force)"),
        force: bool = typer.Option(False, "--force", help="replace an existing --out file (default: refuse)"),
        seed: int = typer.Option(0, "--seed", help="seed of the draws that set the prior spread"),
        prior_draws: int = typer.Option(
            12, "--prior-draws", help="MMG models drawn from the regressions' scatter for the prior spread (>= 2)"
        ),
    ) -> None:
        """A profile for a single-screw, twin-screw or podded ship from its main particulars: published regressions give
        an MMG model, its manoeuvres are fitted into the profile's per-sample form, and the new
        ship's standard manoeuvres are printed for a sanity check before planning."""
        from primitives.particulars.build import Particulars, build_profile
        from primitives.particulars.trials import describe, imo_warnings, standard_trials

        check_out_file(out, (".toml",), "--out", "profile", replace=force)  # before the build's seconds of work
        if prior_draws < 2:
            raise UserError(f"--prior-draws {prior_draws}: give 2 or more (a spread needs two draws; 12 by default)")
        p = Particulars(
            name,
            length,
            beam,
            draught,
            block_coefficient,
            speed,
            rudder_area,
            propeller_diameter,
            pitch_ratio,
            rpm,
            mcr_kw,
            actuator,
        )
        try:
            built = build_profile(p, draws=prior_draws, seed=seed)
        except FloatingPointError as exc:
            raise UserError(
                f"these particulars give no usable model ({exc}); check --speed, --rudder-area and --propeller-diameter"
            ) from None
        figures = standard_trials(built.profile)
        atomic_write_text(out, built.text)
        print(
            f"wrote {out}: {name}, approach {60 * built.approach_rps:.1f} rpm at {speed:g} kn, sample time {built.profile.sample_time:g} s"
        )
        print("standard manoeuvres of the new profile (simulated; check them against what you know of the ship):")
        for line in describe(figures, length):
            print(f"  {line}")
        for note in built.notes:
            print(f"note: {note}", file=sys.stderr)
        for w in figures.warnings(length) + imo_warnings(figures, length, built.profile.cruise_speed_mps):
            print(f"warning: {w}", file=sys.stderr)
