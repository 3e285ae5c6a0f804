"""Input checks of ``detect`` and ``detect-prior``: a recording the prior cannot describe at all
(a pod yaw moment of the wrong sign or unit, a flipped yaw rate, a run that hardly turns the ship)
is an input error, refused in one line, not a change."""

from __future__ import annotations

import numpy as np

from diagnose.recording import Recording, RecordingError
from identify.detect.yawmodel import YAW_MODELS, YawPrior, model_inputs, prior_name, simulate_r
from identify.yawid.model import INPUT_TERMS, STATE_TERMS
from primitives.savgol import savgol_filter  # scipy.signal's, without its 2 s import

MOMENT = "tau_n"  # measured pod yaw moment, N m (the recording format's actuator yaw moment)
#: the prior's prediction may miss a recording by this many times its noise sigma before the
#: recording is refused as an input error: simulated changed and unchanged runs (full and
#: simplified model, measured or derived tau_r) stay within 2.0x; tau_n x1000 gives ~780x,
#: tau_n or r of the wrong sign ~18-24x (the sign check below catches these too)
MISFIT_SIGMAS = 20.0
#: the recorded tau_n may be off the moment the prior needs by this factor before the recording is
#: refused (:func:`moment_scale`): measured 0.90-1.00 on our own kernel's
#: runs (0.90 for a -10 % pod gain), 0.70-0.99 on the podded truth family's (steering lag lowest);
#: a moment in kN m gives ~1000
MOMENT_FACTOR = 4.0
#: below this correlation of the two moments the slope is noise, not a unit (a straight run: 0.06,
#: slope 0.17, measured on a podded-truth ship; harbour manoeuvres 0.97-1.00, steering lag 0.66)
MOMENT_CORRELATION = 0.3
#: a v_dot correlating with dv/dt below minus this is flipped (:func:`check_sway_acceleration`)
VDOT_CORRELATION = 0.3

#: refuse a recording whose ``phi`` negated fits the prior's yaw rate this much better (rms ratio): on the
#: podded truth family's ships 108-109 (240 runs, 12 priors) a correct phi fitted 1.05-11.3 times better
#: than it negated; negated, it fitted 0.41-0.95 times as well (coloured-noise highest, not all caught)
#: and 0.35 on our own kernel's run (stop 50, docs/bad-input-sweep.md)
ROLL_FLIP = 0.9

UNITS_FIX = (
    f"check the units and signs: {MOMENT} in N m, > 0 turning the ship to starboard, and r in rad/s, "
    "> 0 turning to starboard (docs/commands/detect.md: 'Recordings for detect and detect-prior')"
)


def time_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """d/dt along axis 0 by a quadratic Savitzky-Golay fit over about 2 s (np.gradient on records
    shorter than that window)."""
    win = max(5, 2 * int(1.0 / dt) + 1)
    return savgol_filter(x, win, 2, deriv=1, delta=dt, axis=0) if len(x) > win else np.gradient(x, dt, axis=0)


def check_sway_acceleration(rec: Recording) -> None:
    """Refuse a measured sway acceleration ``v_dot`` that runs against the rate of the recorded ``v``
    (their correlation, both smoothed over about 2 s, below -:data:`VDOT_CORRELATION`): a flipped ``v_dot``
    biased the prior's I_r by +7.6 % and read as a "pod gain" change in stop 50's sweep. Measured 0.80-0.85 on
    our own kernel's runs, 0.40-0.96 on the podded truth family's ships 108-109 (210 runs, coloured noise
    lowest); -0.81 negated. A run with little sway (a straight run) has both signals at their noise and a
    correlation near 0 of either sign: not judged (6 of 10 straight runs read -0.01 to -0.09 in review)."""
    if "v_dot" not in rec.channels or rec.n_samples < 10:
        return
    dt = rec.sample_time
    win = max(5, 2 * int(1.0 / dt) + 1)
    smooth = savgol_filter(rec.channels["v_dot"], win, 2) if rec.n_samples > win else rec.channels["v_dot"]
    rate = time_derivative(rec.y[:, 1], dt)
    c = float(np.corrcoef(smooth, rate)[0, 1]) if np.ptp(smooth) > 0 and np.ptp(rate) > 0 else 1.0
    if c < -VDOT_CORRELATION:
        raise RecordingError(
            f"{rec.source}: column 'v_dot' correlates {c:+.2f} with the rate of v (a measured sway acceleration "
            "follows it: expected > 0); negate v_dot (m/s^2, > 0 accelerating to starboard) or leave it out"
        )


def check_moment_sign(rec: Recording, tau_r: np.ndarray, r: np.ndarray) -> None:
    """Refuse a measured pod yaw moment that does not turn the ship the way it is pushed (tau_n
    against dr/dt, as diagnose checks its columns' signs): a flipped tau_n or r."""
    if MOMENT in rec.channels and np.ptp(tau_r) > 0 and np.ptp(r) > 0:
        c = float(np.corrcoef(tau_r, time_derivative(r, rec.sample_time))[0, 1])
        if not c > 0:
            raise RecordingError(
                f"{rec.source}: column '{MOMENT}' correlates {c:+.2f} with the rate of r (a pod yaw "
                f"moment turns the ship its way: expected > 0); {UNITS_FIX}"
            )


def check_inputs(
    rec: Recording,
    prior: YawPrior,
    sig: dict[str, np.ndarray],
    r: np.ndarray,
    eps: np.ndarray,
    inputs: dict[str, np.ndarray] | None = None,
) -> float:
    """Refuse a recording the prior cannot describe at all (an input error, not a change): a
    measured pod yaw moment of the wrong sign (:func:`check_moment_sign`) or off the moment the
    prior needs to turn the ship as recorded by more than MOMENT_FACTOR (tau_n in kN m, x1000:
    :func:`moment_scale`), a recording that turns the ship too little for
    either check (the two moments correlate less than MOMENT_CORRELATION: a straight run, which
    read as a +100 % change before), or a prediction residual not finite or over MISFIT_SIGMAS
    times the prior's noise sigma. Returns the residual's rms. ``inputs``: ``prior.inputs(sig)``
    when the caller has it already."""
    k, c = moment_scale(prior, sig, r, inputs) if MOMENT in rec.channels else (1.0, 1.0)
    off_unit = not 1 / MOMENT_FACTOR <= k <= MOMENT_FACTOR
    if off_unit and abs(c) < MOMENT_CORRELATION:
        raise RecordingError(
            f"{rec.source}: the recorded '{MOMENT}' and the moment the prior needs to turn the ship as "
            f"recorded hardly correlate ({c:+.2f}): the recording turns the ship too little (a straight "
            "run?) to be tested against the prior (neither its sign nor its unit can be checked); record "
            "manoeuvres (turns, zigzags)"
        )
    check_moment_sign(rec, sig["tau_r"], r)
    if off_unit:
        raise RecordingError(
            f"{rec.source}: the prior needs {k:.3g} times the recorded '{MOMENT}' to turn the ship as "
            f"recorded (more than {MOMENT_FACTOR:g}x either way is no ship change: a unit error, kN m "
            f"gives 1000); {UNITS_FIX}"
        )
    sigma = prior.sigma
    rms = float(np.sqrt(np.mean(eps**2)))
    if not np.isfinite(rms) or rms > MISFIT_SIGMAS * sigma:
        raise RecordingError(
            f"{rec.source}: the prior's yaw rate misses the recording's by {rms:.2g} rad/s rms, "
            f"{rms / sigma:.0f}x its noise {sigma:.2g} rad/s (over {MISFIT_SIGMAS:g}x is no ship "
            f"change: an input error); {UNITS_FIX}"
        )
    check_roll_sign(rec, prior, sig, r, rms, inputs)
    return rms


def check_roll_sign(
    rec: Recording,
    prior: YawPrior,
    sig: dict[str, np.ndarray],
    r: np.ndarray,
    rms: float,
    inputs: dict[str, np.ndarray] | None = None,
) -> None:
    """Refuse a roll angle whose sign is flipped against the prior's: the prior's yaw rate fits the
    recording better with ``-phi`` than with ``phi`` by more than ROLL_FLIP (the roll terms of (2.17)
    act the other way round). A flipped ``phi`` stayed within MISFIT_SIGMAS (2.8x) and alarmed as
    "yaw damping" in stop 50's sweep. ``inputs``: ``prior.inputs(sig)`` when the caller has it: phi's
    input filter is linear and alone (:func:`identify.detect.yawmodel.model_inputs`), and IEEE rounding
    is symmetric in sign, so ``-inputs["phi"]`` is the filtered ``-phi`` to the bit (tests/test_detect.py),
    not filtered again."""
    if "phi" not in sig or not np.ptp(sig["phi"]) > 0:
        return
    r0 = float(np.mean(r[:5]))
    if inputs is None:
        r_flip = prior.predict(sig | {"phi": -sig["phi"]}, r0)
    else:
        r_flip = simulate_r(prior.kind, prior.values, inputs | {"phi": -inputs["phi"]}, prior.dt, r0=r0)
    flipped = float(np.sqrt(np.mean((r - r_flip) ** 2)))
    if flipped < ROLL_FLIP * rms:
        raise RecordingError(
            f"{rec.source}: column 'phi' looks negated against the prior: its yaw rate fits the recording with -phi "
            f"({flipped:.2g} rad/s rms) better than with phi ({rms:.2g}); phi is > 0 starboard side down, in the "
            "recording and in the prior's nominal run (docs/commands/detect.md: 'Recordings for detect and detect-prior')"
        )


def moment_scale(
    prior: YawPrior, sig: dict[str, np.ndarray], r: np.ndarray, inputs: dict[str, np.ndarray] | None = None
) -> tuple[float, float]:
    """How many times the yaw moment the prior's row needs to turn the ship as recorded is the
    recorded actuator moment: the least-squares slope of ``I_r r' - sum_j theta_j phi_j(r, w)``
    ((2.17)/(2.18) solved for tau_r, with the measured r low-passed like the inputs and r' its
    Savitzky-Golay rate) on ``tau_r``. About 1 for a recording of the ship in the units the prior
    was fitted in (within the change of its properties); 1000 for a moment given in kN m as N m.
    Returns the slope and the correlation of the two moments (near 0 when the recording hardly
    turns the ship: the slope is then noise, not a unit). ``inputs``: ``prior.inputs(sig)`` when
    the caller has it already."""
    w = prior.inputs(sig) if inputs is None else inputs
    rl = model_inputs({"r": r}, prior.dt, prior.prefilter_hz)["r"]
    rest = np.zeros_like(rl)
    for name in YAW_MODELS[prior.kind].params[1:]:  # after I_r
        reg = STATE_TERMS[name][0](rl, w) if name in STATE_TERMS else INPUT_TERMS[name](w)
        rest = rest + prior.values[prior_name(name)] * reg
    win = 2 * int(1.0 / prior.dt) + 1
    need = prior.values["I_r"] * savgol_filter(rl, win, 2, deriv=1, delta=prior.dt) - rest
    tau = w["tau_r"]
    k = float(np.dot(need, tau) / max(float(np.dot(tau, tau)), 1e-300))
    c = float(np.corrcoef(need, tau)[0, 1]) if np.ptp(need) > 0 and np.ptp(tau) > 0 else 0.0
    return k, c
