"""Delay or damping by the residual's phase and a delay profile (issue 26, diagnose.delaycheck):
with two runs a 3 s delay and a missing r|r| damping fit about equally well; the residual's
signature tells them apart."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from diagnose import delaycheck


def _zigzag(n: int = 600, seed: int = 0):
    """A first-order ship (T = 30 s) under a +-10 deg zig-zag rudder, sampled at 1 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    delta = np.radians(10.0) * np.sign(np.sin(2 * np.pi * t / 110.0 + 0.3))
    r = np.zeros(n)
    for k in range(n - 1):
        r[k + 1] = r[k] + (0.03 * delta[k] - r[k]) / 30.0
    return t, delta, r, rng


def test_a_delays_residual_is_locked_to_the_rudder_and_a_dampings_is_not():
    t, delta, r_hat, rng = _zigzag()
    shifted = np.interp(t - 3.0, t, r_hat)  # the ship answers 3 s late
    noise = 2e-5 * rng.standard_normal(len(t))
    sig = np.zeros(len(t))  # the damping term's signature: the ship's first-order response to an r|r| force
    for k in range(len(t) - 1):
        sig[k + 1] = sig[k] + (-r_hat[k] * abs(r_hat[k]) - sig[k]) / 30.0
    delay = delaycheck.rudder_phase([shifted - r_hat + noise], [r_hat], [delta], 1.0, [sig])
    damping = delaycheck.rudder_phase([30.0 * sig + noise], [r_hat], [delta], 1.0, [sig])
    assert delay.locked and abs(delay.shift_corr) > 0.9
    assert not damping.locked and abs(damping.damping_corr) > abs(damping.shift_corr)


def test_the_round_keeps_the_delay_or_the_damping_the_evidence_names():
    t, delta, r_hat, rng = _zigzag()
    locked = delaycheck.Phase(-20.0, -0.8, -0.05, 0.08)
    unlocked = delaycheck.Phase(10.0, -0.2, -0.7, 0.08)
    grid = np.arange(0.0, 6.5, 0.5)
    profile = delaycheck.Profile(grid, (grid - 3.0) ** 2 + 1.0)  # minimum at 3 s, inside the grid
    edge = delaycheck.Profile(grid, 10.0 - grid)  # falling to the grid's end: no delay of its own
    assert profile.interior and profile.best_s == 3.0 and not edge.interior
    delay = (SimpleNamespace(effect="actuator_delay"), "d")
    damp = (SimpleNamespace(effect="quadratic_damping"), "q")
    assert delaycheck.choose([damp, delay], locked, profile) is delay
    assert delaycheck.choose([delay, damp], unlocked, profile) is damp
    assert delaycheck.choose([delay, damp], locked, edge) is None  # not decided: the round's held-out choice
    assert delaycheck.choose([delay], locked, profile) is None  # nothing to choose between


def _damping_signature(r_hat: np.ndarray) -> np.ndarray:
    sig = np.zeros(len(r_hat))
    for k in range(len(r_hat) - 1):
        sig[k + 1] = sig[k] + (-r_hat[k] * abs(r_hat[k]) - sig[k]) / 30.0
    return sig


def test_noise_alone_decides_neither_delay_nor_damping():
    """A residual of white or AR(1) noise (time constant 30 s, the yaw's) follows neither
    signature: the rule is undecided even with a delay profile that would admit a delay (it chose
    the delay 36 and the damping 164 times of 200 AR(1) seeds with a band at N samples)."""
    from scipy.signal import lfilter

    t, delta, r_hat, _ = _zigzag(3500)
    sig = _damping_signature(r_hat)
    grid = np.arange(0.0, 6.5, 0.5)
    profile = delaycheck.Profile(grid, (grid - 1.0) ** 2 + 1.0)  # interior minimum at 1 s, half the misfit removed
    decided = {"white": 0, "ar1": 0}
    for seed in range(40):
        e = np.random.default_rng(seed).standard_normal(len(t))
        for kind, res in (("white", e), ("ar1", lfilter([1.0], [1.0, -np.exp(-1.0 / 30.0)], e))):
            phase = delaycheck.rudder_phase([1e-4 * res], [r_hat], [delta], 1.0, [sig])
            decided[kind] += delaycheck.prefer_delay(phase, profile) is not None
    assert decided["white"] == 0
    assert decided["ar1"] <= 2  # a 3-sigma band at the effective sample size: a few per cent at most


def test_a_residual_ahead_of_the_response_is_not_a_delay():
    """r_hat(t + 3) - r_hat(t) is +3 dr/dt: a negative delay, unphysical. It is neither kept as a
    delay nor taken for damping."""
    t, delta, r_hat, rng = _zigzag()
    ahead = np.interp(t + 3.0, t, r_hat) - r_hat + 2e-5 * rng.standard_normal(len(t))
    phase = delaycheck.rudder_phase([ahead], [r_hat], [delta], 1.0, [_damping_signature(r_hat)])
    grid = np.arange(0.0, 6.5, 0.5)
    profile = delaycheck.Profile(grid, (grid - 3.0) ** 2 + 1.0)
    assert phase.shift_corr > 0.9 and not phase.locked
    assert delaycheck.prefer_delay(phase, profile) is None
