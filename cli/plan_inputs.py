"""``plan``'s options as typed, checked and turned into the planner's and the design's inputs
(:func:`plan_inputs`), each bad one refused in one line before the map is loaded."""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from primitives.errors import UserError

if TYPE_CHECKING:  # annotations only: the command imports the library when it runs
    from expdesign.prior import ParameterPrior
    from maps.planoptions import PlanOptions


@dataclass(frozen=True)
class LatticeArgs:
    """The lattice options as given on the command line (the fields are the options' names)."""

    resolution: float | None
    headings: int
    heuristic: str
    margin: float
    split: bool
    size: str  # NORTHxEAST points
    run_in: float | None
    max_memory: float

    def size_points(self) -> tuple[int, int]:
        """``size`` as (north, east) points (checked by :func:`cli.options.validate_plan_options` first)."""
        ni, nj = (int(v) for v in self.size.lower().split("x"))
        return ni, nj

    def items(self) -> list[tuple[str, Any]]:
        """(option name, value) of every field."""
        return [(f.name, getattr(self, f.name)) for f in fields(self)]


@dataclass(frozen=True)
class OutputArgs:
    """Where and how the plan is written, as given on the command line."""

    out: Path
    seed: int
    vessel_name: str | None
    start_time: str | None
    no_export: bool


@dataclass(frozen=True)
class DesignArgs:
    """The experiment design's options as given on the command line (None: not given)."""

    criterion: str | None
    mean_subtraction: str | None
    trial_length: str | None  # seconds, or with a unit s, min or h
    prior_spread: float | None
    prior_file: Path | None
    prior_draws: int | None


@dataclass(frozen=True)
class DesignChoice:
    """The design ``plan`` runs (the defaults filled in, the criterion canonical, the trial length in seconds,
    a robust criterion's prior made): the keywords of :func:`maps.planner.plan_with_design` and of the drawer's
    early design (:func:`cli.plan_early.early_design`)."""

    criterion: str
    mean_subtraction: str
    trial_length_s: float | None
    seed: int
    parameter_prior: ParameterPrior | None

    def kwargs(self) -> dict[str, Any]:
        """The fields as keywords (the values themselves, not copies: the prior is keyed by its pickle)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def parse_point(text: str | None, what: str) -> tuple[float, float, float | None] | None:
    """``LAT,LON[,HEADING_DEG]`` -> (lat, lon, heading or None)."""
    if text is None:
        return None
    try:
        vals = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        vals = []
    if len(vals) not in (2, 3):
        raise UserError(f"--{what}: expected LAT,LON[,HEADING_DEG] in degrees (e.g. 60.16,24.96,180), got {text!r}")
    return vals[0], vals[1], (vals[2] if len(vals) == 3 else None)


def parse_counts(text: str | None) -> dict[str, int] | None:
    """``NAME=N,NAME=N`` -> dict."""
    if text is None:
        return None
    out: dict[str, int] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, val = part.partition("=")
        try:
            n = int(val)
        except ValueError:
            n = -1
        if not sep or not name or n < 0:
            raise UserError(f"--counts: expected NAME=N with N a whole number >= 0, got {part!r}")
        out[name.strip()] = n
    if not out:
        raise UserError("--counts: give at least one NAME=N")
    return out


def design_conflict(counts: str | None, scenario: str | None, **design: object) -> None:
    """Refuse design options (``--criterion``, ``--mean-subtraction``, ``--trial-length``, ``--prior-spread``,
    ``--prior-file``) beside ``--counts`` or ``--scenario``: those choose the manoeuvres without a design, so the
    options would be ignored without a word."""
    given = [f"--{k.replace('_', '-')}" for k, v in design.items() if v is not None]
    chooser = "--counts" if counts is not None else "--scenario" if scenario is not None else None
    if given and chooser:
        raise UserError(
            f"{given[0]}: sets the experiment design, but {chooser} chooses the manoeuvres without one: "
            f"drop {' and '.join(given)} or {chooser}"
        )


def check_lattice_and_outputs(lattice: LatticeArgs, outputs: OutputArgs, **others: Any) -> None:
    """:func:`cli.options.validate_plan_options` of the lattice and output options (``others``: the
    start, goal, counts and design options it checks as well)."""
    from cli.options import validate_plan_options

    validate_plan_options(
        resolution=lattice.resolution,
        margin=lattice.margin,
        headings=lattice.headings,
        size=lattice.size,
        run_in=lattice.run_in,
        max_memory=lattice.max_memory,
        out=outputs.out,
        seed=outputs.seed,
        vessel_name=outputs.vessel_name,
        start_time=outputs.start_time,
        no_export=outputs.no_export,
        **others,
    )


def plan_inputs(
    ship: str,
    start: str | None,
    goal: str | None,
    counts: str | None,
    scenario: str | None,
    given: DesignArgs,
    lattice: LatticeArgs,
    outputs: OutputArgs,
) -> tuple[PlanOptions, DesignChoice]:
    """The planner's options and the design of ``plan`` without --resume, every option refused in one line first."""
    from cli.options import duration_s
    from expdesign.dopt import canonical_criterion
    from maps.planoptions import PlanOptions

    trial_length = duration_s(given.trial_length, "--trial-length")
    design_conflict(
        counts,
        scenario,
        criterion=given.criterion,
        mean_subtraction=given.mean_subtraction,
        trial_length=trial_length,
        prior_spread=given.prior_spread,
        prior_file=given.prior_file,
    )
    criterion = "D" if given.criterion is None else given.criterion
    mean_subtraction = "complete" if given.mean_subtraction is None else given.mean_subtraction
    check_lattice_and_outputs(
        lattice,
        outputs,
        start=start,
        goal=goal,
        counts=counts,
        scenario=scenario,
        criterion=criterion,
        mean_subtraction=mean_subtraction,
        trial_length=trial_length,
    )
    criterion = canonical_criterion(criterion)  # checked by validate_plan_options: "local-D" is "D"
    if counts is not None and scenario is not None:
        raise UserError("--counts and --scenario both choose the manoeuvres: give one of them")
    opts = PlanOptions(
        resolution=lattice.resolution,
        headings=lattice.headings,
        heuristic=lattice.heuristic,
        margin=lattice.margin,
        split=lattice.split,
        size=lattice.size_points(),
        run_in_s=lattice.run_in,
        max_memory_gib=lattice.max_memory,
    )
    opts.check()
    seed = outputs.seed
    prior = _prior(ship, criterion, given.prior_spread, given.prior_file, given.prior_draws, seed)
    design = DesignChoice(
        criterion=criterion, mean_subtraction=mean_subtraction, trial_length_s=trial_length, seed=seed, parameter_prior=prior
    )
    return opts, design


def _prior(
    ship: str, criterion: str, spread: float | None, path: Path | None, draws: int | None, seed: int
) -> ParameterPrior | None:
    """The parameter prior of a robust criterion (None for a local one), refused in one line when bad."""
    from cli.options import check_prior_options
    from expdesign.dopt import ROBUST
    from expdesign.prior import make_prior
    from primitives.ship import load_profile

    profile = load_profile(ship)
    check_prior_options(criterion, spread, path, draws, profile_prior=profile.prior_std is not None)
    if criterion not in ROBUST:
        return None
    return make_prior(profile, spread, path, draws, seed)
