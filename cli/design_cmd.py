"""``shiptrial design``: D/A/E-optimal primitive mix, rounding, Monte Carlo check, report."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from primitives.io import dumps

if TYPE_CHECKING:
    from expdesign.api import Design
    from expdesign.mc_parallel import MCEvaluation
    from expdesign.prior import ParameterPrior
    from primitives.library import Primitive
    from primitives.ship import ShipProfile


def register(app: typer.Typer) -> None:
    @app.command("design")
    def design(
        ship: str = typer.Option("model-ship", "--ship", help="built-in profile name or a .toml/.json profile file"),
        criterion: str = typer.Option(
            "D",
            "--criterion",
            help="D (= local-D), A, E, or the robust bayes-D (mean log det over the prior's draws) "
            "or maximin-D (best worst-case D-efficiency over them)",
        ),
        mean_subtraction: str = typer.Option(
            "complete", "--mean-subtraction", help="instrument mean removal: none, batchwise (7.53) or complete (7.57)"
        ),
        trial_length_text: str | None = typer.Option(
            None,
            "--trial-length",
            help="trial length: seconds, or with a unit s, min or h (1800, 30min, 0.5h; default: every primitive once)",
        ),
        monte_carlo: int = typer.Option(500, "--monte-carlo", help="Monte Carlo runs per design (0 skips the evaluation)"),
        mc_samples: int = typer.Option(1000, "--mc-samples", help="samples per Monte Carlo experiment (thesis: 1000 = 125 s)"),
        seed: int = typer.Option(0, "--seed", help="seed of every random draw (starts, Monte Carlo)"),
        out: Path | None = typer.Option(
            None, "--out", help="directory for report.md, design.json and figures (default: write no files)"
        ),
        json_out: bool = typer.Option(False, "--json", help="print the report JSON"),
        sensitivity: bool = typer.Option(
            False, "--sensitivity", help="add the model-ship sensitivity study (zig-zag period, sway, noisy moments)"
        ),
        psi_switch: float | None = typer.Option(
            None, "--psi-switch", help="model-ship zig-zag switching heading in rad (default 0.5)"
        ),
        min_frac: float | None = typer.Option(None, "--min-frac", help="minimum share of every primitive"),
        max_frac: float | None = typer.Option(None, "--max-frac", help="maximum share of every primitive"),
        noisy_moments: int = typer.Option(
            0, "--noisy-moments", help="estimate the moments from this many noisy simulations (0: noise-free)"
        ),
        scheduler: str | None = typer.Option(
            None,
            "--scheduler",
            help="'inline', 'local' or a Dask scheduler address for the Monte Carlo (default: $SHIPTRIAL_SCHEDULER, else all local cores)",
        ),
        mc_protocol: str = typer.Option(
            "continuous",
            "--mc-protocol",
            help="continuous (one experiment per run, primitives back to back; "
            "as Ljungberg 2022, section 9.1.2) or piecewise (every primitive restarts from its nominal state)",
        ),
        mc_order: str = typer.Option(
            "library",
            "--mc-order",
            help="order of a fixed design's primitives in a continuous experiment: library "
            "(one sequence, as Ljungberg's (2022) optimized input), given (the shares' order) or random (drawn per run)",
        ),
        mc_settle: int = typer.Option(0, "--mc-settle", help="settling samples between primitives in a continuous experiment"),
        mc_min_block: int = typer.Option(
            40, "--mc-min-block", help="shortest sub-experiment in samples (shorter shares are dropped or raised)"
        ),
        mc_estimator: str = typer.Option(
            "oe",
            "--mc-estimator",
            help="oe (output-error refinement of the IV estimate; the IV figures are reported "
            "beside it) or iv (the thesis's estimator only)",
        ),
        keep_partial: bool = typer.Option(
            False, "--keep-partial", help="on Ctrl-C or a lost worker, write the report of the finished runs, marked partial"
        ),
        prior_spread: float | None = typer.Option(
            None,
            "--prior-spread",
            help="robust criteria: every parameter drawn within +-FRACTION of the profile's value (0 < FRACTION <= 1)",
        ),
        prior_file: Path | None = typer.Option(
            None,
            "--prior-file",
            help="robust criteria: JSON with parameter_names and draws, or a covariance (also a model.json's parameter_covariance)",
        ),
        prior_draws: int | None = typer.Option(
            None, "--prior-draws", help="parameter draws of the robust criteria (default 200; a prior file's draws as given)"
        ),
        prior_truths: int | None = typer.Option(
            None,
            "--prior-truths",
            help="robust criteria: truths drawn from the prior for the Monte Carlo (default 20; --monte-carlo runs shared)",
        ),
    ) -> None:
        """Choose the mix of manoeuvres that maximises information, and check it by Monte Carlo."""
        from cli.options import duration_s, validate_design_options, whole
        from expdesign.errors import DesignError

        trial_length = duration_s(trial_length_text, "--trial-length", DesignError)
        validate_design_options(
            criterion=criterion,
            mean_subtraction=mean_subtraction,
            trial_length=trial_length,
            monte_carlo=monte_carlo,
            mc_samples=mc_samples,
            seed=seed,
            out=out,
            psi_switch=psi_switch,
            min_frac=min_frac,
            max_frac=max_frac,
            noisy_moments=noisy_moments,
        )
        _check_mc_options(mc_protocol, mc_order, mc_estimator, mc_settle, mc_min_block, mc_samples)
        from cli.options import check_prior_options
        from expdesign.dopt import ROBUST
        from expdesign.prior import make_prior
        from primitives.ship import load_profile

        profile = load_profile(ship)
        check_prior_options(criterion, prior_spread, prior_file, prior_draws, DesignError, profile.prior_std is not None)
        if prior_truths is not None and (not monte_carlo or criterion not in ("bayes-D", "maximin-D")):
            raise DesignError(
                "--prior-truths is for the Monte Carlo of a robust design: add --monte-carlo R and a robust --criterion"
            )
        prior_truths = 20 if prior_truths is None else prior_truths
        whole(prior_truths, "--prior-truths", 1, 10_000, "truths", DesignError)
        prior = make_prior(profile, prior_spread, prior_file, prior_draws, seed) if criterion in ROBUST else None
        lib, thesis, d = _design_step(
            profile, criterion, mean_subtraction, trial_length, seed, psi_switch, min_frac, max_frac, noisy_moments, prior
        )
        ev = None
        if monte_carlo:
            ev = _monte_carlo_step(
                profile,
                lib,
                d,
                monte_carlo,
                seed,
                scheduler,
                mc_samples,
                mean_subtraction,
                mc_protocol,
                mc_order,
                mc_settle,
                mc_min_block,
                mc_estimator,
            )
            if not ev.complete and not (keep_partial and ev.results):
                _fail(
                    ev,
                    "no run finished, nothing to keep: nothing written"
                    if keep_partial
                    else "nothing written (--keep-partial writes the finished runs, marked partial)",
                )
        sens = _sensitivity_step(profile, seed) if sensitivity else None
        from expdesign.report import report_dict

        doc = report_dict(d, ev, sens, thesis)
        if d.robust and monte_carlo:
            doc["prior_truths_drawn"], doc["prior_monte_carlo"] = _prior_mc_step(
                profile,
                lib,
                d,
                prior,
                prior_truths,
                monte_carlo,
                seed,
                mc_samples,
                mean_subtraction,
                mc_estimator,
                {"protocol": mc_protocol, "order": mc_order, "settle": mc_settle, "min_block": mc_min_block},
            )
        paths = _write_step(out, doc, d, ev, thesis) if out is not None else {}
        if ev is not None and not ev.complete:
            _fail(
                ev,
                f"partial report of the finished runs written to {paths['json']}"
                if paths
                else "partial results not written (no --out)",
            )
        from primitives.library import library_notes

        for note in library_notes(profile):  # on stderr, as the design's warnings: a manoeuvre family its library lacks
            typer.echo(f"note: {note}", err=True)
        _print_step(profile.name, d, doc, ev, paths, json_out)


def _design_step(
    profile: ShipProfile,
    criterion: str,
    mean_subtraction: str,
    trial_length: float | None,
    seed: int,
    psi_switch: float | None,
    min_frac: float | None,
    max_frac: float | None,
    noisy_moments: int,
    prior: ParameterPrior | None,
) -> tuple[list[Primitive], dict[str, float] | None, Design]:
    """The ship's design library, the thesis's shares (model ship) and the design."""
    from expdesign.api import default_library, run_design
    from expdesign.sensitivity import THESIS_SHARES

    profile.require_planar("shiptrial design")
    lib = default_library(profile, psi_switch)
    thesis = THESIS_SHARES if profile.library == "thesis-model-ship" else None
    d = run_design(
        profile,
        lib,
        criterion=criterion,
        mean_subtraction=mean_subtraction,
        trial_length_s=trial_length,
        min_frac=min_frac,
        max_frac=max_frac,
        seed=seed,
        disturbed_realisations=noisy_moments,
        references={"thesis": thesis} if thesis else None,
        parameter_prior=prior,
    )
    return lib, thesis, d


def _prior_mc_step(
    profile: ShipProfile,
    lib: list[Primitive],
    d: Design,
    prior: ParameterPrior,
    truths: int,
    runs: int,
    seed: int,
    samples: int,
    mean_subtraction: str,
    estimator: str,
    protocol: dict,
) -> tuple[str, dict]:
    """Where the truths come from and the local-D and robust mixes against them, the runs shared
    among them: ``truths`` fresh draws of the prior (its TRUTHS stream, held out from the draws
    designed on), or for a file's fixed draws its first ``truths`` (in-sample); never more truths
    than ``runs``, so at most ``runs`` runs in all; ``protocol``: the --mc-* options."""
    from expdesign.prior import TRUTHS
    from expdesign.prior_mc import prior_monte_carlo

    designs = {"local-D": d.robust["local_weights"], d.criterion: d.weights}
    truths = min(truths, runs)
    fresh = prior.fresh(truths, TRUTHS)
    if fresh is None:
        thetas, label = prior.draws[: min(truths, prior.n_draws)], "in-sample: draws of the file the mix was designed on"
    else:
        thetas, label = fresh, "held out: fresh draws from an independent seed stream"
    n = len(thetas)
    return label, prior_monte_carlo(
        profile,
        designs,
        thetas,
        max(1, runs // n),
        seed,
        primitives=lib,
        n_samples=samples,
        mean_subtraction=mean_subtraction,
        estimator=estimator,
        **protocol,
    )


def _monte_carlo_step(
    profile: ShipProfile,
    lib: list[Primitive],
    d: Design,
    runs: int,
    seed: int,
    scheduler: str | None,
    samples: int,
    mean_subtraction: str,
    protocol: str,
    order: str,
    settle: int,
    min_block: int,
    estimator: str,
) -> MCEvaluation:
    """The Monte Carlo of the optimized design against the random and uniform ones (and the
    thesis's shares for the model ship), with its speed line printed."""
    from expdesign.mc_parallel import evaluate_designs_parallel
    from expdesign.sensitivity import THESIS_SHARES

    names = [p.name for p in lib if p.kind == "informative"]
    designs = {"optimized": d.weights, "random": "random", "uniform": {n: 1.0 / len(names) for n in names}}
    if profile.library == "thesis-model-ship" and set(THESIS_SHARES) <= set(names):
        designs["thesis"] = THESIS_SHARES  # the shares section 9.1.1 reports, for comparison
    ev = evaluate_designs_parallel(
        profile,
        designs,
        runs=runs,
        seed=seed,
        scheduler=scheduler,
        primitives=lib,
        n_samples=samples,
        mean_subtraction=mean_subtraction,
        protocol=protocol,
        order=order,
        settle=settle,
        min_block=min_block,
        estimator=estimator,
    )
    _echo_speed(ev)
    return ev


def _sensitivity_step(profile: ShipProfile, seed: int) -> list[dict]:
    """The model-ship sensitivity study (--sensitivity), refused for another dictionary."""
    from expdesign.errors import DesignError
    from expdesign.sensitivity import sensitivity_study

    if profile.library != "thesis-model-ship":
        raise DesignError("--sensitivity studies the model-ship dictionary tau1-tau11; use --ship model-ship")
    return sensitivity_study(profile, seed=seed)


def _write_step(out: Path, doc: dict, d: Design, ev: MCEvaluation | None, thesis: dict[str, float] | None) -> dict[str, Path]:
    """report.md, design.json and the figures into ``out``, replaced whole or not at all."""
    from expdesign.report import write_report
    from primitives.io import atomic_output_dir

    with atomic_output_dir(out) as tmp:  # a failed report never leaves a mix of old and new files
        written = write_report(tmp, doc, d, ev.results if ev else None, thesis)
    return {k: out / p.relative_to(tmp) for k, p in written.items()}


def _print_step(ship: str, d: Design, doc: dict, ev: MCEvaluation | None, paths: dict[str, Path], json_out: bool) -> None:
    """The design's warnings on stderr, then the JSON document or the text summary on stdout."""
    for w in d.warnings:  # on stderr: with --json stdout carries only the JSON (which holds them too)
        typer.echo(f"warning: {w}", err=True)
    if json_out:
        typer.echo(dumps(doc))
        return
    _echo_design(ship, d)
    if ev:
        _echo_mc(doc["monte_carlo"])
    from expdesign.robust_report import robust_lines

    for line in robust_lines(doc):
        typer.echo(line)
    if paths:
        typer.echo(f"wrote {paths['markdown']} and {paths['json']}")


def _echo_design(ship: str, d: Design) -> None:
    """The design's mix, its efficiency and the reference shares' efficiency, as text."""
    typer.echo(f"{ship}: {d.criterion}-optimal mix ({d.mean_subtraction} mean subtraction)")
    # every primitive the rounding uses (as design.json's "rounded"), and any with a share worth printing
    shown = [n for n, w in d.weights.items() if w > 0.005 or d.rounded.get(n, 0) > 0]
    width = max((len(n) for n in shown), default=8)
    for n in shown:
        typer.echo(f"  {n:{width}s} {100 * d.weights[n]:5.1f} %   {d.rounded.get(n, 0):3d} x {d.unit_s[n]:.1f} s")
    bound = "no efficiency bound" if d.efficiency_bound is None else f"certificate >= {d.efficiency_bound:.4f}"
    typer.echo(
        f"efficiency vs equal shares {d.efficiency_vs_uniform:.3f}; {'' if d.criterion.endswith('-D') else 'convex '}{bound}"
    )
    for label, eff in d.references.items():
        typer.echo(f"the {label}'s shares reach {eff:.3f} of this design's {d.criterion}-efficiency")


def _echo_mc(mc: dict) -> None:
    """One line per Monte Carlo design (and one for the same runs' IV reference), as text."""
    for n, s in mc.items():
        p = (
            "n/a"
            if s["param_rmse_p50"] is None
            else f"{s['param_rmse_p50']:.3g} ({100 * s['frac_param_rmse_below_1_5']:.1f} % < 1.5)"
        )
        typer.echo(
            f"  MC {n:9s} param RMSE p50 {p}; sim RMSE p50 {_g(s['sim_rmse_p50'])} "
            f"({100 * s['frac_sim_rmse_below_0_15']:.1f} % < 0.15); diverged {s['diverged']} of {s['runs']} "
            f"[{s['estimator']}]"
        )
        if s.get("reference"):
            r = s["reference"]
            rp = "n/a" if r["param_rmse_p50"] is None else f"{100 * r['frac_param_rmse_below_1_5']:.1f} %"
            typer.echo(
                f"     {'':9s} same runs, {r['estimator']} (the thesis's estimator): {rp} < 1.5, "
                f"{100 * r['frac_sim_rmse_below_0_15']:.1f} % < 0.15; diverged {r['diverged']}"
            )


def _check_mc_options(protocol: str, order: str, estimator: str, settle: int, min_block: int, samples: int) -> None:
    """Refuse a bad Monte Carlo option before the design step (seconds of work) runs."""
    from expdesign.errors import DesignError
    from expdesign.montecarlo import ESTIMATORS, ORDERS, PROTOCOLS, MCConfig

    for flag, value, allowed in (
        ("--mc-protocol", protocol, PROTOCOLS),
        ("--mc-order", order, ORDERS),
        ("--mc-estimator", estimator, ESTIMATORS),
    ):
        if value not in allowed:
            raise DesignError(f"{flag} {value!r} is not one of {', '.join(allowed)}")
    if settle < 0:
        raise DesignError(f"--mc-settle {settle}: the settling gap is a number of samples, 0 or more")
    segment = samples // MCConfig.n_segments
    if not 2 <= min_block <= segment:
        raise DesignError(
            f"--mc-min-block {min_block}: use 2 to {segment} samples (a random-design segment is "
            f"--mc-samples {samples} / {MCConfig.n_segments}), or raise --mc-samples"
        )


def _g(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3g}"


def _echo_speed(ev: MCEvaluation) -> None:
    """Runs done, runs per second and how the work was cut, on stderr."""
    e, n = ev.engine, sum(ev.runs_finished.values())
    typer.echo(
        f"Monte Carlo: {n} runs in {ev.elapsed_s:.1f} s ({n / max(ev.elapsed_s, 1e-9):.0f} runs/s) on {e['name']}, "
        f"{e['workers']} workers x {e['threads_per_worker']} threads, {e['tasks']} tasks "
        f"({e['tasks_per_worker']:.1f} per worker slot)",
        err=True,
    )
    if e["name"] == "dask" and e["threads_per_worker"] > 1:
        # the kernel's time loops step arrays of one task's runs, too small for numpy to release the lock: over half
        # of a 63-run task's CPU (bench_design.py --profile-task); bench_design.py --threads measures what threads give
        typer.echo(
            f"note: the Dask workers run {e['threads_per_worker']} threads each, which share Python's interpreter "
            "lock; the Monte Carlo's time loops hold it most of the time: for full speed start the workers with "
            "--nthreads 1, one per core",
            err=True,
        )


def _fail(ev: MCEvaluation, what: str) -> None:
    """Exit non-zero after an interrupted or failed Monte Carlo: 130 for Ctrl-C, 1 for lost work."""
    done = ", ".join(f"{k} {v}" for k, v in ev.runs_finished.items()) or "none"
    why = "interrupted" if ev.interrupted else f"{len(ev.errors)} task(s) failed ({ev.errors[0]})"
    typer.echo(f"error: Monte Carlo {why}: runs finished of {ev.config.runs} per design: {done}; {what}", err=True)
    raise typer.Exit(130 if ev.interrupted else 1)
