"""Change detection on recordings: fit a yaw prior on a nominal run, then say whether, when and how
the ship changed (chapter 5 of the MSc thesis "Estimating a ship's dynamics
during operation", with the change named). A notebook calls these; the CLI
``shiptrial detect-prior`` / ``shiptrial detect`` is a thin layer over them."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from diagnose.recording import Recording, RecordingError, load_recording, split_metadata
from identify.detect.checks import MOMENT, check_inputs, check_moment_sign, check_sway_acceleration
from identify.detect.columns import missing_columns, renamed_columns, unknown_column_notes
from identify.detect.cusum import calibrate_dead_zone, first_alarms
from identify.detect.glr import SignatureCusum, calibrate
from identify.detect.inputs import SWAY_ACC, Deriver, signals
from identify.detect.nullsim import null_records
from identify.detect.power import detectable
from identify.detect.priorfit import batch_fits, check_noise_model, fit
from identify.detect.rollband import roll_band
from identify.detect.verdict import Detection, Screening, implausible_inertia, physical_change, verdict
from identify.detect.vessel import TABLE_4_1, Vessel, base_profile, harbour_inputs, measure, truth
from identify.detect.yawmodel import (
    CANDIDATES,
    YawPrior,
    block_mean,
    check_prior_out,
    predict_with_signatures,
    shift_moment,
)
from primitives.errors import UserError
from primitives.io import atomic_write_text, dumps, read_input_text
from primitives.ship import load_profile


def load_runs(paths: list[Path] | list[str], kind: str | None = None, notes: list[str] | None = None) -> list[Recording]:
    """Recordings that carry what the yaw row needs (measured r; the pod inputs or the measured pod
    yaw moment ``tau_n``; ``phi`` for the full model when ``kind`` says so; optionally the measured
    sway acceleration ``v_dot``), one sample time. Every missing column of a file is named in one
    message, with every column that looks renamed (:func:`renamed_columns`: ``vdot`` for an absent
    ``v_dot`` moved the prior's I_r by 10 % in stop 50's sweep, a note was all it got); any other column
    detect does not read is named in ``notes`` with the closest known name."""
    recs = []
    for p in paths:
        header = _header(Path(p))
        if not header:
            raise RecordingError(
                f"{p}: no header row (an empty file?); give a recording CSV (docs/commands/detect.md: 'Recordings for detect and detect-prior')"
            )
        problems = [f"missing column(s): {'; '.join(m)}"] if (m := missing_columns(header, kind)) else []
        renamed = renamed_columns(header)
        problems += [
            f"column '{h}' looks like '{c}' ({what}), which the file lacks: rename it '{c}', or leave it out if it is "
            "another quantity"
            for h, c, what in renamed
        ]
        if problems:
            raise RecordingError(
                f"{p}: {'; '.join(problems)} (docs/commands/detect.md: 'Recordings for detect and detect-prior')"
            )
        if notes is not None:
            notes.extend(unknown_column_notes(p, header))
        try:
            runs = load_recording(p)
        except RecordingError as e:  # the loader's fix names diagnose's option; detect reads the header only
            raise RecordingError(str(e).replace(" (or --yaw-rate-sign)", "")) from None
        if SWAY_ACC in header and any(SWAY_ACC not in r.channels for r in runs):
            raise RecordingError(f"{p}: column '{SWAY_ACC}' holds no finite values; fill it or leave the column out")
        for r in runs:
            check_sway_acceleration(r)
            check_declared_rate(p, r)
            if notes is not None:  # the loader's repairs (gaps bridged, repeated stamps averaged): said, not silent
                notes.extend(f"{p}: {n}" for n in r.notes)
        recs.extend(runs)
    dts = {round(r.sample_time, 9) for r in recs}
    if len(dts) > 1:
        raise RecordingError(
            f"{', '.join(str(p) for p in paths)}: different sample times {sorted(dts)} s; "
            "resample the recordings to one sample time"
        )
    return recs


def check_declared_rate(path: Path | str, rec: Recording) -> None:
    """Refuse a recording whose time stamps step at another rate than its ``# sample_time:`` (median
    step more than 10 % off): the loader resamples irregular stamps onto the declared grid (diagnose's
    rule, for jittery loggers), which for a run logged at 0.2 s under a 0.1 s header interpolated every
    other sample and passed it to a 0.1 s prior (exit 0, "CHANGED", in stop 50's sweep). The median
    step is the loader's own note's (diagnose.recording_table.uniform_axis)."""
    for n in rec.notes:
        m = re.match(r"time stamps irregular \(median step ([0-9.eE+-]+) s\)", n)
        if m and abs(float(m.group(1)) / rec.sample_time - 1) > 0.1:
            raise RecordingError(
                f"{path}: column 't' steps {float(m.group(1)):g} s (median) but '# sample_time:' says "
                f"{rec.sample_time:g} s; correct the header (the prior needs recordings at its own sample time)"
            )


def _header(path: Path) -> list[str]:
    _, body = split_metadata(
        read_input_text(
            path,
            RecordingError,
            "a recording CSV (docs/commands/detect.md: 'Recordings for detect and detect-prior')",
            "utf-8-sig",
        ).splitlines()[:200]
    )
    return [h.strip() for h in body[0].split(",")] if body else []


def fit_prior(
    paths: list[Path] | list[str],
    kind: str = "full",
    bootstrap: int = 64,
    seed: int = 0,
    notes: list[str] | None = None,
    roll_rate: bool = True,
    moment_lag: bool = True,
    noise_model: str | None = None,
) -> YawPrior:
    """Yaw prior (2.17)/(2.18) fitted on the longest gap-free piece of the nominal recording(s),
    its parameter error described by ``bootstrap`` parametric-bootstrap refits of the nominal
    data (errors in variables: noisy u, v, phi and the v', tau_r derived from them). The full
    model gets the roll-rate term ``N_p p`` (kind ``full-p``) when that recording has the roll
    rate ``p`` and ``roll_rate`` is on; the recordings tested with the prior then need ``p`` too.
    ``moment_lag``: with a measured moment, its advance against the yaw rate is fitted
    (:func:`moment_shift`, said in ``notes``) and kept with the prior. ``noise_model``: how the signals'
    noise is read (:func:`identify.detect.priorfit.read_noise`; None: its default)."""
    if kind not in ("full", "simplified"):
        raise UserError(f"--model {kind!r}: choose full (2.17) or simplified (2.18)")
    if noise_model is not None:  # up front: not after loading and the whole fit
        check_noise_model(noise_model)
    recs = load_runs(paths, kind, notes)
    rec = max(recs, key=lambda r: r.n_samples)
    if kind == "full" and roll_rate and "p" in rec.channels:
        kind = "full-p"  # the measured roll rate lets the yaw row carry the roll-yaw coupling N_p p
    sig, r = signals(rec, kind)
    if np.ptp(r) < 1e-3:
        raise RecordingError(f"{rec.source}: the yaw rate hardly moves (range {np.ptp(r):.1e} rad/s); a prior needs turning")
    check_moment_sign(rec, sig["tau_r"], r)
    shift, scales = moment_shift(kind, sig, r, rec.sample_time) if MOMENT in rec.channels and moment_lag else (0.0, None)
    prior = fit(
        kind,
        shift_moment(sig, shift, rec.sample_time),
        r,
        rec.sample_time,
        source=str(rec.source),
        bootstrap=bootstrap,
        seed=seed,
        derive=Deriver.of(rec, kind),
        scales=scales,
        noise_model=noise_model,
    )
    prior.moment_shift_s = shift
    if shift and notes is not None:
        notes.append(
            f"{rec.source}: the measured moment {MOMENT} is read {shift:+.1f} s ahead of the yaw rate (its sensor "
            "lags the gyro by that much more; fitted on this run, applied to every recording screened with this prior)"
        )
    return prior


#: the measured moment's advances against the yaw rate that :func:`moment_shift` tries, s
MOMENT_SHIFTS = (-0.2, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5)
#: relative drop of the nominal fit's robust residual a shift needs (truth family strong-roll: 12 % and 7.5 % at
#: 0.2 s; the kernel's own data: 0.1 % at -0.1 s, noise)
MOMENT_SHIFT_GAIN = 0.01


def moment_shift(kind: str, sig: dict[str, np.ndarray], r: np.ndarray, dt: float) -> tuple[float, np.ndarray | None]:
    """The advance of the measured moment (MOMENT_SHIFTS) whose output-error fit leaves the smallest
    robust residual on the nominal run, when it beats none by MOMENT_SHIFT_GAIN. On the podded truth
    family: 0.2 s on strong-roll ships 100 and 101, 0.1 s on nominal-mmg's; the family's load cell lags the
    gyro (0.5 s against 0.3 s), and with the shift strong-roll's unchanged runs' inertia reading no longer
    falls with their roll level (ship 100: -0.65 -> -0.10 % of I_r per degree of roll sd). The shift is
    chosen on 2 + 2 ships and a 0.1 s grid; I_r moves about 0.9 % per 10 ms of it (not a fine estimate).
    Returns the shift and the fit's scales at it (None when no fit converged), fitted in one batch."""
    x, sd = batch_fits(kind, [shift_moment(sig, d, dt) for d in MOMENT_SHIFTS], r, dt)
    best, none = int(np.argmin(sd)), MOMENT_SHIFTS.index(0.0)
    # the shift trades against I_r (+0.9 % of I_r per 10 ms on the kernel's own nominal run, where the residual
    # is flat within 0.1 % from -0.1 to +0.1 s): a shift must earn MOMENT_SHIFT_GAIN of the residual, else none
    chosen = best if sd[best] < (1 - MOMENT_SHIFT_GAIN) * sd[none] else none
    return float(MOMENT_SHIFTS[chosen]), (x[chosen] if np.isfinite(sd[chosen]) else None)


def hull_inertia(
    profile: str | Path | None = None, i_z: float | None = None, n_rdot: float | None = None
) -> tuple[float | None, float | None]:
    """The hull's rigid-body yaw inertia I_z and added yaw inertia N_rdot (kg m^2) that convert a
    change of the lumped I_r = I_z - N_rdot into one of I_z: the ship profile's ``[rigid_body]``
    ``I_z`` and ``N_rdot`` (a built-in name or a TOML/JSON file), each replaced by ``i_z`` or
    ``n_rdot`` when given. (None, None) when neither a profile nor both values are given: the
    ship's hull is then not known, and no other ship's values stand in for it."""
    if profile is not None:
        rb = load_profile(profile).rigid_body
        if n_rdot is None and "N_rdot" not in rb.added:
            raise UserError(f"{profile}: the profile's [rigid_body] has no N_rdot; add it or give --n-rdot")
        i_z = rb.i_z if i_z is None else i_z
        n_rdot = rb.added["N_rdot"] if n_rdot is None else n_rdot
    if (i_z is None) != (n_rdot is None):
        given, other = ("--i-z", "--n-rdot") if i_z is not None else ("--n-rdot", "--i-z")
        raise UserError(
            f"{given} given without {other}: give both (kg m^2), or --profile with the ship's profile "
            "(its [rigid_body] I_z and N_rdot)"
        )
    if i_z is not None and not (i_z > 0 and n_rdot < 0):
        raise UserError(
            f"{profile or '--i-z/--n-rdot'}: I_z {i_z:g} must be positive and N_rdot {n_rdot:g} negative (kg m^2, "
            "N_rdot the added yaw inertia); correct the profile's [rigid_body] or give --i-z and --n-rdot"
        )
    return i_z, n_rdot


PLOT_WRITER = "shiptrial detect"  # the Creator mark of detect's figures: how a second run knows its own plot


def save_prior(prior: YawPrior, path: Path, *, force: bool = False) -> Path:
    """Write ``prior`` as JSON; a file that is not a prior is refused unless ``force`` (:func:`check_prior_out`)."""
    check_prior_out(path, force=force)
    return atomic_write_text(path, dumps(prior.to_dict()) + "\n")


def load_prior(path: Path) -> YawPrior:
    text = read_input_text(path, UserError, "a prior JSON written by 'shiptrial detect-prior'")
    try:
        d = json.loads(text)
    except ValueError as e:
        raise UserError(
            f"{path}: not JSON ({e.msg} at line {e.lineno}); give a prior written by 'shiptrial detect-prior'"
        ) from None
    if not isinstance(d, dict):
        raise UserError(f"{path}: not a yaw prior; give a prior written by 'shiptrial detect-prior'")
    return YawPrior.from_dict(d, where=str(path))


def detect(
    rec: Recording,
    prior: YawPrior,
    false_alarm: float = 0.02,
    min_change: float = 0.05,
    seed: int = 0,
    null_runs: int = 400,
    n_rdot: float | None = None,
    i_z: float | None = None,
    draws: dict | None = None,
) -> Detection:
    """Signature LR-CUSUM (and, for comparison, the dead-zone CUSUM of (5.1)) on one recording,
    calibrated for ``false_alarm`` per recording length from the prior alone (:func:`screen`); an
    alarm also needs the estimated change to reach ``min_change`` and twice its own noise
    (:func:`identify.detect.verdict.verdict`). The evidence holds the change point with its 95 %
    interval and, for yaw inertia, the change of the rigid body's ``i_z`` beside that of the lumped
    I_r = I_z - ``n_rdot`` (the hull's values, :func:`hull_inertia`; None: not known, the change
    is of I_r and ``min_change`` applies to it). A prior whose I_r is far off the hull's is refused
    (:func:`identify.detect.verdict.implausible_inertia`): a UserError, before any screening. ``detectable``
    says how large a change from the start this recording's alarms would catch in 90 % of cases
    (:func:`identify.detect.power.detectable`, from the same no-change records and thresholds)."""
    odd = implausible_inertia(prior, i_z, n_rdot)
    if odd:
        raise UserError(f"prior fitted on {prior.source or 'its nominal recording'}: {odd}")
    sc = screen(rec, prior, false_alarm, min_change, seed, null_runs, n_rdot, i_z, draws=draws)
    d = verdict(sc, prior, min_change, n_rdot, i_z)
    d.detectable = detectable(sc, prior, change_sizes(min_change, i_z, n_rdot), false_alarm, min_change, seed, i_z, n_rdot)
    return d


def change_sizes(min_change: float, i_z: float | None = None, n_rdot: float | None = None) -> np.ndarray:
    """The LR-CUSUM's change worth an alarm per candidate signature (its ``theta1``): ``min_change`` of I_z
    is less of the lumped I_r, on the hull's basis as the verdict's (the prior's fitted I_r is in the
    recorded moment's units); of I_r when the hull is not known."""
    iz_per_ir = physical_change("yaw_inertia", 1.0, i_z - n_rdot, n_rdot) if i_z is not None and n_rdot is not None else 1.0
    return np.array([min_change / iz_per_ir, min_change, min_change])


def screen(
    rec: Recording,
    prior: YawPrior,
    false_alarm: float = 0.02,
    min_change: float = 0.05,
    seed: int = 0,
    null_runs: int = 400,
    n_rdot: float | None = None,
    i_z: float | None = None,
    leave_out_roll_band: bool = False,
    draws: dict | None = None,
) -> Screening:
    """The recording's residual against the prior, the change signatures, ``null_runs`` no-change
    records simulated from the prior alone (:func:`identify.detect.nullsim.null_records`), and the
    LR-CUSUM and dead-zone CUSUM statistics with thresholds calibrated on those for ``false_alarm``
    per recording length; the LR-CUSUM looks for a change of ``min_change``: of I_z for inertia
    when the hull's ``i_z`` and ``n_rdot`` are given (converted to I_r with the hull's I_z - N_rdot,
    as :func:`identify.detect.verdict.verdict` converts the estimate), else of I_r.

    ``leave_out_roll_band`` reads the residual and the signatures outside the recording's roll band
    (:mod:`identify.detect.rollband`), here and in the verdict. Off by default: on the podded truth
    family (50 + 50 runs) it halved the false alarms (20 -> 10 %) but missed more (38 -> 48 %) and
    detected 64 s later (the stored screenings of benchmarks/bench_detect_truth.py re-decided with the
    band out; README, stop 39; ``--roll-band`` there screens with it). ``draws``: the no-change
    records' noise kept over a job (:func:`identify.detect.nullsim.normals`)."""
    if abs(rec.sample_time - prior.dt) > 1e-6 * prior.dt:
        raise RecordingError(
            f"{rec.source}: sample time {rec.sample_time:g} s differs from the prior's {prior.dt:g} s; "
            "resample the recording or fit the prior on data of this sample time"
        )
    if rec.n_samples < 20 * prior.block:
        raise RecordingError(
            f"{rec.source}: {rec.duration_s:.0f} s is too short to detect a change; give at least "
            f"{20 * prior.block * prior.dt:.0f} s"
        )
    sig, r = signals(rec, prior.kind)
    sig = shift_moment(sig, prior.moment_shift_s, prior.dt) if MOMENT in rec.channels else sig
    r0 = float(np.mean(r[:5]))
    w = prior.inputs(sig)  # filtered once for the prediction, the input checks and the signatures
    r_hat, S = predict_with_signatures(prior, w, r0)  # the prediction and the change signatures in one simulation
    eps = r - r_hat
    residual_rms = check_inputs(rec, prior, sig, r, eps, w)
    if i_z is not None and n_rdot is not None and not (i_z > 0 and n_rdot < 0):
        raise ValueError(f"i_z {i_z:g} must be positive and n_rdot {n_rdot:g} negative (kg m^2)")
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging draw is counted below, not printed as numpy's
        null_raw = null_records(prior, sig, null_runs, seed, derive=Deriver.of(rec, prior.kind), r0=r0, draws=draws)
    # a bootstrap draw whose ship cannot be simulated on this manoeuvre (diverged) is no no-change record:
    # left in, its NaNs made every threshold NaN and the recording silently unable to alarm. Left out, the
    # thresholds are low if the diverging draws are the prior's largest parameter errors: detect warns
    kept = np.isfinite(null_raw).all(axis=0)
    if kept.sum() < max(2, null_runs // 2):
        raise RecordingError(
            f"{rec.source}: {null_runs - kept.sum()} of {null_runs} no-change simulations from the prior diverged on "
            "this manoeuvre; the prior's parameter error is too large for it: refit the prior on a longer nominal run"
        )
    null_raw = null_raw[:, kept]
    null_blocks = block_mean(null_raw, prior.block)
    theta1 = change_sizes(min_change, i_z, n_rdot)
    # the roll band's yaw residual follows how much the recording rolls against the nominal run, not the ship
    band = roll_band(rec.channels["phi"], rec.sample_time, prior.block) if leave_out_roll_band and "phi" in rec.channels else None
    sc: SignatureCusum = calibrate(prior, S, null_blocks, theta1=theta1, false_alarm=false_alarm, seed=seed, band=band)
    dz = calibrate_dead_zone(prior.sigma, null_raw, false_alarm=false_alarm)
    st = sc.statistics(block_mean(eps, prior.block), S)
    g = dz.statistic(eps)
    j = int(first_alarms(g[:, None], dz.h)[0])
    return Screening(
        str(rec.source),
        eps,
        S,
        st,
        np.asarray(sc.h),
        null_blocks,
        g,
        float(dz.h),
        j,
        rec.t - rec.t[0],
        residual_rms,
        int(null_runs - kept.sum()),
        band,
    )


def plot_paths(sources: list[str], path: Path, panels: int = 4) -> list[Path]:
    """The files :func:`plot` writes for recordings ``sources``: ``path`` for up to ``panels`` of them, beyond,
    one file per recording (``stem-NNN-<recording>``)."""
    if len(sources) <= panels:
        return [path]
    out = []
    for k, source in enumerate(sources):
        name = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in Path(source).stem) or f"rec{k}"
        out.append(path.with_name(f"{path.stem}-{k + 1:03d}-{name}{path.suffix}"))
    return out


def check_plot_out(sources: list[str], path: Path, panels: int = 4, option: str = "path", *, force: bool = False) -> list[Path]:
    """Each file :func:`plot` would write: one that exists and detect did not draw (its Creator mark) is refused
    unless ``force``, before any is drawn (``option``: the CLI's "--plot", or the keyword's "path")."""
    from primitives.io import check_figure_file

    return [check_figure_file(p, option, PLOT_WRITER, force=force) for p in plot_paths(sources, Path(path), panels)]


def plot(dets: list[Detection], path: Path, panels: int = 4, *, force: bool = False) -> list[Path]:
    """Both detectors against time, one panel per recording: the LR-CUSUM statistic per candidate
    over its own threshold (left axis, statistic / threshold, alarm at 1) and the dead-zone CUSUM
    (5.1) over its threshold (right axis), the alarm and the change point with its interval. Up to
    ``panels`` recordings in ``path``; beyond, one file per recording (:func:`plot_paths`). A file detect
    did not draw is refused unless ``force`` (:func:`check_plot_out`), before any is drawn."""
    paths = check_plot_out([d.source for d in dets], Path(path), panels, force=force)
    if len(paths) == 1:
        return [_figure(dets, paths[0])]
    return [_figure([d], p) for d, p in zip(dets, paths)]


def _figure(dets: list[Detection], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from primitives.io import atomic_savefig

    fig, axes = plt.subplots(len(dets), 1, figsize=(9, 3.4 * len(dets)), squeeze=False)
    for ax, d in zip(axes[:, 0], dets):
        for k, c in enumerate(CANDIDATES):
            ax.plot(
                d.t_blocks, d.statistic[:, k] / d.threshold[k], label=f"LR-CUSUM {c.replace('_', ' ')} / h = {d.threshold[k]:.1f}"
            )
        ax2 = ax.twinx()
        ax2.plot(
            d.t[: len(d.dead_zone)],
            d.dead_zone / d.dead_zone_h,
            color="0.5",
            lw=0.8,
            label=f"dead-zone CUSUM (5.1) / h = {d.dead_zone_h:.3g}",
        )
        ax2.set_ylabel("dead-zone CUSUM / threshold", color="0.4")
        ax.axhline(1.0, color="k", ls="--", lw=1, label="threshold (both)")
        lo, hi = d.evidence["onset_interval_s"]
        if d.changed:
            ax.axvline(d.alarm_s, color="r", lw=1.2, label=f"alarm {d.alarm_s:.0f} s")
            ax.axvspan(
                lo, hi, color="r", alpha=0.12, label=f"change point {d.evidence['onset_s']:.0f} s (95 %: {lo:.0f}-{hi:.0f})"
            )
        if d.dead_zone_alarm_s is not None:
            ax.axvline(d.dead_zone_alarm_s, color="0.4", ls=":", lw=1.2, label=f"dead-zone alarm {d.dead_zone_alarm_s:.0f} s")
        verdict = f"changed, {d.property.replace('_', ' ')}" if d.changed else "no change detected"
        ax.set_title(f"{Path(d.source).name}: {verdict}", fontsize=10)
        ax.set_ylabel("LR-CUSUM / threshold")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    out = atomic_savefig(fig, path, dpi=110, metadata={"Creator": PLOT_WRITER})  # how detect knows its own plot
    plt.close(fig)
    return out


def simulated_recording(
    vessel: Vessel,
    duration_s: float = 500.0,
    dt: float = 0.1,
    seed: int = 0,
    noise_scale: float = 1.0,
    change_at_s: float | None = None,
    changed: Vessel | None = None,
    source: str = "simulated",
    measured_moment: bool = False,
) -> Recording:
    """A podded-ship recording simulated by the shared kernel (``naval-vessel`` profile, changed as
    ``vessel`` says) with Table 4.1 noise on u, v, r, phi and the measured sway acceleration
    ``v_dot`` (and, with ``measured_moment``, on a measured pod yaw moment ``tau_r``, as the
    thesis assumes, as column ``tau_n``; else the detector derives it from the pod inputs)
    (examples, tests).

    With ``change_at_s`` the ship is ``vessel`` before and ``changed`` after (a step change). A
    ``dt`` other than the profile's sample time is made by keeping every k-th kernel sample."""
    ts = base_profile().sample_time
    every = int(round(dt / ts))
    if every < 1 or abs(every * ts - dt) > 1e-9:
        raise UserError(f"dt {dt:g} s: give a multiple of the profile's sample time {ts:g} s")
    n = int(round(duration_s / ts))
    ch = harbour_inputs(n, ts, seed=seed)
    tr = truth(ch, vessel, changed, None if change_at_s is None else int(round(change_at_s / ts)))
    tr = {k: x[::every] for k, x in tr.items()}
    ch = ch[::every]
    m = len(tr["r"])
    rng = np.random.default_rng(seed + 1)
    noisy = measure(tr, {k: noise_scale * sd for k, sd in TABLE_4_1.items()}, rng)
    chans = {
        "phi": noisy["phi"],
        SWAY_ACC: noisy["v_dot"],
        "n1": ch[:, 0],
        "alpha1": ch[:, 1],
        "n2": ch[:, 2],
        "alpha2": ch[:, 3],
    }
    if measured_moment:
        chans[MOMENT] = noisy["tau_r"]
    rec = Recording(
        source,
        np.arange(m) * dt,
        np.column_stack([noisy["u"], noisy["v"], noisy["r"]]),
        tr["psi"],
        np.column_stack([tr["x"], tr["y"]]),
        chans,
    )
    return replace(rec, meta={"sample_time": f"{dt:g}"})
