"""Delay or damping, told by the residual's phase against the rudder and by a delay profile of
the fit, not by the fit gain alone (issue 26: with two runs a 3 s delay was claimed as
quadratic damping).

A missing actuator delay tau shifts the ship's response to the rudder: the yaw residual of the
simulation is about r_hat(t - tau) - r_hat(t) = -tau dr_hat/dt, in phase with the model's yaw
acceleration, a quarter period ahead of the yaw rate. A missing damping term r|r| leaves a
residual in phase with the model's response to an r|r| force (the damping slot's sensitivity). So the residual's phase
against the rudder tells them apart: the lag of its cross-correlation with the rudder angle,
measured from the lag of the model's own yaw rate (negative: ahead of the yaw rate, a delay's),
and its correlation with the two signatures (Box, Jenkins & Reinsel 2008, section 11.1: sample
cross-correlations and their band). A simulation residual is strongly autocorrelated (the yaw
time constant is tens of samples), so the band is taken at Bartlett's (1935) effective sample size
for the correlation of two autocorrelated series, N_eff = N / sum_k rho_res(k) rho_sig(k)
(Bretherton et al. 1999, J. Climate 12, 1990-2009), not at N. A delay's residual is -tau dr/dt, so
its correlation with the yaw acceleration must be negative (a positive one would be a negative,
unphysical delay). The fit as a function of an assumed delay (a profile: residual sum of squares
over a grid of delays, the other parameters held) is the other test: a real delay has its minimum
inside the grid and removes a clear part of the misfit. When neither signature is clearly
followed the rule is undecided and the round keeps its held-out choice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from diagnose.model import AugmentedModel, Prepared, residuals, stack

BAND = 3.0  # the correlation band in units of 1/sqrt(N_eff)
MIN_DROP = 0.2  # a delay's profile removes at least this fraction of the no-delay misfit
MAX_LAG_S = 60.0  # cross-correlation lags searched, full-scale seconds (about a zig-zag's half period)


@dataclass(frozen=True)
class Phase:
    """The yaw residual against the rudder and the model's response."""

    lag_s: float  # lag of |xcorr(residual, rudder)|'s peak minus that of the model's yaw rate (reported, not used)
    shift_corr: float  # correlation with the model's yaw acceleration (a delay's signature: negative)
    damping_corr: float  # correlation with the model's response to the damping term (its signature)
    band: float  # |correlation| above this is not noise (BAND / sqrt(N_eff) at the smaller N_eff of the two signatures')

    @property
    def locked(self) -> bool:
        """The residual is a positive time shift of the response to the rudder (a delay's signature)."""
        return -self.shift_corr > self.band and -self.shift_corr > abs(self.damping_corr)

    @property
    def damped(self) -> bool:
        """The residual follows the damping term's signature more than a delay's, above noise."""
        return abs(self.damping_corr) > self.band and abs(self.damping_corr) > abs(self.shift_corr)


def _corr(a: list[np.ndarray], b: list[np.ndarray], lag: int = 0) -> float:
    """Sample cross-correlation of a(k + lag) with b(k), pooled over runs (each demeaned)."""
    num = aa = bb = 0.0
    for x, y in zip(a, b):
        x, y = x - x.mean(), y - y.mean()
        x, y = (x[lag:], y[: len(y) - lag]) if lag >= 0 else (x[:lag], y[-lag:])
        num, aa, bb = num + float(x @ y), aa + float(x @ x), bb + float(y @ y)
    return num / np.sqrt(max(aa * bb, 1e-300))


def _acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of x at lags 0..max_lag (biased estimator, x demeaned)."""
    x = x - x.mean()
    n = len(x)
    f = np.fft.rfft(x, 2 * n)
    c = np.fft.irfft(f * np.conj(f))[: max_lag + 1]
    return c / max(c[0], 1e-300)


def n_eff(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    """Effective number of independent samples for the correlation of a with b, pooled over runs:
    sum over runs of N / (1 + 2 sum_{k=1}^{N/4} rho_a(k) rho_b(k)) (Bartlett 1935; Bretherton et
    al. 1999), at most N."""
    total = 0.0
    for x, y in zip(a, b):
        m = max(1, len(x) // 4)
        s = 1.0 + 2.0 * float(_acf(x, m)[1:] @ _acf(y, m)[1:])
        total += len(x) / max(s, 1.0)
    return total


def _unexplained(res: list[np.ndarray], sigs: list[list[np.ndarray]]) -> list[np.ndarray]:
    """Per run, the residual less its least-squares fit on the signatures: the noise whose
    autocorrelation sets the band (a residual that follows a signature is not noise, and its
    smoothness must not widen the band that tests it)."""
    out = []
    for i, x in enumerate(res):
        A = np.column_stack([np.ones(len(x))] + [s[i] for s in sigs])
        out.append(x - A @ np.linalg.lstsq(A, x, rcond=None)[0])
    return out


def _peak_lag(a: list[np.ndarray], b: list[np.ndarray], max_lag: int) -> int:
    lags = np.arange(-max_lag, max_lag + 1)
    return int(lags[int(np.argmax([abs(_corr(a, b, int(k))) for k in lags]))])


def rudder_phase(
    res_r: list[np.ndarray],
    r_hat: list[np.ndarray],
    delta: list[np.ndarray],
    ts: float,
    damping: list[np.ndarray] | None = None,
) -> Phase:
    """:class:`Phase` from per-run yaw residuals (measured - simulated), simulated yaw rates and
    rudder angles, each (N+1,), sample time ``ts``. ``damping``: the damping term's signature in
    the simulated yaw rate (the model's response to it), by default r_hat |r_hat| itself."""
    max_lag = max(1, int(MAX_LAG_S / ts))
    lag = _peak_lag(res_r, delta, max_lag) - _peak_lag(r_hat, delta, max_lag)
    acc = [np.gradient(r) for r in r_hat]
    damping = damping if damping is not None else [r * np.abs(r) for r in r_hat]
    noise = _unexplained(res_r, [acc, damping])
    n = min(n_eff(noise, acc), n_eff(noise, damping))
    return Phase(lag * ts, _corr(res_r, acc), _corr(res_r, damping), BAND / np.sqrt(max(n, 1.0)))


@dataclass(frozen=True)
class Profile:
    """The fit against an assumed delay (other parameters held)."""

    delays: np.ndarray
    rss: np.ndarray

    @property
    def best_s(self) -> float:
        return float(self.delays[int(np.argmin(self.rss))])

    @property
    def drop(self) -> float:
        """Fraction of the no-delay misfit the best delay removes."""
        r0 = float(np.interp(0.0, self.delays, self.rss))
        return 1.0 - float(np.min(self.rss)) / max(r0, 1e-300)

    @property
    def interior(self) -> bool:
        """The minimum lies inside the grid (a delay of its own, not the edge of a trend)."""
        k = int(np.argmin(self.rss))
        return 0 < k < len(self.rss) - 1


def prefer_delay(phase: Phase | None, profile: Profile | None) -> bool | None:
    """True: the residual is a delay's (negatively correlated with the yaw acceleration above the
    noise band, and a profile minimum inside the grid removing at least MIN_DROP of the misfit);
    False: it follows the damping term's signature above the band and more than a delay's;
    None: neither is clearly followed (noise, or no evidence)."""
    if phase is None or profile is None:
        return None
    if phase.locked and profile.interior and profile.drop >= MIN_DROP:
        return True
    if phase.damped:
        return False
    return None


def choose(passed: list, phase: Phase | None, profile: Profile | None):
    """Of the refitted survivors of a search round (tuples whose first item is the candidate,
    best first), the first delay over the first damping term or the reverse as the evidence
    says; otherwise None (the round keeps its held-out choice)."""
    delay = [p for p in passed if p[0].effect == "actuator_delay"]
    damp = [p for p in passed if p[0].effect == "quadratic_damping"]
    if not (delay and damp):
        return None
    pick = prefer_delay(phase, profile)
    if pick is None:
        return None
    return delay[0] if pick else damp[0]


def arbitrate(model: AugmentedModel, preps: list[Prepared], P: np.ndarray, passed: list):
    """(the survivor kept or None, a note or None) for a search round's refitted survivors
    ``passed`` (candidate, slots, P1, cov1, step, delay profile), best first on the held-out
    runs: when they hold a delay and a damping term, the phase is taken against the best damping
    survivor's signature and the profile of the best delay's grid (:func:`choose`)."""
    delay = next((r for r in passed if r[0].effect == "actuator_delay"), None)
    damp = next((r for r in passed if r[0].effect == "quadratic_damping"), None)
    if delay is None or damp is None:
        return None, None
    phase = rudder_phase_at(model, preps, P, damp[1][0])
    if phase is None:
        return None, None
    pick = choose(passed, phase, delay[5])
    kept = f"{pick[0].effect} kept" if pick is not None else "undecided: the held-out choice stands"
    return pick, describe(phase, delay[5]) + ": " + kept


def describe(phase: Phase, profile: Profile | None) -> str:
    """One line for the diagnosis notes."""
    s = (
        f"delay or damping: the yaw residual against the rudder peaks {phase.lag_s:+.0f} s from the model's yaw rate, "
        f"correlates {phase.shift_corr:+.2f} with its yaw acceleration (a delay's signature) and "
        f"{phase.damping_corr:+.2f} with the damping term's response, noise band {phase.band:.2f}"
    )
    if profile is not None:
        s += f"; the fit against an assumed delay is best at {profile.best_s:.1f} s ({100 * profile.drop:.0f} % of the misfit at none removed{'' if profile.interior else ', at the edge of the grid'})"
    return s


def grid_delay(model: AugmentedModel, preps: list[Prepared], w: list, P: np.ndarray, j: int, max_samples: int = 12):
    """(starting delay of slot ``j``, :class:`Profile`): a grid search over half-sample delays in
    one batched simulation, the other parameters at P; the profile in physical delays (the
    slot's shift plus the half sample of the zero-order hold)."""
    ts = model.profile.sample_time
    grid = np.arange(-1, 2 * max_samples + 1) * 0.5 * ts
    grid = grid[grid >= -model.half_sample]
    Pb = np.repeat(P[None], len(grid), axis=0)
    Pb[:, j] = grid
    R = stack(residuals(model, preps, Pb), w)
    rss = (R**2).sum(axis=1)
    return float(grid[int(np.argmin(rss))]) or 0.25 * ts, Profile(grid + model.half_sample, rss)


def rudder_phase_at(model: AugmentedModel, preps: list[Prepared], P: np.ndarray, damping_slot: int) -> Phase | None:
    """The yaw residual's :class:`Phase` at P, the damping signature the model's response to a
    step of the slot ``damping_slot`` (None: no rudder among the inputs)."""
    names = list(model.profile.inputs)
    if "delta" not in names:
        return None
    k = names.index("delta")
    Pb = np.repeat(P[None], 2, axis=0)
    Pb[1, damping_slot] += model.steps(preps, P)[damping_slot]
    sims = model.simulate_many(preps, Pb)
    return rudder_phase(
        [p.y[:, 2] - s[0, :, 2] for p, s in zip(preps, sims)],
        [s[0, :, 2] for s in sims],
        [p.inputs[:, k] for p in preps],
        model.profile.sample_time,
        [s[1, :, 2] - s[0, :, 2] for s in sims],
    )
