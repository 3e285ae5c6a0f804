"""The yaw row's measured inputs of one recording (:func:`signals`) and how its derived inputs are
recomputed on a simulated record (:class:`Deriver`): the same derivation for the recording, the
prior's fit and the no-change records, and whether that derivation is linear in the signals (which
lets :func:`identify.detect.nullsim.null_records` filter the records' noise once per job)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diagnose.recording import Recording, RecordingError
from identify.detect.checks import MOMENT, time_derivative
from identify.detect.vessel import base_profile
from identify.detect.yawmodel import PREFILTER_HZ, SIGNALS, model_inputs
from identify.yawid.experiment import pod_yaw_moment

POD_COLUMNS = ("n1", "alpha1", "n2", "alpha2")
SWAY_ACC = "v_dot"  # measured sway acceleration, m/s^2 (Table 4.1 of seed 000 measures it)


def signals(rec: Recording, kind: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The yaw row's measured inputs and the measured yaw rate of one recording.

    v' is the recording's ``v_dot`` column (measured sway acceleration, m/s^2) when it has one,
    else a Savitzky-Golay derivative of v (2 s window; a smoothed v' that biases the prior's
    I_r); tau_r is the recording's ``tau_n`` column (measured pod yaw moment, N m) when it has
    one, else the pods' yaw moment from the pod inputs and the low-passed measured motion (u,
    v fused with v', r, and the roll rate: column ``p``, else the rate of phi) -- noise on the
    motion then enters tau_r and biases the prior (+12 to +14 % on I_r in 400 s at Table 4.1 noise)."""
    u, v, r = rec.y[:, 0], rec.y[:, 1], rec.y[:, 2]
    sig = {"u": u, "v": v} | ({"tau_r": rec.channels[MOMENT]} if MOMENT in rec.channels else {})
    if "phi" in SIGNALS[kind]:
        sig["phi"] = _column(
            rec, "phi", "(roll, rad) that the full model (2.17) needs; add it or use the simplified model (--model simplified)"
        )
        if SWAY_ACC in rec.channels:
            sig["v_dot"] = rec.channels[SWAY_ACC]
    if "p" in SIGNALS[kind]:
        sig["p"] = _column(
            rec,
            "p",
            "(roll rate, rad/s) that the prior's yaw row needs (its roll-rate term N_p p); add it, or refit the "
            "prior with detect-prior --no-roll-rate",
        )
    return Deriver.of(rec, kind)(sig, r), r


def _column(rec: Recording, name: str, why: str) -> np.ndarray:
    """The recording's column ``name``; without it, a RecordingError saying ``why`` it is needed."""
    if name not in rec.channels:
        raise RecordingError(f"{rec.source}: no column '{name}' {why}")
    return rec.channels[name]


@dataclass(frozen=True, eq=False)
class Deriver:
    """``derive(sig, r) -> sig``: the model inputs SIGNALS[kind] from measured u, v (, phi, p,
    v_dot, tau_r) and r, each (n,) or (n, runs) (the no-change simulation derives them as for the
    recording). ``pods``: the recording's pod inputs (its angles alpha_i are the profile's inputs
    delta_i), None when the recording measures the pod yaw moment ``tau_n``."""

    kind: str
    dt: float
    measured_vdot: bool
    pods: dict[str, np.ndarray] | None = None
    p_rec: np.ndarray | None = None  # the recording's roll rate (the pods move sideways with it)

    @classmethod
    def of(cls, rec: Recording, kind: str) -> Deriver:
        """The derivation the recording ``rec`` needs for a prior of ``kind``."""
        measured_tau = MOMENT in rec.channels
        pods = None if measured_tau else {c.replace("alpha", "delta"): rec.channels[c] for c in POD_COLUMNS}
        return cls(kind, rec.sample_time, SWAY_ACC in rec.channels, pods, rec.channels.get("p"))

    @property
    def linear(self) -> bool:
        """Whether the derived inputs are a linear map of the signals that does not read r, so that
        derive(s + e, r + e_r) = derive(s, r) + derive(e, e_r) (to rounding).

        True exactly when the recording measures the pod yaw moment: tau_r is then the measured
        tau_n, and the only derived input is v' = dv/dt (a Savitzky-Golay derivative: a convolution
        and least-squares fits at the edges, both linear), or the measured v'. From the pod inputs, tau_r is the pods' moment tau_n of (2.12) (the
        thesis's pod forces), nonlinear in the motion (the drift angle atan(v/u), the inflow speed
        squared) and a function of r: False."""
        return self.pods is None

    @property
    def derived(self) -> frozenset[str]:
        """The model inputs this derivation computes rather than reads from a sensor: tau_r from the pod inputs
        (no ``tau_n`` column), v_dot from v (no ``v_dot`` column). Their noise is not a sensor's low-passed noise,
        so a noise model of sensors (:func:`identify.detect.priorfit.read_noise`) reads them white."""
        out = {"tau_r"} if self.pods is not None else set()
        if "v_dot" in SIGNALS[self.kind] and not self.measured_vdot:
            out.add("v_dot")
        return frozenset(out)

    @property
    def form(self) -> tuple:
        """What the derivation does with its signals, as a key: two derivations of one form give
        the same inputs from the same signals (recordings of one job share their no-change noise)."""
        return (self.kind, self.dt, self.measured_vdot, self.pods is None)

    def __call__(self, sig: dict[str, np.ndarray], r: np.ndarray) -> dict[str, np.ndarray]:
        out = dict(sig)
        v = sig["v"]
        if "v_dot" in SIGNALS[self.kind] and not self.measured_vdot:
            out["v_dot"] = time_derivative(v, self.dt)
        if self.pods is None:
            return {k: out[k] for k in SIGNALS[self.kind]}
        col = (slice(None),) + (None,) * (v.ndim - 1)  # recorded channels broadcast over runs
        # roll rate moves the pods sideways (z_pod p): measured p, else the rate of the measured roll
        if "p" in sig:  # the prior's own roll-rate input (noisy in the no-change records)
            p = sig["p"]
        elif self.p_rec is not None:
            p = np.broadcast_to(self.p_rec[col], v.shape)
        else:
            p = time_derivative(sig["phi"], self.dt) if "phi" in sig else np.zeros_like(v)
        # the pod model is nonlinear in the motion (drift angle, speed squared): feed it the
        # low-passed motion (v fused with v'), as the prior's inputs are, so noise does not bias tau_r
        motion = model_inputs(
            {"u": sig["u"], "v": v, "r": r, "p": p} | ({"v_dot": out["v_dot"]} if "v_dot" in out else {}), self.dt, PREFILTER_HZ
        )
        out["tau_r"] = pod_yaw_moment(
            base_profile(), {k: x[col] for k, x in self.pods.items()}, **{k: motion[k] for k in ("u", "v", "r", "p")}
        )
        return {k: out[k] for k in SIGNALS[self.kind]}
