"""``shiptrial detect-prior`` and ``shiptrial detect``: has the ship changed, when, and what (chapter 5 of the MSc
thesis "Estimating a ship's dynamics during operation")."""

from __future__ import annotations

from pathlib import Path

import typer

from primitives.io import dumps

PLOT_PANELS = 4  # recordings in one figure; beyond, one file per recording
N_RDOT_HELP = "the ship's added yaw inertia N_rdot (kg m^2, negative); replaces the --profile's"
I_Z_HELP = (
    "the ship's rigid-body yaw inertia I_z (kg m^2): a relative change of I_r is (I_z - N_rdot) / I_z "
    "times that of I_z; replaces the --profile's"
)


def register(app: typer.Typer) -> None:
    @app.command("detect-prior")
    def detect_prior(
        nominal: list[Path] = typer.Argument(
            ...,
            help="nominal recording CSV(s) of the podded ship: t, psi, x, y, u, v, r, phi "
            "(full model), the measured pod yaw moment tau_n or the pod inputs n1, alpha1, n2, "
            "alpha2; optional measured sway acceleration v_dot (docs/commands/detect.md: 'Recordings for detect "
            "and detect-prior')",
        ),
        out: Path = typer.Option(..., "--out", help="prior model file to write (.json)"),
        model: str = typer.Option("full", "--model", help="full (2.17, needs phi) or simplified (2.18)"),
        bootstrap: int = typer.Option(
            64,
            "--bootstrap",
            help="the prior's parameter error from N parametric-bootstrap "
            "refits of the nominal data (errors in variables; one batch, seconds); 0: Gaussian "
            "from the fit's Jacobian (knows the noise on r only)",
        ),
        seed: int = typer.Option(0, "--seed", help="seed of the bootstrap"),
        roll_rate: bool = typer.Option(
            True,
            "--roll-rate/--no-roll-rate",
            help="with the full model and a roll-rate column p, add the yaw moment N_p p of the roll "
            "rate to the yaw row (the recordings tested then need p too)",
        ),
        profile: str | None = typer.Option(
            None,
            "--profile",
            help="the ship's profile (built-in name or a .toml/.json file): a prior whose I_r is more than 3 times "
            "off its [rigid_body] I_z - N_rdot is refused here, as detect would refuse it, and not written",
        ),
        n_rdot: float | None = typer.Option(None, "--n-rdot", help=N_RDOT_HELP),
        i_z: float | None = typer.Option(None, "--i-z", help=I_Z_HELP),
        noise_model: str | None = typer.Option(
            None,
            "--noise-model",
            help="how each signal's measurement noise is read for the bootstrap refits and the no-change records: "
            "'spectral' (white noise through a first-order sensor low-pass, corner and sd read from the recording's "
            "spectrum above the ship's own motion) or 'white' (white noise from the second difference); channels derived rather than sensed (tau_r without a "
            "tau_n column, v_dot without a v_dot column) always read white; default: white (docs/detect-accuracy.md, stop 56)",
        ),
        force: bool = typer.Option(
            False, "--force", help="replace a --out file that is not a prior (default: refuse, naming the file)"
        ),
    ) -> None:
        """Fit the yaw-row prior (2.17)/(2.18) of "Estimating a ship's dynamics during operation" on a nominal recording, for `detect`."""
        from cli.options import validate_detect_prior_options
        from identify.detect.api import fit_prior, hull_inertia, save_prior
        from identify.detect.verdict import implausible_inertia
        from identify.detect.yawmodel import CANDIDATES
        from primitives.errors import UserError

        validate_detect_prior_options(
            out=out, bootstrap=bootstrap, seed=seed, n_rdot=n_rdot, i_z=i_z, noise_model=noise_model, force=force
        )
        i_z, n_rdot = hull_inertia(profile, i_z, n_rdot)
        notes: list[str] = []
        prior = fit_prior(nominal, model, bootstrap, seed, notes, roll_rate=roll_rate, noise_model=noise_model)
        for n in notes:
            typer.echo(f"note: {n}", err=True)
        odd = implausible_inertia(prior, i_z, n_rdot)
        if odd:
            raise UserError(f"{prior.source}: {odd} (nothing written to {out})")
        save_prior(prior, out, force=force)
        typer.echo(
            f"wrote {out}: {prior.kind} yaw row, I_r {prior.values['I_r']:.4g} kg m^2, residual sigma {prior.sigma:.2g} rad/s"
            + (f", N_p {prior.values['N_p']:.3g} N m s (yaw moment of the roll rate)" if "N_p" in prior.values else "")
        )
        if prior.structure.max() > 0:
            typer.echo(
                "  on a manoeuvre it was not fitted on, the structure's misfit alone reads as a change of "
                + ", ".join(f"{c.replace('_', ' ')} {100 * x:.1f} %" for c, x in zip(CANDIDATES, prior.structure))
                + " (rms); detect's thresholds allow for it"
            )

    @app.command("detect")
    def detect(
        recordings: list[Path] = typer.Argument(
            ...,
            help="recording CSV(s) to test against the prior (columns as for "
            "detect-prior; docs/commands/detect.md: 'Recordings for detect and detect-prior')",
        ),
        prior_file: Path = typer.Option(..., "--prior", help="prior model from `shiptrial detect-prior`"),
        plot: Path | None = typer.Option(
            None,
            "--plot",
            help="figure of both detectors' statistics (.png, .pdf, .svg), one "
            f"panel per recording; beyond {PLOT_PANELS} recordings one file per recording "
            "(NAME-001-<recording>.png, numbered in order)",
        ),
        false_alarm: float = typer.Option(
            0.02,
            "--false-alarm",
            help="design false-alarm probability per recording (on ships the prior's "
            "model describes; measured higher on ships unlike it: README 'How good are the "
            "answers', Detect)",
        ),
        min_change: float = typer.Option(
            0.05, "--min-change", help="smallest relative change worth an alarm (0.05 = 5 %; of I_z for yaw inertia)"
        ),
        profile: str | None = typer.Option(
            None,
            "--profile",
            help="the ship's profile (built-in name, e.g. naval-vessel, or a .toml/.json file) whose [rigid_body] "
            "I_z and N_rdot convert a change of the identified I_r = I_z - N_rdot into one of I_z; without it "
            "(or --i-z and --n-rdot) the change is reported of I_r and --min-change applies to I_r",
        ),
        n_rdot: float | None = typer.Option(None, "--n-rdot", help=N_RDOT_HELP),
        i_z: float | None = typer.Option(None, "--i-z", help=I_Z_HELP),
        seed: int = typer.Option(0, "--seed", help="seed of the threshold's no-change simulation"),
        json_out: bool = typer.Option(False, "--json", help="print the verdicts as JSON"),
        force: bool = typer.Option(
            False, "--force", help="replace a --plot file that detect did not draw (default: refuse, naming the file)"
        ),
    ) -> None:
        """Say whether the ship changed, when it changed (a change point with its 95 % interval) and which
        property (yaw inertia, yaw damping, pod gain, or undecided between them)."""
        from cli.options import validate_detect_options
        from identify.detect import noisecache
        from identify.detect.api import check_plot_out, hull_inertia, load_prior, load_runs
        from identify.detect.api import plot as plot_stats
        from identify.detect.batch import detect_all
        from identify.detect.verdict import implausible_inertia
        from primitives.errors import UserError
        from primitives.heap import DETECT_KEEP_BYTES, keep_freed_memory

        validate_detect_options(
            plot=plot,
            false_alarm=false_alarm,
            min_change=min_change,
            seed=seed,
            n_rdot=n_rdot,
            i_z=i_z,
            force=force,
            one_figure=len(recordings) <= PLOT_PANELS,
        )
        i_z, n_rdot = hull_inertia(profile, i_z, n_rdot)
        prior = load_prior(prior_file)
        notes: list[str] = []
        recs = load_runs(recordings, prior.kind, notes)
        if plot is not None:  # beyond PLOT_PANELS recordings one file each: known now, checked before the detection
            check_plot_out([str(r.source) for r in recs], plot, PLOT_PANELS, "--plot", force=force)
        odd = implausible_inertia(prior, i_z, n_rdot)
        if odd:
            raise UserError(f"{prior_file}: {odd}")
        # this process is the command's own: the no-change records' 16 MB arrays reused, not faulted in afresh
        keep_freed_memory(always=True, keep_bytes=DETECT_KEEP_BYTES)  # (primitives.heap: the figures)
        # one job: under 12,500 samples in all (two 500 s recordings) the numpy loops, more the compiled ones (jitloop.job)
        # the no-change records' noise of this prior and length read from the user's cache after the first run
        with noisecache.used():  # (identify.detect.noisecache: the same bits; ~96 MB an entry, 256 MiB kept)
            dets = detect_all(recs, prior, false_alarm, min_change, seed, n_rdot=n_rdot, i_z=i_z)
        # notes and warnings after the recordings passed their checks: a refused input is one line
        for n in notes:
            typer.echo(f"note: {n}", err=True)
        if i_z is None:
            typer.echo(
                "warning: the hull's I_z and N_rdot are not known: a yaw-inertia change is reported of the lumped "
                "I_r = I_z - N_rdot only, and --min-change applies to I_r; give --profile (the ship's profile) or "
                "--i-z and --n-rdot",
                err=True,
            )
        if prior.model_error > 0 and not prior.structure.any():
            # Measured (benchmarks/bench_detect.py): such priors alarm far above the design rate.
            typer.echo(
                f"warning: {prior_file}: the prior's structure misfits its own data (model error "
                f"{prior.model_error:.2g}) and it holds no held-out estimate of that misfit; alarms are not "
                "calibrated to --false-alarm: refit it with detect-prior (--bootstrap > 0)",
                err=True,
            )
        written = plot_stats(dets, plot, PLOT_PANELS, force=force) if plot is not None else []
        if json_out:
            typer.echo(
                dumps(
                    {
                        "prior": str(prior_file),
                        "model": prior.kind,
                        "false_alarm": false_alarm,
                        "min_change": min_change,
                        "n_rdot": n_rdot,
                        "i_z": i_z,
                        "hull_from": profile if profile is not None else ("options" if i_z is not None else None),
                        "notes": notes,
                        "recordings": [d.summary() for d in dets],
                    }
                )
            )
            return
        for d in dets:
            for line in verdict_lines(d, min_change):
                typer.echo(line)
        for w in written:
            typer.echo(f"wrote {w}")


def detectable_lines(can: dict | None) -> list[str]:
    """The smallest change the recording could show (identify.detect.power.detectable), and its warning."""
    if can is None:
        return []
    from identify.detect.power import later_text, sizes_text

    later = later_text(can)
    out = [
        f"  detectable: {sizes_text(can)} ({100 * can['power']:.0f} % power at --false-alarm {can['false_alarm']:g} "
        f"and --min-change {100 * can['min_change']:g} %, for a change from the recording's start"
        + (f"; a later change: {later})" if later else ")")
    ]
    if can["warning"]:
        out.append(f"  warning [{can['warning']['name']}]: {can['warning']['message']}")
    return out


def verdict_lines(d, min_change: float) -> list[str]:
    """The text report of one recording: verdict, change point, estimates (I_z beside I_r), dead-zone CUSUM, the
    smallest change it could show (:func:`detectable_lines`)."""
    ev = d.evidence
    lo, hi = ev["onset_interval_s"]
    if d.changed:
        what = (
            f"undecided between {' and '.join(c.replace('_', ' ') for c in ev['undecided_between'])}"
            if d.property == "undecided"
            else d.property.replace("_", " ")
        )
        out = [
            f"{d.source}: CHANGED (alarm at {d.alarm_s:.0f} s; change point {ev['onset_s']:.0f} s, 95 % interval "
            f"{lo:.0f}-{hi:.0f} s): {what}",
            f"  named on the data from the change point to the recording's end ({ev['named_on_s'][0]:.0f}-"
            f"{ev['named_on_s'][1]:.0f} s; the alarm used the data up to {d.alarm_s:.0f} s, and its lead then was "
            f"{ev['at_alarm']['candidate'].replace('_', ' ')}): the name is for the whole recording, not known at the alarm",
        ]
    else:
        why = (
            f"the statistic crossed a threshold but the estimated change is below --min-change {min_change:g} or "
            "within its own noise"
            if ev.get("crossed_but_below_min_change")
            else "every statistic stayed below its threshold"
        )
        peaks = ", ".join(
            f"{c.replace('_', ' ')} {ev['statistic_max'][c]:.1f}/{h:.1f}" for c, h in zip(ev["statistic_max"], d.threshold)
        )
        out = [
            f"{d.source}: no change detected ({why}; statistic max/threshold: {peaks}); the estimates below are not "
            "changes worth an alarm"
        ]
    for name, c in ev["candidates"].items():
        line = f"  {name.replace('_', ' '):12s} {100 * c['relative_change']:+6.1f} % +- {100 * c['std']:4.1f} %"
        if name == "yaw_inertia":
            line += " of I_r = I_z - N_rdot"
            line += (
                f" (I_z {100 * c['I_z_relative_change']:+.1f} % +- {100 * c['I_z_std']:.1f} % with "
                f"I_z {c['I_z']:.3g}, N_rdot {c['N_rdot']:.3g} kg m^2)"
                if c.get("I_z_relative_change") is not None
                else " (I_z not known: give --profile or --i-z and --n-rdot)"
            )
        line += f", log-likelihood ratio {c['llr']:.1f}"
        if not d.changed and abs(c["relative_change"]) >= 2 * c["std"]:
            # the alarm tests only the candidate with the largest log-likelihood ratio
            # of I_z when the hull is known, else of I_r (as the decision applied --min-change)
            size = c.get("I_z_relative_change") if name == "yaw_inertia" else None
            size = c["relative_change"] if size is None else size
            line += (
                " (over 2 sd, but every statistic stayed below its threshold)"
                if not ev.get("crossed_but_below_min_change")
                else " (over 2 sd, below --min-change)"
                if size is not None and abs(size) < min_change
                else " (over 2 sd, not separable from the other candidates)"
            )
        out.append(line)
    dz = f"{d.dead_zone_alarm_s:.0f} s" if d.dead_zone_alarm_s is not None else "none"
    out.append(f"  dead-zone CUSUM (5.1) alarm: {dz}")
    out += detectable_lines(d.detectable)
    div = ev.get("null_diverged", {"left_out": 0, "of": 0})
    if div["left_out"]:
        out.append(
            f"  warning: {div['left_out']} of {div['of']} no-change simulations from the prior diverged on this manoeuvre "
            "and were left out of the calibration: if they were its largest parameter errors, the thresholds are low "
            "and false alarms above --false-alarm"
        )
    return out
