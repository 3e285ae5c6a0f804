"""Wall-sided roll restoring beyond the linear term, as a known roll moment from the measured roll angle.

The linear model's restoring is ``C phi`` (Linder et al. 2015, eq. (3) with (5a)). A wall-sided hull
(sides vertical over the heeled range) has the righting arm of the wall-sided formula (e.g. Biran 2003, Ship Hydrostatics and Stability)

    GZ(phi) = sin(phi) (GM + BM/2 tan^2 phi),    BM = I_T / V,

so its restoring moment is ``Delta g GZ`` with ``Delta = rho V``. The ``BM`` part is
``rho g I_T / 2 sin(phi) tan^2(phi)``: the waterplane's inertia ``I_T`` does not change as a
wall-sided hull sinks, so that term is the same for every load (a load changes V and BM = I_T / V
together). On the 1:24 Our Lass II (BM 0.083 m from Table 1, :func:`~identify.rollmass.model.metacentric_radius`; GM 0.018 m) it is 0.6 % of the linear restoring at
3 deg of heel and 2.5 % at 6 deg; the load's own restoring is about 25 % of it for 0.4 kg, so an
amplitude-dependent restoring left out reads as part of the load.

The roll angle is measured (an AHRS's roll output, the recording's ``phi`` column), so the moment
beyond ``C phi`` is a known input computed once per recording, and the model stays linear in its
states (its rudder response, free response and Jacobian unchanged in form):

    tau_heel(t) = -kappa w(t),   kappa = M g BM / 2,
    w(t) = sin(phi) tan^2(phi) + (2 GM / BM) (sin(phi) - phi),

with the nominal ship's ``M``, ``GM`` and ``BM`` (:class:`~identify.rollmass.model.Known`). The second
term of ``w`` is ``GM``'s share, ``-GM phi^3 / 6`` to third order: 6.5 % of the moment on Our Lass II,
taken at the nominal GM for every load (a load's change of GM moves it by under 2 % of itself).

The oe fit frees ``kappa`` from the hull's value (``output_error.FIT_KAPPA``): the recording's roll
angle has been through the same filters as the other channels, and a filter whose gain is not one
(the paper's order-20 FIR has 0.935 at 0 Hz) scales ``phi^3`` by its cube but the moment only once, so
the hull's ``kappa`` is not the one the filtered data obey. Measured, noise-free independent basin truth
(``restoring``, ``simulate_runs("restoring", 2, 3015)`` run 0, case 2): ``kappa`` held at the hull's
9.0 N m gave -40.5 % / -105 mm, fitted (12.3 N m) +0.24 % / +0.2 mm; without the term +23.8 % / +33 mm.

The AHRS's roll angle has its own error (an MTi-G: 0.5 deg static), and through the cubic a bias ``b``
adds a moment ``3 kappa b phi^2`` that reads as load, so the angle is re-referenced to the heel the
accelerometer reads (:func:`referenced_heel`). Measured on the basin truth with an AHRS error
(``python benchmarks/bench_heel_reference.py --runs 4 --variants restoring``): median |mean error|
0.356 deg as recorded, 0.043 deg referenced; on the noise-free half-length ``restoring`` case 2 with
0.5 deg added (tests/test_rollmass_restoring.py, ``test_a_roll_angle_bias_does_not_read_as_load``),
-9.65 % / -13.8 mm as recorded (``heel_reference="raw"``), +0.44 % / +0.5 mm referenced, with the bias
and without it. Re-measured at stop 43 with the offset divided by ``cos(phi)`` before the low-pass
(stop 42's order; the figures were first taken with the division after it): the same to the digits shown.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from identify.rollmass.model import Known
from primitives.iir import butter, filtfilt  # scipy.signal's, without its import (2 s of CPU)

if TYPE_CHECKING:  # simulate imports this module
    from identify.rollmass.simulate import RollRecording

# How the AHRS roll angle is referenced before it enters the heel signal (see :func:`referenced_heel`):
# "raw" as recorded, "mean" each recording's mean taken out, "acc" its mean re-referenced to the
# accelerometer's heel, "acc-lp" its slow part (below ACC_LP_HZ) re-referenced to the accelerometer's heel.
# The choice is a parameter of the estimator (``estimate(..., heel_reference=...)``), not a module
# setting: a setting made in one process is not seen by workers it spawns.
HEEL_REFERENCES = ("raw", "mean", "acc", "acc-lp")
DEFAULT_HEEL_REFERENCE = "acc-lp"
ACC_LP_HZ = 0.05  # 20 s: longer than a joystick turn (1-6 s), shorter than an AHRS's gravity-correction drift


def heel_signal(phi: np.ndarray, kn: Known) -> np.ndarray:
    """``w(t)`` of the module docstring (dimensionless); zero when the profile gives no ``BM``."""
    if kn.BM <= 0.0:
        return np.zeros_like(phi)
    s = np.sin(phi)
    return s * np.tan(phi) ** 2 + (2.0 * kn.GM / kn.BM) * (s - phi)


def heel_gain(kn: Known) -> float:
    """``kappa = M g BM / 2`` [N m]: ``rho g I_T / 2`` of the module docstring."""
    return 0.5 * kn.M * kn.g * kn.BM


def gravity_excess(phi: np.ndarray, g: float) -> np.ndarray:
    """``g (sin phi - phi)`` [m/s^2]: what the lateral accelerometer reads of gravity beyond the linear
    model's ``g phi`` (its specific force has ``g sin phi``, Linder et al. 2015, eq. (7) before linearising)."""
    return g * (np.sin(phi) - phi)


def accelerometer_heel_offset(rec: RollRecording, g: float, U: float) -> np.ndarray:
    """``sin(phi) - (a_s + u r) / g`` per sample: the AHRS roll angle's offset from the heel the lateral
    accelerometer reads. ``a_s = g sin(phi) - v' - u r - x_s r' + z_s p'`` (Linder et al. 2015, eq. (7)
    before linearising, with the centripetal ``u r``), and ``v'``, ``r'`` and ``p'`` average out over
    longer than a turn, so the slow part of this offset is the AHRS's roll error (bias and drift),
    left with the accelerometer's own bias (MTi-G: 0.02 m/s^2, 0.12 deg) and ``u`` times the yaw gyro's.
    ``u`` is the recording's surge speed when it has one, else ``U``."""
    u = rec.u if rec.u is not None else U
    return np.sin(rec.phi) - (rec.a_s + u * rec.r) / g


def referenced_heel(rec: RollRecording, g: float, U: float, how: str = DEFAULT_HEEL_REFERENCE) -> np.ndarray | None:
    """The recording's roll angle with its AHRS error estimated and taken out (``how``: one of
    :data:`HEEL_REFERENCES`); ``None`` without a ``phi`` column.

    Why: the heel moment ``-kappa w(phi)`` is cubic, so a roll bias ``b`` adds ``3 b phi^2``, a moment
    even in the heel that reads as load (measured: 0.5 deg moved the noise-free basin truth ``restoring``
    case 2 from +0.24 % to -5.1 %). Taking each recording's mean out removes the bias but also the true
    mean heel of its turns; the accelerometer's heel does not have that trade (see
    :func:`accelerometer_heel_offset`).

    The offset ``d = sin(phi) - (a_s + u r)/g`` is ``cos(phi) b`` to first order in the bias ``b``, so
    ``d / cos(phi)`` is divided sample by sample *before* the low-pass: dividing the low-passed ``d`` by
    the instantaneous ``cos(phi)`` would put the turns' heel back into the slow part (a 20 deg turn:
    1 / cos 20 deg, 6 % of the bias). Without a ``u`` column the centripetal ``u r`` is taken at the
    run's ``U`` (a ship that slows in a turn then leaves ``(U - u) r / g`` in the offset); ``mass``
    (:func:`identify.rollmass.api.estimate_from_files`) drops a ``u`` whose variation is within the
    positioning's error (:func:`identify.rollmass.speed.followed_speed`), so it is used here only
    where the model follows it too."""
    if rec.phi is None:
        return None
    if how not in HEEL_REFERENCES:
        raise ValueError(f"heel reference must be one of {HEEL_REFERENCES}")
    if how == "raw":
        return rec.phi
    if how == "mean":
        return rec.phi - rec.phi.mean()
    bias = accelerometer_heel_offset(rec, g, U) / np.cos(rec.phi)
    if how == "acc" or ACC_LP_HZ * rec.n * rec.T < 2.0:  # a recording shorter than two filter periods: its mean
        return rec.phi - bias.mean()
    b, a = butter(1, ACC_LP_HZ, fs=1.0 / rec.T)
    return rec.phi - filtfilt(b, a, bias, padtype="even")
