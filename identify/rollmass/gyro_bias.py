"""The yaw-rate gyro's bias of each recording, as the output-error fit's turn input needs it.

The turn input ``(u/U - 1) (r - b)`` (:func:`identify.rollmass.output_error.speed_inputs`) must have the
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
efficient. The turn input enters the mean of ``r`` only through ``(u/U - 1)``, whose mean is about zero, so the
estimate depends only a little on the bias the input was built with: :func:`gyro_biases` iterates
:data:`PASSES` times from it (measured on ``speed_loss`` seed 5015 run 0 case 1 at the fit's optimum, true biases
-0.0109 / -0.0035 / -0.0033 rad/s: one pass from ``mean r`` gave -0.0109 / -0.0047 / -0.0031, two -0.0110 /
-0.0034 / -0.0033), and the fit re-estimates it at each reweighting
(:func:`identify.rollmass.oe_fit.fit_output_error`).
"""

from __future__ import annotations

import numpy as np

from identify.rollmass.model import Known, Load
from identify.rollmass.output_error import _simulate, followed_speed
from identify.rollmass.simulate import RollRecording

PASSES = 3  # fixed-point passes of gyro_biases (each one simulation a dataset)


def gyro_bias(v: dict[str, float], kn: Known, z_f: float, load: Load, rec: RollRecording, r_bias: float | None = None) -> float:
    """The yaw-rate gyro's bias of ``rec`` (rad/s): the constant of ``r - r_model`` on the free-response
    basis and a constant, at parameters ``v`` (the turn input built with ``r_bias``, as the fit has it)."""
    yhat, basis = _simulate(v, kn, z_f, load, rec, r_bias)
    coef, *_ = np.linalg.lstsq(basis, rec.r - yhat[:, 2], rcond=None)
    return float(coef[-1])  # free_basis's last column is the constant


def gyro_biases(
    v: dict[str, float], kn: Known, z_f: float, loads: list[Load], datasets: list[RollRecording], r_bias: list[float | None]
) -> list[float | None]:
    """:func:`gyro_bias` of every dataset that has a turn input (a followed speed), :data:`PASSES` fixed-point
    passes from ``r_bias`` (None: ``mean r``); None for the others (their model has no turn input to correct)."""
    out = list(r_bias)
    for i, (rec, load) in enumerate(zip(datasets, loads)):
        if followed_speed(rec) is None:
            out[i] = None
            continue
        for _ in range(PASSES):
            out[i] = gyro_bias(v, kn, z_f, load, rec, out[i])
    return out
