"""Manoeuvres and simulated recordings for the yaw identification (the podded-ship MSc thesis, sections 3.1 and 4.3).

Three input programmes for a two-pod profile (inputs n1, delta1, n2, delta2; both pods steered
alike, as in the thesis):

- :func:`turn_pulse` -- experiment 1 of chapter 3 (L944-966): both propellers at n from rest, a
  low-pass filtered pod-angle pulse after 50 s.
- :func:`harbour_exit` -- experiment 2 (L968-983): pods at 90 deg, propellers on at 10 s and off at
  50 s. In this model it drives the ship astern (u < 0), which breaks the lumped A u r term of
  (2.17); kept only to show that (:func:`identify.yawid.model.forward_only`).
- :func:`identification_run` -- ours for chapter 4's 10 min at 10 Hz: from rest, pod-angle pulses of
  random sign, size (5-20 deg) and length (15-60 s) with straight gaps, and propeller-speed steps
  (55-80 rev/s) so that u varies and A u r separates from N_r|r| r|r|. The pod angle stays within
  20 deg, where the pod model of (2.9)-(2.10) is "fairly accurate" (L457-459), and the ship keeps
  going ahead (u >= 0 throughout, checked), so the model (2.17) stays valid.

Choices: the pod-angle low-pass filter (not specified in the thesis) is first order with a 5 s
time constant; RPM changes are steps (no spin-up dynamics in the thesis).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from identify.yawid.model import forward_only
from primitives.errors import UserError
from primitives.ship import ShipProfile
from primitives.simulate import model_signals, simulate

POD_FILTER_S = 5.0


def pods_inputs(n: np.ndarray, delta: np.ndarray, ts: float, tau_s: float = POD_FILTER_S) -> np.ndarray:
    """Inputs (N, 4) with both pods alike; the commanded pod angle through a first-order lag."""
    from scipy.signal import lfilter  # here: the simulations need it, a detect run on a recording does not (its 2 s import)

    a = np.exp(-ts / tau_s)
    d = lfilter([1 - a], [1, -a], delta)
    return np.stack([n, d, n, d], axis=-1)


def turn_pulse(
    ts: float, duration_s: float = 200.0, n: float = 80.0, angle_deg: float = -10.0, start_s: float = 50.0, length_s: float = 50.0
) -> np.ndarray:
    """Experiment 1 of chapter 3: straight run from rest at n rev/s, then a pod-angle pulse."""
    t = np.arange(int(round(duration_s / ts))) * ts
    delta = np.where((t >= start_s) & (t < start_s + length_s), np.radians(angle_deg), 0.0)
    return pods_inputs(np.full(t.size, n), delta, ts)


def harbour_exit(ts: float, duration_s: float = 120.0, n: float = 80.0) -> np.ndarray:
    """Experiment 2 of chapter 3 ("yaw-axis rotation"): pods at 90 deg, propellers on 10-50 s."""
    t = np.arange(int(round(duration_s / ts))) * ts
    on = np.where((t >= 10.0) & (t < 50.0), n, 0.0)
    return np.stack([on, np.full(t.size, np.pi / 2), on, np.full(t.size, np.pi / 2)], axis=-1)


def identification_run(ts: float, seed: int, duration_s: float = 600.0) -> np.ndarray:
    """Our 10-minute forward-only manoeuvring programme (see the module docstring)."""
    rng = np.random.default_rng(seed)
    n_samples = int(round(duration_s / ts))
    t = np.arange(n_samples) * ts
    delta = np.zeros(n_samples)
    t0, sign = 40.0, rng.choice([-1.0, 1.0])
    while t0 < duration_s:
        length = rng.uniform(15.0, 60.0)
        delta[(t >= t0) & (t < t0 + length)] = sign * np.radians(rng.uniform(5.0, 20.0))
        t0 += length + rng.uniform(5.0, 30.0)
        sign = -sign if rng.random() < 0.8 else sign
    n = np.full(n_samples, 80.0)
    for start in np.arange(100.0, duration_s, 100.0):
        n[t >= start] = rng.uniform(55.0, 80.0)
    return pods_inputs(n, delta, ts)


@dataclass(frozen=True)
class Noise:
    """White measurement noise per signal (Table 4.1 of the podded-ship MSc thesis), standard deviations in SI."""

    r: float = 0.0025
    v_dot: float = 0.015
    u: float = 0.15
    v: float = 0.15
    phi: float = 0.025
    tau_r: float = 5e4

    def scaled(self, k: float) -> Noise:
        return replace(self, **{f.name: k * getattr(self, f.name) for f in fields(self)})


SIGNALS = tuple(f.name for f in fields(Noise))  # the yaw model's signals, one noise level each


@dataclass
class YawData:
    """Sampled signals of the yaw model, each (N,) or (B, N): r, v_dot, u, v, phi, tau_r at t."""

    t: np.ndarray
    signals: dict[str, np.ndarray]
    source: str = "simulation"
    notes: tuple[str, ...] = ()  # the recording reader's (a last row cut short and left out)

    @property
    def sample_time(self) -> float:
        return float(self.t[1] - self.t[0])


def true_signals(profile: ShipProfile, inputs: np.ndarray, theta: str | None = None) -> YawData:
    """Noise-free yaw-model signals of a kernel simulation of ``profile`` (4-DOF, pods).

    v_dot is the kernel's own Euler increment (v(k+1) - v(k)) / Ts, tau_r the pods' yaw moment
    (2.12) at sample k: with these the full model (2.17) reproduces the kernel's yaw rate exactly.
    """
    if not profile.pods or profile.n_dof != 4:
        raise UserError(f"ship {profile.name!r}: the yaw identification needs a 4-DOF profile with pods (e.g. 'naval-vessel')")
    res = simulate(profile, inputs, theta)
    return YawData(res.t[:-1], yaw_row_signals(profile, res.nu[0], res.eta[0], inputs))


def yaw_row_signals(profile: ShipProfile, nu: np.ndarray, eta: np.ndarray, inputs: np.ndarray) -> dict[str, np.ndarray]:
    """r, v_dot, u, v, phi, tau_r at samples 0 .. N-1 of a kernel trajectory ``nu``, ``eta`` (N+1, 4)
    driven by ``inputs`` (N, m): v_dot the Euler increment, tau_r the profile's pod yaw moment (2.12)."""
    in_sig = {name: inputs[:, i] for i, name in enumerate(profile.inputs)}
    u, v, r, p = nu[:-1].T
    return {
        "r": r,
        "v_dot": np.diff(nu[:, 1]) / profile.sample_time,
        "u": u,
        "v": v,
        "phi": eta[:-1, 3],
        "tau_r": pod_yaw_moment(profile, in_sig, u, v, r, p),
    }


def pod_yaw_moment(
    profile: ShipProfile, inputs: dict[str, np.ndarray], u: np.ndarray, v: np.ndarray, r: np.ndarray, p: np.ndarray | None = None
) -> np.ndarray:
    """The pods' yaw moment tau_n of (2.12) from the pod inputs (named as ``profile.inputs``: n1,
    delta1, ...) and the motion, by the kernel's own signal function (``model_signals``); all
    arrays broadcast together (e.g. (n, 1) inputs with (n, runs) motion)."""
    nu = np.stack(np.broadcast_arrays(u, v, r, np.zeros_like(u) if p is None else p), axis=-1)
    return np.asarray(model_signals(profile, nu, np.zeros(nu.shape[:-1]), inputs)["tau_n"], float)


def measure(clean: YawData, noise: Noise, runs: int, seed: int, first: int = 0) -> YawData:
    """Noisy realisations first .. first + runs - 1, (B, N), of the clean signals; run i's noise
    depends on (seed, i) only."""
    out = {k: np.empty((runs, clean.t.size)) for k in SIGNALS}
    for row, i in enumerate(range(first, first + runs)):
        rng = np.random.default_rng([seed, i])
        for k in SIGNALS:
            out[k][row] = clean.signals[k] + rng.normal(0.0, getattr(noise, k), clean.t.size)
    return YawData(clean.t, out, clean.source)


def check_forward(data: YawData, what: str) -> None:
    """Refuse a recording in which the ship goes astern: A u r of (2.17) needs u >= 0."""
    frac = forward_only(data.signals["u"], tol=0.5)
    if frac > 0.01:  # a few noisy samples near rest are not a manoeuvre astern
        raise UserError(
            f"{what}: the ship goes astern (u < -0.5 m/s) in {100 * frac:.1f} % of the samples; "
            "the lumped A u r of (2.17) needs u >= 0 (use a forward-only manoeuvre)"
        )
