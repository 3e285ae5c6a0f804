"""Up-front checks of every command's options: one call at the top of each command, before any work.

Each function raises :class:`primitives.errors.UserError` with one line naming the option, the
value, its unit and what to give instead (see :mod:`primitives.validate`).
"""

from __future__ import annotations

import math
import re
import unicodedata
from pathlib import Path

from primitives.errors import UserError
from primitives.io import FIGURE_SUFFIXES, check_figure_file, check_out_file, check_out_path, check_replaceable_dir
from primitives.validate import MAX_MC_SAMPLES, check_counts, check_monte_carlo, in_range, one_of, positive, whole


def check_plot_path(path: Path | None, option: str = "--plot", *, writer: str | None = None, force: bool = False) -> None:
    """A figure path; with ``writer`` (the Creator mark the command saves) an existing figure is replaced only if
    that command drew it, or with ``--force`` (:func:`primitives.io.check_figure_file`)."""
    if path is None:
        return
    if writer is None:
        check_out_file(path, FIGURE_SUFFIXES, option, "figure")
    else:
        check_figure_file(path, option, writer, force=force)


def check_input_file(path: Path | str | None, option: str, what: str, kind: str) -> None:
    """An input file that exists and is a file (not a directory); ``kind`` names it (plan, map, ...)."""
    if path is None:
        return
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{option} {p}: is a directory; give {what}")
    if not p.exists():
        raise UserError(f"{option} {p}: no such {kind} file; give {what}")


DURATION_UNITS = {
    "": 1.0,
    "s": 1.0,
    "sec": 1.0,
    "secs": 1.0,
    "seconds": 1.0,
    "min": 60.0,
    "mins": 60.0,
    "minutes": 60.0,
    "h": 3600.0,
    "hr": 3600.0,
    "hours": 3600.0,
}
_DURATION = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|[-+]?inf|nan)\s*([a-z]*)\s*$", re.IGNORECASE)


def duration_s(text: str | None, option: str, error: type[UserError] = UserError) -> float | None:
    """A duration option in seconds: a number (seconds) or a number with a unit s, min or h
    ("1800", "30min", "0.5 h"); anything else refused naming the forms it takes."""
    if text is None:
        return None
    m = _DURATION.match(text)
    unit = m.group(2).lower() if m else None
    if m is None or unit not in DURATION_UNITS:
        raise error(f"{option} {text!r}: give the duration in seconds (e.g. 1800) or with a unit s, min or h (e.g. 30min, 0.5h)")
    return float(m.group(1)) * DURATION_UNITS[unit]


def check_design_choices(
    criterion: str, mean_subtraction: str, trial_length: float | None, error: type[UserError] = UserError
) -> None:
    """The design's criterion, mean subtraction and trial length (``design`` and ``plan``)."""
    one_of(criterion, "--criterion", ("D", "A", "E", "local-D", "bayes-D", "maximin-D"), error)
    one_of(mean_subtraction, "--mean-subtraction", ("none", "batchwise", "complete"), error)
    if trial_length is not None:
        in_range(trial_length, "--trial-length", 1.0, 30 * 86400.0, "s", error)


def check_prior_options(
    criterion: str,
    spread: float | None,
    path: Path | None,
    draws: int | None,
    error: type[UserError] = UserError,
    profile_prior: bool = False,
) -> None:
    """A robust criterion has one prior (``--prior-spread``, ``--prior-file``, or the profile's own
    ``[prior] std`` when ``profile_prior``); a local one none, nor ``--prior-draws`` (None: not given)."""
    robust = criterion in ("bayes-D", "maximin-D")
    if spread is not None and path is not None:
        raise error("--prior-spread and --prior-file both give the prior: give one of them")
    if robust and spread is None and path is None and not profile_prior:
        raise error(
            f"--criterion {criterion} designs over parameter draws: give --prior-spread FRACTION (e.g. 0.3) or --prior-file PATH"
            " (a profile made by `shiptrial profile new` carries its own prior)"
        )
    if not robust and (spread is not None or path is not None or draws is not None):
        given = "--prior-spread" if spread is not None else "--prior-file" if path is not None else "--prior-draws"
        raise error(f"{given} is for the robust criteria: add --criterion bayes-D or maximin-D")
    if spread is not None and not (math.isfinite(spread) and 0.0 < spread <= 1.0):
        raise error(
            f"--prior-spread {spread:g}: give a fraction in (0, 1], e.g. 0.3 for parameters within +-30 % of the profile's"
        )
    if draws is not None:
        whole(draws, "--prior-draws", 2, 100_000, "parameter draws", error)


def check_vessel_name(name: str | None, rtz: bool, error: type[UserError] = UserError) -> None:
    """A ship's name is one line of printable text: a control character (a pasted escape or
    newline) would make the RTZ route invalid XML that the ECDIS refuses. ``rtz``: an RTZ route
    will be written, so the name must fit its limit (refused here, before any other file is written)."""
    if name is None:
        return
    if not name.strip():
        raise error("--vessel-name is empty: give the ship's name, e.g. --vessel-name 'MT Example', or leave the option out")
    bad = next((c for c in name if unicodedata.category(c) == "Cc"), None)
    if bad is not None:
        raise error(f"--vessel-name {name!r}: holds the control character {bad!r}; give the name as one line of plain text")
    if rtz:
        from maps.export.rtz import VESSEL_NAME_MAX

        shown = " ".join(name.split())  # as the exports write it
        if len(shown) > VESSEL_NAME_MAX:
            raise error(
                f"--vessel-name {shown!r} has {len(shown)} characters; the RTZ route holds at most "
                f"{VESSEL_NAME_MAX}: give a shorter name"
            )


def check_start_time(text: str | None, option: str) -> None:
    """A UTC start time in ISO 8601 within 1970..2199: a year outside is a typo (0226 for 2026),
    and near year 9999 the schedule's clock times would overflow the calendar."""
    if text is None:
        return
    from maps.export import ExportError
    from maps.export._common import resolve_start

    try:
        t0 = resolve_start(None, text)
    except ExportError:
        raise ExportError(
            f"{option} {text!r}: not an ISO 8601 time; give the UTC start, e.g. {option} 2026-06-01T08:00Z"
        ) from None
    if not 1970 <= t0.year <= 2199:
        raise ExportError(
            f"{option} {text!r}: year {t0.year} is not a trial date; give the UTC start, e.g. {option} 2026-06-01T08:00Z"
        )


def validate_primitives_options(plot: Path | None, force: bool = False) -> None:
    from cli.primitives_cmd import PLOT_WRITER

    check_plot_path(plot, writer=PLOT_WRITER, force=force)


def validate_design_options(
    *,
    criterion: str,
    mean_subtraction: str,
    trial_length: float | None,
    monte_carlo: int,
    mc_samples: int,
    seed: int,
    out: Path | None,
    psi_switch: float | None,
    min_frac: float | None,
    max_frac: float | None,
    noisy_moments: int,
) -> None:
    from expdesign.errors import DesignError

    check_design_choices(criterion, mean_subtraction, trial_length, DesignError)
    if monte_carlo:
        check_monte_carlo(monte_carlo, mc_samples, error=DesignError)
    else:
        whole(monte_carlo, "--monte-carlo", 0, 0, "runs", DesignError)
        whole(mc_samples, "--mc-samples", 10, MAX_MC_SAMPLES, "samples per experiment", DesignError)
    whole(seed, "--seed", 0, 2**63 - 1, "", DesignError)
    if psi_switch is not None:
        in_range(psi_switch, "--psi-switch", 0.01, math.pi, "rad", DesignError)
    for name, v in (("--min-frac", min_frac), ("--max-frac", max_frac)):
        if v is not None:
            in_range(v, name, 0.0, 1.0, "", DesignError)  # a share of the trial
    if min_frac is not None and max_frac is not None and min_frac > max_frac:
        raise DesignError(f"--min-frac {min_frac:g} is above --max-frac {max_frac:g}; give min <= max")
    whole(noisy_moments, "--noisy-moments", 0, 10_000, "simulations", DesignError)
    if out is not None:
        check_replaceable_dir(out)


def validate_export_options(
    *, plan_file: Path, fmt: str, out: Path | None, sea_map: Path | None, vessel_name: str | None = None, start: str | None = None
) -> None:
    """Export: the format known, the extension of a one-format --out matching it, the plan never overwritten."""
    from maps.export import FORMATS, ExportError

    fmt_l = fmt.lower()
    if fmt_l != "all" and fmt_l not in FORMATS:
        raise ExportError(f"--format {fmt!r} is unknown: choose one of {', '.join(FORMATS)} or all")
    check_vessel_name(vessel_name, fmt_l in ("rtz", "all"), ExportError)
    check_start_time(start, "--start")
    check_input_file(plan_file, "PLAN", "the plan.json written by plan-trial --out DIR", "plan")
    if sea_map is not None:  # a bundled map's name (open-sea) is a map, as --help and plan's --map say
        from maps.geo import map_source

        sea_map = map_source(sea_map)
    check_input_file(sea_map, "--map", "a GeoJSON sea map or a bundled map's name (helsinki, open-sea)", "map")
    if out is None:
        return
    if fmt_l == "all" or out.is_dir():
        check_out_path(out, option="--out")
        return
    allowed = {FORMATS[fmt_l], ".pdf"} if fmt_l == "card" else {FORMATS[fmt_l]}
    if not out.suffix:  # as every other output file (sweep tables, plots): the extension names the format
        also = ", its PDF beside it" if fmt_l == "card" else ""
        raise ExportError(
            f"--out {out}: no extension: give {out}{FORMATS[fmt_l]} (the {fmt_l} file{also}) or an existing "
            "directory to write the default name into"
        )
    if out.suffix.lower() not in allowed:
        raise ExportError(
            f"--out {out}: extension {out.suffix!r} does not match --format {fmt_l} ({' or '.join(sorted(allowed))})"
        )
    if out.resolve() == plan_file.resolve():
        raise ExportError(f"--out {out}: is the plan being exported; choose another file")
    check_out_path(out, kind="file")


def validate_sweep_options(*, config: Path, out: Path, plot: Path | None, force: bool = False, partial: bool = False) -> None:
    """The table and the plot (``--plot``, else beside the table), and with ``partial`` (``--keep-partial``) the
    names an interrupted sweep writes: each may replace only a sweep's own file unless ``force``."""
    from expdesign.sweep import check_outputs

    check_input_file(config, "CONFIG", "a sweep TOML file", "sweep")
    check_outputs(out, plot or out.with_suffix(".png"), replace=force)
    if partial:
        cut = out.with_name(f"{out.stem}.partial{out.suffix}")
        check_outputs(cut, plot or cut.with_suffix(".png"), replace=force)


def validate_diagnose_options(
    *,
    recordings: dict[str, list[str]],
    params: str | None,
    out: Path | None,
    environment: str | None = None,
    rudder_sign: str | None = None,
    yaw_rate_sign: str | None = None,
) -> None:
    """``recordings``: option name (RECORDING, --fit-on, --validate) -> its files; ``environment``,
    ``rudder_sign`` and ``yaw_rate_sign``: the values of --environment, --rudder-sign and
    --yaw-rate-sign (the header values they stand for)."""
    from diagnose.recording import ENVIRONMENTS, RUDDER_SIGNS, YAW_RATE_SIGNS

    for option, value, allowed in (
        ("--environment", environment, ENVIRONMENTS),
        ("--rudder-sign", rudder_sign, RUDDER_SIGNS),
        ("--yaw-rate-sign", yaw_rate_sign, YAW_RATE_SIGNS),
    ):
        if value is not None and value not in allowed:
            raise UserError(f"{option} {value}: must be one of {', '.join(allowed)}")
    for option, paths in recordings.items():
        for r in paths:
            check_input_file(r, option, "a recording file (.csv or MARIN .dat)", "recording")
    check_runs_once(recordings)
    if params is not None and Path(params).is_dir():  # a missing file may be a parameter set's name: checked with the ship
        raise UserError(
            f"--params {params}: is a directory; give a parameter set name, a profile TOML/JSON or a JSON with 'theta'"
        )
    if out is not None:
        check_out_path(out)


def check_runs_once(recordings: dict[str, list[str]]) -> None:
    """Each run once among the diagnosed, --fit-on and --validate recordings: a run given twice (the
    same file, another path to it, or a copy with identical content) is scored in-sample where the
    report says held out, or fitted on twice."""
    import hashlib

    seen: dict[tuple, tuple[str, str]] = {}
    for option, paths in recordings.items():
        for r in paths:
            p = Path(r)
            digest = hashlib.sha256(p.read_bytes()).hexdigest()
            for key, why in (((p.resolve(),), "the same file"), (("sha256", digest), "identical content")):
                if key in seen:
                    o_opt, o_path = seen[key]
                    raise UserError(
                        f"{option} {r}: the same run as {o_opt} {o_path} ({why}); a run given twice is "
                        "scored or fitted on twice (in-sample where the report says held out): give each run once"
                    )
            seen[(p.resolve(),)] = seen[("sha256", digest)] = (option, r)


def _point(text: str | None, option: str) -> None:
    if text is None:
        return
    parts = text.replace(" ", "").split(",")
    names = ("latitude", "longitude", "heading")
    ranges = ((-90.0, 90.0, "deg"), (-180.0, 180.0, "deg"), (-360.0, 360.0, "deg"))
    if len(parts) not in (2, 3):
        raise UserError(f"{option}: expected LAT,LON[,HEADING_DEG] in degrees (e.g. 60.16,24.96,180), got {text!r}")
    for part, name, (lo, hi, unit) in zip(parts, names, ranges):
        in_range(part, f"{option} {name}", lo, hi, unit)


def validate_plan_options(
    *,
    resolution: float | None,
    margin: float,
    headings: int,
    start: str | None,
    goal: str | None,
    counts: str | None,
    size: str,
    out: Path,
    seed: int = 0,
    scenario: str | None = None,
    criterion: str = "D",
    mean_subtraction: str = "complete",
    trial_length: float | None = None,
    run_in: float | None = None,
    max_memory: float = 2.0,
    vessel_name: str | None = None,
    start_time: str | None = None,
    no_export: bool = False,
) -> None:
    """Every ``plan`` option checked before the map is loaded (the lattice's memory estimate is the
    planner's, once it knows the map)."""
    if scenario is not None:
        from maps.planner import SCENARIOS  # only here: the planner's import is the slow part of a refusal

        one_of(scenario, "--scenario", SCENARIOS)
    check_design_choices(criterion, mean_subtraction, trial_length)
    if run_in is not None:  # held for the whole run-in: an hour is already far past any settling time
        in_range(run_in, "--run-in", 0.0, 3600.0, "s (steady run before each execute point)")
    if positive(max_memory, "--max-memory", "GiB") > 1024:
        raise UserError(
            f"--max-memory: {max_memory:g} GiB is more than any machine has; give the memory the planner may use, in GiB"
        )
    check_vessel_name(vessel_name, rtz=not no_export)
    check_start_time(start_time, "--start-time")
    if resolution is not None:
        if positive(resolution, "--resolution", "m (lattice spacing)") > 1e5:
            raise UserError(f"--resolution: {resolution:g} m is wider than any sea map; give the lattice spacing in metres")
    in_range(margin, "--margin", 0.0, 1e4, "m (safety margin around the hull)")
    if headings not in (4, 8, 16):
        raise UserError(f"--headings: must be 4, 8 or 16 lattice headings, got {headings}")
    _point(start, "--start")
    _point(goal, "--goal")
    try:
        ni, nj = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise UserError(f"--size: expected NORTHxEAST whole numbers, e.g. 35x44, got {size!r}") from None
    for n, what in ((ni, "NORTH"), (nj, "EAST")):
        whole(n, f"--size {what}", 3, 2000, "lattice points")
    if counts is not None:
        parsed = {}
        for part in filter(None, (p.strip() for p in counts.split(","))):
            name, _, val = part.partition("=")
            if val.strip().lstrip("+").isdigit():
                parsed[name.strip()] = int(val)
        check_counts(parsed)
    whole(seed, "--seed", 0, 2**63 - 1)
    check_out_path(out)


def validate_detect_prior_options(
    *,
    out: Path,
    bootstrap: int,
    seed: int,
    n_rdot: float | None = None,
    i_z: float | None = None,
    noise_model: str | None = None,
    force: bool = False,
) -> None:
    from identify.detect.yawmodel import check_prior_out

    check_prior_out(out, "--out", force=force)  # also refuses a directory
    if noise_model is not None:
        from identify.detect.priorfit import check_noise_model  # the library's check, read only when the option is given

        check_noise_model(noise_model)
    if bootstrap != 0:  # 0: no bootstrap; one refit is no spread
        whole(bootstrap, "--bootstrap", 2, 256, "refits (or 0: no bootstrap)")
    whole(seed, "--seed", 0, 2**63 - 1)
    _validate_hull_inertia(n_rdot, i_z)


def _validate_hull_inertia(n_rdot: float | None, i_z: float | None) -> None:
    """``--n-rdot`` and ``--i-z`` of detect-prior and detect."""
    if n_rdot is not None:
        in_range(n_rdot, "--n-rdot", -1e12, -1.0, "kg m^2 (the added yaw inertia N_rdot is negative, e.g. -28.7e6)")
    if i_z is not None:
        in_range(i_z, "--i-z", 1.0, 1e13, "kg m^2 (the rigid body's yaw inertia, positive, e.g. 33.7e6)")


def validate_detect_options(
    *,
    plot: Path | None,
    false_alarm: float,
    min_change: float,
    seed: int,
    n_rdot: float | None = None,
    i_z: float | None = None,
    force: bool = False,
    one_figure: bool = True,
) -> None:
    from identify.detect.api import PLOT_WRITER

    # beyond PLOT_PANELS recordings --plot itself is never written (one file per recording, checked once read):
    # only its extension is checked here, so a user's file of that name is not refused for nothing
    check_plot_path(plot, writer=PLOT_WRITER if one_figure else None, force=force)
    _validate_hull_inertia(n_rdot, i_z)
    in_range(false_alarm, "--false-alarm", 1e-4, 0.5)  # a probability per recording
    in_range(min_change, "--min-change", 0.005, 1.0)  # relative: 0.05 = 5 %
    whole(seed, "--seed", 0, 2**63 - 1)


def validate_mass_options(*, z_f: float | None) -> None:
    """``mass`` options that are numbers (the files and --known-load are checked where they are read)."""
    if z_f is not None:
        in_range(z_f, "--z-f", -10.0, 10.0, "m (minus the roll centre's depth below the waterline: -0.03 = 3 cm below)")


def validate_mass_sim_options(*, out: Path, seed: int) -> None:
    whole(seed, "--seed", 0, 2**63 - 1)
    check_out_path(out, option="OUT")  # mass-sim's output directory is its argument, not an --out option
    check_replaceable_dir(out, option="OUT")
