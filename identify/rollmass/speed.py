"""The ship's speed in the output-error model: whether a recording's measured surge speed ``u`` is followed
(:func:`followed_speed`: its variation clearly the ship's, not the positioning's error) and the inputs it then
makes (:func:`speed_inputs`: the rudder by ``(u/U)^2`` and the turn input). Used by
:mod:`identify.rollmass.output_error`'s model and by the checks and warnings of :mod:`identify.rollmass.api`."""

from __future__ import annotations

import numpy as np

from identify.rollmass.simulate import RollRecording
from primitives.iir import filtfilt
from primitives.zerophase import lowpass

# low-pass of the measured speed before it enters the inputs (:func:`speed_inputs`): above the surge's
# own bandwidth (time constant (m - X_udot)/|X_u|, ~5 s on the model ship) and below the roll band (0.5-1.5 Hz)
SPEED_LP_HZ = 0.2
# The speed is followed only where its variation is clearly the ship's (:func:`followed_speed`): the sd of
# the low-passed u/mean(u) at least SPEED_NOISE_RATIO times the sd above SPEED_LP_HZ (the positioning's own
# error: a ship's speed has nothing there) and at least SPEED_VAR_MIN (a held speed within 1.5 % moves the
# rudder's u^2 forces by under 3 %, less than the sway-roll couplings' scatter)
SPEED_NOISE_RATIO = 3.0
SPEED_VAR_MIN = 0.015


def speed_inputs(rec: RollRecording, r_bias: float | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """The rudder input ``delta (u/U)^2`` and the turn input ``(u/U - 1) (r - b)`` of a recording with
    a measured surge speed ``u`` (``delta`` and ``None`` without one); ``U`` is the run's speed, at which
    the model's derivatives hold; ``b`` the yaw-rate gyro's bias ``r_bias``, or ``mean r`` when it is None.

    Why: a ship slows in its turns (rudder drag, the ``v r`` term of the surge equation; by 10-25 % on
    the basin truth's ``speed_loss`` variant), and the model's forces scale with the speed (Fossen 2011,
    ch. 6.4: rudder forces with ``u^2``, the yaw-rate terms ``Y_r u``, ``K_r u`` and the Coriolis
    ``(M + m) u r``, ``m z u r`` with ``u``; the accelerometer's centripetal ``u r``). With ``U`` held the
    rudder's force is too large in every turn and the yaw rate's too small, an error even in the rudder
    that the roll row absorbs as load. The terms in the speed's variation whose other factor is measured
    (the rudder, the yaw rate) are known inputs, so the model stays linear and time-invariant in its
    states; the sway velocity's ``(u/U - 1)`` times ``Y_v v``, ``n_v v``, ``K_v v`` is a fourth input when the
    fit gives the model's own ``v`` (:func:`model_inputs`' ``sway``), and ``Y_p p`` is left out (``Y_p`` is held at 0).
    The speed's level comes from the run's ``U`` and only its variation ``u / mean(u)`` from the column,
    so a positioning system's scale error does not move the level. The yaw-rate gyro's bias must come out of
    ``r`` (a bias times the speed's variation is not a constant the fit's bias columns would take); ``mean r``
    takes the ship's own mean turning with it, so the fit passes its estimate
    (:func:`identify.rollmass.gyro_bias.gyro_biases`). The speed is low-passed at :data:`SPEED_LP_HZ` first: a ship's speed
    follows its turns with the surge time constant (about 5 s on the model ship, 0.03 Hz), so what a
    positioning system gives above that is its own error, and through ``delta (u/U)^2`` that error
    would be a rudder input in the roll band (measured: basin truth ``speed_loss``, 4-run seed, run 0,
    case 2, +36.1 % / +53 mm unfiltered, +6.3 % / +5.4 mm at 0.2 Hz)."""
    return speed_inputs_at(rec, followed_speed(rec), r_bias)


def speed_inputs_at(rec: RollRecording, s: np.ndarray | None, r_bias: float | None) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`speed_inputs` at the followed speed ``s`` (:func:`followed_speed`; None: held)."""
    if s is None:
        return rec.delta, None
    return rec.delta * s * s, (s - 1.0) * (rec.r - (np.mean(rec.r) if r_bias is None else r_bias))


def speed_variation(rec: RollRecording) -> tuple[float, float]:
    """The sd of the recording's ``u / mean(u)`` below and above :data:`SPEED_LP_HZ` (2nd-order Butterworth,
    zero phase); ``(nan, nan)`` without ``u``, for a recording shorter than two filter periods or sampled
    at under twice the filter's frequency (the split is then not made), and for a ``u`` not finite and
    positive (a ship going astern is not this model; ``shiptrial mass`` refuses such a column,
    :func:`identify.rollmass.recording.read_roll_csv`)."""
    split = _speed_split(rec)
    if split is None:
        return float("nan"), float("nan")
    s, slow = split
    return float(np.std(slow)), float(np.std(s - slow))


def _speed_split(rec: RollRecording) -> tuple[np.ndarray, np.ndarray] | None:
    """``u / mean(u)`` and its part below :data:`SPEED_LP_HZ`, or None where :func:`speed_variation`
    makes no split."""
    if rec.u is None or SPEED_LP_HZ * rec.n * rec.T < 2.0 or SPEED_LP_HZ * rec.T >= 0.5:
        return None
    if not np.all(np.isfinite(rec.u) & (rec.u > 0.0)):
        return None
    s = rec.u / np.mean(rec.u)
    return s, filtfilt(*lowpass(2, SPEED_LP_HZ, 1.0 / rec.T), s, padtype="even")


def followed_speed(rec: RollRecording) -> np.ndarray | None:
    """The speed's variation ``u / mean(u)``, low-passed at :data:`SPEED_LP_HZ`, that :func:`speed_inputs`
    follows; ``None`` (the run's ``U`` held) without ``u``, for a recording too short to split, or when
    the low-passed variation is not clearly above the positioning's error: its sd below
    :data:`SPEED_NOISE_RATIO` times the sd above the low-pass, or below :data:`SPEED_VAR_MIN`.

    Why a test: a positioning system's speed error fed through the speed inputs is a rudder and yaw-rate
    input the fit explains with load. On the independent basin truth's ``base`` variant (a constant
    speed, a positioning error of 1 % scale and 5 mm/s with ~1 s correlation) following ``u`` moved run 0
    case 1 from -15.3 % / -40 mm to -34.0 % / -102 mm, not converged (stop 42). The ship's speed follows
    its turns with the surge time constant (~5 s on the model ship), so above the low-pass the column
    holds the positioning's error alone, and an error with ~1 s correlation has about as much variance
    below 0.2 Hz as above. Measured on the family's recordings as ``estimate_from_files`` reads them
    (``python benchmarks/bench_speed_follow.py --runs 4``: seeds of ``bench_rollmass_truth``, 4 runs x 4
    datasets a variant): the constant-speed variants
    (``base``, ``sway_roll``, ``restoring``, ``imu_mount``, ``waves``) low/high sd ratio 0.67-1.52,
    low-passed sd 0.38-1.02 %, none followed; ``speed_loss`` and ``combined`` (slowing 10-25 % in
    turns) ratio 3.67-21.9, low-passed sd 3.2-15.0 %, all followed.
    Three times the high band separates them (nearest: a ``combined`` recording at 3.67, a constant-speed
    one at 1.52)."""
    if SPEED_LP_HZ <= 0.0 and rec.u is not None:  # no low-pass (a test's switch): the variation as given
        return rec.u / np.mean(rec.u)
    split = _speed_split(rec)
    if split is None:
        return None
    s, slow = split
    slow_sd, fast_sd = np.std(slow), np.std(s - slow)
    return slow if slow_sd >= SPEED_NOISE_RATIO * fast_sd and slow_sd >= SPEED_VAR_MIN else None
