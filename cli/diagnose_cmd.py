"""``shiptrial diagnose``: locate a simulation-vs-recording mismatch, name the missing physics,
model it and show the fit improve (issue 6)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from primitives.io import dumps


def _split(values: list[str] | None) -> list[str]:
    out: list[str] = []
    for v in values or []:
        out += [x.strip() for x in v.split(",") if x.strip()]
    return out


def _load_params(path: str, profile):
    """Baseline parameters: a parameter set of the ship (``nominal``), a built-in profile with the
    same model terms, a profile TOML/JSON (its simulation set) or JSON {"theta": [...]} / {surge: [..], ...}."""
    import numpy as np

    from diagnose.recording import RecordingError
    from primitives.ship import DOFS, ProfileError, builtin_profiles, load_profile

    p = Path(path)
    if not p.exists():
        if path in profile.parameter_sets:
            return profile.params(path)
        same = [n for n in builtin_profiles() if load_profile(n).model_terms == profile.model_terms]
        if path in same:
            return load_profile(path).params()
        raise RecordingError(
            f"--params {path!r}: no such file, and not a parameter set of ship {profile.name!r} "
            f"({', '.join(sorted(profile.parameter_sets))}) nor a built-in profile with its model "
            f"terms ({', '.join(same)}); give one of those names, a profile TOML/JSON or a JSON with 'theta'"
        )
    try:
        other = load_profile(p)
        if other.model_terms != profile.model_terms:
            raise RecordingError(f"{p}: its model terms differ from ship {profile.name!r}; pass it as --ship instead")
        return other.params()
    except ProfileError:
        pass
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{p}: --params must be a profile TOML/JSON or JSON with 'theta' ({exc})") from None
    if isinstance(data, dict) and "theta" in data:
        vec = np.asarray(data["theta"], float)
    elif isinstance(data, dict) and all(d in data for d in DOFS):
        vec = np.asarray([x for d in DOFS for x in data[d]], float)
    else:
        raise RecordingError(f"{p}: --params JSON needs a 'theta' list or 'surge', 'sway', 'yaw' lists")
    if vec.shape != (profile.model.n_params,):
        raise RecordingError(f"{p}: field 'theta' has {vec.size} values; ship {profile.name!r} needs {profile.model.n_params}")
    return vec


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        recordings: list[str] = typer.Argument(
            ...,
            help="recordings to diagnose (.csv with the columns of docs/commands/diagnose.md: 'Recordings for diagnose'; or MARIN .dat)",
        ),
        ship: str = typer.Option(..., "--ship", help="built-in profile name or a .toml/.json profile file"),
        params: str | None = typer.Option(
            None,
            "--params",
            help="baseline parameters: a parameter set of the ship (e.g. nominal), a built-in profile name, a profile TOML/JSON or a JSON with 'theta'",
        ),
        fit_on: list[str] | None = typer.Option(
            None, "--fit-on", help="fit the baseline on these recordings first (repeat or comma-separate)"
        ),
        validate: list[str] | None = typer.Option(
            None, "--validate", help="held-out recordings for the before/after fit (repeat or comma-separate)"
        ),
        out: Path | None = typer.Option(
            None, "--out", help="directory for report.txt, diagnosis.json, model.json and residual plots"
        ),
        json_out: bool = typer.Option(False, "--json", help="print the diagnosis as JSON"),
        resample: bool = typer.Option(
            False, "--resample", help="interpolate recordings onto the ship's sample time (default: refuse)"
        ),
        environment: str | None = typer.Option(
            None,
            "--environment",
            help="where every run was recorded: sea, basin or towing-tank (no current, no wind); overrides '# environment:'",
        ),
        rudder_sign: str | None = typer.Option(
            None,
            "--rudder-sign",
            help="the recordings' rudder convention: port-positive or starboard-positive (converted to the ship's); "
            "overrides '# rudder_sign:'",
        ),
        yaw_rate_sign: str | None = typer.Option(
            None,
            "--yaw-rate-sign",
            help="the recordings' yaw rate convention: starboard-positive (r = dpsi/dt, the default) or port-positive "
            "(converted); overrides '# yaw_rate_sign:'",
        ),
    ) -> None:
        """Diagnose recordings against a ship model: locate, name and model the missing physics."""
        from cli.errors import warn_ship
        from cli.options import validate_diagnose_options
        from diagnose import report
        from diagnose.api import run
        from diagnose.recording import load_recording
        from diagnose.recording_checks import conform, ship_notes, with_conventions
        from diagnose.stability import check_baseline
        from primitives.ship import load_profile

        validate_diagnose_options(
            recordings={"RECORDING": _split(recordings), "--fit-on": _split(fit_on), "--validate": _split(validate)},
            params=params,
            out=out,
            environment=environment,
            rudder_sign=rudder_sign,
            yaw_rate_sign=yaw_rate_sign,
        )
        profile = load_profile(ship)
        profile.require_planar("shiptrial diagnose")
        warn_ship(profile)
        theta = _load_params(params, profile) if params else None

        def load(paths: list[str]):
            recs = []
            for p in paths:
                # unused input columns never split a run; --yaw-rate-sign is applied before r is checked against psi
                recs += load_recording(p, inputs=profile.inputs, yaw_rate_sign=yaw_rate_sign)
            recs = with_conventions(recs, environment, rudder_sign)  # the options stand for every file's header lines
            return conform(recs, profile, resample=resample)  # Froude scale, sample time, input units: said in notes

        recs = load(_split(recordings))
        fit_recs = load(_split(fit_on)) or None
        val_recs = load(_split(validate)) or None
        for rec in recs + (fit_recs or []) + (val_recs or []):
            for note in ship_notes(rec):  # what conform attached (also in the report's notes), before the minutes of fitting
                typer.echo(f"warning: {note}", err=True)
        # the given baseline must simulate the runs it is first simulated on (the --fit-on runs, else
        # the diagnosed and validation runs): when it diverges, the profile or --params is at fault
        where = f"ship profile {profile.name!r} ({ship})" + (f" with --params {params}" if params else "")
        check_baseline(profile, profile.params(theta), fit_recs or recs + (val_recs or []), where)
        d = run(recs, profile, theta=theta, fit_on=fit_recs, validate=val_recs)
        paths = {}
        if out is not None:
            from primitives.io import atomic_output_dir

            with atomic_output_dir(out) as tmp:  # a failed report never leaves a mix of old and new files
                written = report.write_all(d, tmp, final_dir=out)
            paths = {k: out / v.relative_to(tmp) for k, v in written.items()}
        # without --out nothing is written (no scratch directory left behind in /tmp)
        if json_out:
            typer.echo(dumps(report.to_json(d, str(paths["model"]) if "model" in paths else None)))
            return
        typer.echo(report.to_text(d))
        if paths:
            typer.echo(f"wrote {', '.join(str(p) for p in paths.values())}")
        else:
            typer.echo("no files written: pass --out DIR for report.txt, diagnosis.json, model.json and the residual plots")
