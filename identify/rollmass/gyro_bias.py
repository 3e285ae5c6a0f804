"""The yaw-rate gyro's bias and the sway velocity of each recording, as the output-error fit's speed inputs need them.

The turn input ``(u/U - 1) (r - b)`` (:func:`identify.rollmass.speed.speed_inputs`) must have the
gyro's bias ``b`` out of the measured ``r``: a bias times the speed's variation is not a constant the fit's
bias columns take. Taking ``b`` as the recording's ``mean r`` also takes out the ship's own mean turning
(0.022-0.032 rad/s on the basin truth's ``speed_loss`` recordings against gyro biases of 0.003-0.011 rad/s),
and leaves ``U (u/U - 1) mean(r)`` in the model's error: a low-band structure in ``r`` and ``a_s`` that
the AR whiteners then discount, and with it the roll band's information on the load (stop 47).

The estimate here: the bias is what the measured ``r`` has on top of the model's yaw rate. At the fit's
current parameters the model's rudder-driven ``r`` carries the ship's own mean turning (the yaw row's
steady-state gain times the mean rudder), so the constant of the least-squares fit of ``r - r_model`` on
the free-response basis and a constant (the same basis the fit projects out,
:func:`identify.rollmass.sensitivity.free_basis`) is the gyro's bias. It is separable from the ship's turning
because the turns go both ways and the recording has straight stretches: the model's ``r`` then has its own
mean, not a free one. Unwhitened least squares: unbiased under the coloured residual, if not the most
efficient. What it calls the bias is ``mean(r) - mean(r_model)``, so it is the gyro's bias only as far as the
model's steady turning is right: a rudder zero off by ``delta_0`` (or a ship that needs ``delta_0`` to go straight,
from its propeller's torque; the model is symmetric) puts the yaw gain times ``delta_0`` into it (0.011 rad/s a
degree on the model ship at 0.5 m/s), and a yaw gain off by a fraction puts that fraction of the mean turn in;
``mean r`` puts the whole mean turn in. So this is the better estimate while the model predicts the mean turn
better than zero does; the basin truth's rudder zero is off by 0.05 deg sd and its hull symmetric, so a larger
offset is not measured there. The fit's covariance holds the estimate (and the sway velocity) fixed: on the case
below a bias error of 0.001 rad/s moves the load by 0.6-4 g at this code's final stage (linearised, its
whitening), against the load's sd of 156 g that the fit reports there (its sandwich interval), so the intervals
do not need its uncertainty. The turn input enters the mean of ``r`` only through ``(u/U - 1)``, whose mean is
about zero, so the estimate depends only a little on the bias the input was built with: :func:`gyro_biases`
iterates :data:`PASSES` times from it (measured on ``speed_loss`` seed 5015 run 0 case 1 at the optimum of the
fit before this module (stop 47's, which took ``mean r``), true biases
-0.0109 / -0.0035 / -0.0033 rad/s: one pass from ``mean r`` gave -0.0109 / -0.0047 / -0.0031, two -0.0110 /
-0.0034 / -0.0033), and the fit re-estimates it at each reweighting
(:func:`identify.rollmass.oe_fit.fit_output_error`).

The same stop found the rest of that low-band structure in the speed's other share: the ship's sway-velocity
derivatives scale with its speed too (``Y_v u``, ``K_v u``, ``N_v u``; Fossen 2011, ch. 6.4), a term
``(u/U - 1) (Y_v, K_v, n_v) v`` that the turn input leaves out. ``v`` is not measured, so
:func:`sway_velocity` gives the model's own at the last stage's parameters (a fixed point like the bias), and
the model takes it as a fourth known input (:func:`identify.rollmass.output_error.model_inputs`). On the
model's time-varying twin (tests/test_rollmass_gyro_bias.py) it takes the constant-speed model's error in
``a_s`` from 0.0099 to 0.0019 m/s^2 rms.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from identify.rollmass.model import Known, Load
from identify.rollmass.output_error import _simulate, model_inputs, model_matrices, respond
from identify.rollmass.simulate import RollRecording
from identify.rollmass.speed import followed_speed

PASSES = 3  # fixed-point passes of gyro_biases and sway_velocities (each one simulation a dataset)


def gyro_bias(
    v: dict[str, float],
    kn: Known,
    z_f: float,
    load: Load,
    rec: RollRecording,
    r_bias: float | None = None,
    sway: np.ndarray | None = None,
) -> float:
    """The yaw-rate gyro's bias of ``rec`` (rad/s): the constant of ``r - r_model`` on the free-response
    basis and a constant, at parameters ``v`` (the turn inputs built with ``r_bias`` and ``sway``, as the fit has them)."""
    yhat, basis = _simulate(v, kn, z_f, load, rec, r_bias, sway)
    coef, *_ = np.linalg.lstsq(basis, rec.r - yhat[:, 2], rcond=None)
    return float(coef[-1])  # free_basis's last column is the constant


def gyro_biases(
    v: dict[str, float],
    kn: Known,
    z_f: float,
    loads: list[Load],
    datasets: list[RollRecording],
    r_bias: list[float | None],
    sway: list[np.ndarray | None] | None = None,
) -> list[float | None]:
    """:func:`gyro_bias` of every dataset that has a turn input (a followed speed), :data:`PASSES` fixed-point
    passes from ``r_bias`` (None: ``mean r``); None for the others (their model has no turn input to correct)."""
    sway = sway if sway is not None else [None] * len(datasets)
    return _fixed_point(datasets, r_bias, lambda i, b: gyro_bias(v, kn, z_f, loads[i], datasets[i], b, sway[i]))


def sway_velocity(
    v: dict[str, float], kn: Known, z_f: float, load: Load, rec: RollRecording, r_bias: float | None, sway: np.ndarray | None
) -> np.ndarray:
    """The model's sway velocity state ``v(t)`` (from rest) at parameters ``v``, driven by the inputs the fit
    gives it (:func:`identify.rollmass.output_error.model_inputs`, with ``r_bias`` and ``sway``)."""
    A, B, _, _ = model_matrices(v, kn, z_f, load, rec.U)
    inputs = model_inputs(v, kn, rec, r_bias, sway)
    return respond(A, B, np.eye(4)[:1], np.zeros((1, B.shape[1])), rec.T, inputs, rec.n)[0][:, 0]


def sway_velocities(
    v: dict[str, float],
    kn: Known,
    z_f: float,
    loads: list[Load],
    datasets: list[RollRecording],
    r_bias: list[float | None],
    sway: list[np.ndarray | None],
) -> list[np.ndarray | None]:
    """:func:`sway_velocity` of every dataset with a followed speed, :data:`PASSES` fixed-point passes."""
    return _fixed_point(datasets, sway, lambda i, s: sway_velocity(v, kn, z_f, loads[i], datasets[i], r_bias[i], s))


def speed_terms(
    v: dict[str, float],
    kn: Known,
    z_f: float,
    loads: list[Load],
    datasets: list[RollRecording],
    r_bias: list[float | None],
    sway: list[np.ndarray | None],
    with_sway: bool = True,
) -> tuple[list[float | None], list[np.ndarray | None]]:
    """The speed inputs' gyro biases and (``with_sway``) sway velocities at parameters ``v``, each from the
    last stage's: what :func:`identify.rollmass.oe_fit.fit_output_error` passes the next stage's model."""
    r_bias = gyro_biases(v, kn, z_f, loads, datasets, r_bias, sway)
    return r_bias, sway_velocities(v, kn, z_f, loads, datasets, r_bias, sway) if with_sway else sway


def _fixed_point(datasets: list[RollRecording], start: list, step: Callable[[int, object], object]) -> list:
    """``step(i, x)`` iterated :data:`PASSES` times from ``start[i]`` for each dataset with a followed speed;
    None for the others."""
    out = list(start)
    for i, rec in enumerate(datasets):
        out[i] = None
        if followed_speed(rec) is not None:
            x = start[i]
            for _ in range(PASSES):
                x = step(i, x)
            out[i] = x
    return out
