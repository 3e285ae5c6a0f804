"""The decision stage of ``detect``: from a recording's screening (residual, signatures, LR-CUSUM
statistics and thresholds, no-change records; :func:`identify.detect.api.screen`) to the verdict:
whether the ship changed, when (the alarm and the change point with its interval), which property,
and by how much (chapter 5 of "Estimating a ship's dynamics during operation", improved).

Kept apart from the screening so that a study can re-decide stored screenings (the screening
holds all the simulation)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identify.detect.rollband import RollBand, decision_whiten
from identify.detect.yawmodel import CANDIDATES, YawPrior, block_mean

#: the hull's yaw inertias are the ship's data (``detect --profile``, ``--i-z``, ``--n-rdot``;
#: :func:`identify.detect.api.hull_inertia`), never a default of one ship: a relative change of the lumped
#: yaw inertia I_r = I_z - N_rdot that the yaw row identifies is (I_z - N_rdot) / I_z times that of the
#: rigid body's I_z. The hull's values, not the prior's fitted I_r: that is in the recorded moment's units
#: (a load cell that misses the hull's share of the pod force scales every fitted parameter), while the
#: relative change is not. Unknown (None): the change is reported of I_r alone.
CHECKS = 60  # most alarm candidates (blocks over the threshold) whose estimate is checked
#: least data after the change point (s) that an alarm's estimate needs: right after an estimated change
#: point the estimate is a few seconds of transient misfit (on the podded truth family's strong-roll
#: variant, deciding at the crossing raised false alarms from 40 to 55 % of 20 runs; 120 s kept 40 %
#: and shortened the mean delay by 21 s against the former 60 s look-ahead after every crossing)
MIN_WINDOW_S = 120.0


@dataclass
class Screening:
    """What the decision reads of one recording: the residual ``eps = r - r_hat`` (n,), the
    signatures ``S`` (n, k), the LR-CUSUM statistic per block and candidate ``st`` (nb, k) with
    its thresholds ``h`` (k,), the block means of the no-change records (nb, runs), the dead-zone
    CUSUM (5.1) with its threshold and first alarm sample (-1: none), the time from the
    recording's start (n,), the input checks' residual rms, how many no-change simulations
    diverged and were left out of the calibration, and the roll band the LR-CUSUM and the decision
    leave out (None: none)."""

    source: str
    eps: np.ndarray
    S: np.ndarray
    st: np.ndarray
    h: np.ndarray
    null_blocks: np.ndarray
    dead_zone: np.ndarray
    dead_zone_h: float
    dead_zone_alarm: int
    t: np.ndarray
    residual_rms: float
    null_diverged: int = 0
    roll_band: RollBand | None = None


@dataclass
class Detection:
    """One recording's verdict, the evidence, and the statistics for the plot."""

    source: str
    changed: bool
    alarm_s: float | None
    property: str | None
    evidence: dict
    dead_zone_alarm_s: float | None
    threshold: np.ndarray  # per candidate (CANDIDATES)
    t_blocks: np.ndarray = field(repr=False)
    statistic: np.ndarray = field(repr=False)  # (blocks, candidates)
    dead_zone: np.ndarray = field(repr=False)
    dead_zone_h: float = 0.0
    t: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    #: the smallest change this recording could show (:func:`identify.detect.power.detectable`); None: not computed
    detectable: dict | None = None

    def summary(self) -> dict:
        return {
            "recording": self.source,
            "changed": self.changed,
            "alarm_s": self.alarm_s,
            "property": self.property,
            "onset_s": self.evidence.get("onset_s") if self.changed else None,
            "onset_interval_s": self.evidence.get("onset_interval_s") if self.changed else None,
            "threshold": dict(zip(CANDIDATES, map(float, self.threshold))),
            "evidence": self.evidence,
            "dead_zone_cusum_alarm_s": self.dead_zone_alarm_s,
            "detectable": self.detectable,
        }


def physical_change(name: str, rel: float, i_r: float, n_rdot: float) -> float | None:
    """The relative change of the physical property: I_z = I_r + N_rdot for yaw inertia (a change
    dI = rel I_r of the lumped inertia ``i_r`` is dI / I_z of the rigid body's), the same for the
    others; None when ``i_r`` is not above -N_rdot (I_z would not be positive)."""
    if name != "yaw_inertia":
        return rel
    i_z = i_r + n_rdot
    return rel * i_r / i_z if i_z > 0 else None


#: fitted I_r over the hull's I_z - N_rdot beyond which the prior is not that ship's yaw row: measured
#: 0.66-0.89 on the podded truth family's healthy priors (pod-interaction, nominal-mmg, strong-roll,
#: coloured-noise, ships 100 and 101; below 1 as the load cells miss the hull's share of the pod
#: force), 18 and 31 on its steering-lag priors (a logged set-point moment while the gear lags it; with
#: a warning only, one ship alarmed on 5 of 5 no-change runs and the other missed 5 of 5 changed runs:
#: ``detect`` refuses such a prior, :func:`implausible_inertia`). Any bound from about 1.5 to 15
#: separates these; 3 leaves room for hull values (I_z from a radius of gyration, N_rdot from empirical
#: formulas) known only to tens of percent
INERTIA_RATIO = 3.0


def implausible_inertia(prior: YawPrior, i_z: float | None, n_rdot: float | None) -> str | None:
    """Why ``detect`` refuses the prior when its fitted I_r is more than INERTIA_RATIO times off the
    hull's I_z - N_rdot, else None (also when the hull's values are not known).

    Such a prior is not this ship's yaw row, and no calibration of its alarms holds: on the podded
    truth family's steering-lag ships (the drive logs the moment of its azimuth set-point while the
    gear lags it by a 2 s lag and a 3.5 deg/s rate limit) I_r and the damping terms grow 18-31 times
    together, i.e. the fit all but ignores the recorded moment and turns the ship with the measured
    sway instead; the same ships' priors fitted on the acting moment have I_r 0.75-0.79 times the
    hull's. A first-order lag (0.5-8 s) on the recorded moment, or the set-point angle passed through
    the true gear, did not bring it back (measured by scripts outside the repository; README, stop 40)."""
    if i_z is None or n_rdot is None:
        return None
    ratio = prior.values["I_r"] / (i_z - n_rdot)
    if 1 / INERTIA_RATIO <= ratio <= INERTIA_RATIO:
        return None
    return (
        f"the prior's yaw inertia I_r {prior.values['I_r']:.3g} kg m^2 is {ratio:.2g} times the hull's I_z - N_rdot "
        f"({i_z:.3g} + {-n_rdot:.3g}): the recorded moment does not turn this ship as a yaw row does, and no "
        "alarm of this prior is calibrated; if the drive logs the moment (or pod angles) of its set-points while "
        "the steering gear lags them, record the acting ones and refit with detect-prior; if the moment is in "
        "other units, convert it to N m; if the hull's values are not this ship's, correct --profile or --i-z "
        "and --n-rdot; to use this prior anyway, at your own risk, leave out --profile, --i-z and --n-rdot (a "
        "yaw-inertia change is then reported of I_r only)"
    )


def _decide(eps, S, prior, st, h, null_blocks, min_change, i_ref, n_rdot, band=None) -> tuple[int, dict]:
    """First block over the threshold whose change is also worth an alarm: the leading candidate's
    estimate from the change point on (:meth:`Whitened.onset`) up to the end of that block, or MIN_WINDOW_S
    after the change point if later, clipped at the recording's end (so near the end an alarm can stand
    on less than MIN_WINDOW_S), at least ``min_change`` (of I_z for yaw inertia, from the
    lumped ``i_ref`` = I_z - N_rdot; of I_r when that is None) and twice its no-change standard deviation. Returns (alarm
    sample: the last one that estimate saw, or -1; evidence).

    The evidence (each candidate's estimate and the named property) is then taken from the change
    point to the end of the recording: the alarm needs only the data up to it, the naming all the
    data that bears on it (inertia and pod gain are nearly collinear at turn onsets and need more
    data to be told apart than to be detected). ``at_alarm`` keeps what the alarm decision saw.
    Residual, signatures and no-change records are whitened once (:class:`Whitened`): every
    candidate block reads windows of the same whitened arrays."""
    wd = Whitened.of(eps, S, prior, null_blocks, band)
    n = len(eps)
    over = np.flatnonzero((st / h).max(axis=1) > 1.0)
    step = max(1, len(over) // CHECKS)
    for b in over[::step]:
        upto = (int(b) + 1) * prior.block
        k = int(np.argmax(st[b] / h))
        tau, lo, hi = wd.onset(upto, k)
        end = min(max(upto, tau + int(round(MIN_WINDOW_S / prior.dt))), n)
        seen = wd.attribute(end, start=tau)
        lead = max(seen["candidates"], key=lambda c: seen["candidates"][c]["llr"])
        c = seen["candidates"][lead]
        size = c["relative_change"] if i_ref is None else physical_change(lead, c["relative_change"], i_ref, n_rdot)
        if abs(size) >= min_change and abs(c["relative_change"]) >= 2 * c["std"]:
            ev = wd.attribute(n, start=tau)
            return end - 1, ev | {"onset": (tau, lo, hi), "at_alarm": {"candidate": lead} | c}
    tau, lo, hi = wd.onset(n, int(np.argmax((st / h).max(axis=0))))
    return -1, wd.attribute(n, start=0) | {
        "onset": (tau, lo, hi),
        "crossed_but_below_min_change": bool(len(over)),
    }


def verdict(
    sc: Screening, prior: YawPrior, min_change: float = 0.05, n_rdot: float | None = None, i_z: float | None = None
) -> Detection:
    """The verdict on one screened recording (:func:`_decide`), with the evidence: the change point
    with its 95 % interval, each candidate's estimate and, for yaw inertia, the change of the rigid
    body's ``i_z`` beside that of the lumped I_r = I_z - ``n_rdot`` (when both are given: the hull's
    values; otherwise the I_z change is None and ``min_change`` applies to I_r)."""
    known = i_z is not None and n_rdot is not None
    if known and not (i_z > 0 and n_rdot < 0):
        raise ValueError(f"i_z {i_z:g} must be positive and n_rdot {n_rdot:g} negative (kg m^2)")
    i_ref = i_z - n_rdot if known else None
    band = sc.roll_band  # screenings stored before the roll band have none
    i, ev = _decide(sc.eps, sc.S, prior, sc.st, sc.h, sc.null_blocks, min_change, i_ref, n_rdot, band)
    t = sc.t
    tau, lo, hi = ev.pop("onset")
    ev["onset_s"] = float(t[min(tau, len(t) - 1)])
    ev["onset_interval_s"] = [float(t[min(lo, len(t) - 1)]), float(t[min(hi, len(t) - 1)])]
    if i >= 0:  # the alarm needs the data up to it, the name all the data after the change point
        ev["named_on_s"] = [ev["onset_s"], float(t[-1])]
    inertia = ev["candidates"]["yaw_inertia"]
    iz = physical_change("yaw_inertia", inertia["relative_change"], i_ref, n_rdot) if known else None
    scale = iz / inertia["relative_change"] if iz is not None and inertia["relative_change"] else None
    inertia |= {
        "I_z_relative_change": iz,
        "I_z_std": None if scale is None else abs(scale) * inertia["std"],
        "N_rdot": n_rdot,
        "I_z": i_z,
        "I_r": prior.values["I_r"],
    }
    ev["statistic_max"] = {c: float(sc.st[:, k].max()) for k, c in enumerate(CANDIDATES)}
    ev["residual_rms"] = sc.residual_rms
    ev["roll_band_left_out_hz"] = None if band is None else [band.lo_hz, band.hi_hz]
    ev["prior_sigma"] = prior.sigma
    ev["null_diverged"] = {"left_out": sc.null_diverged, "of": sc.null_diverged + sc.null_blocks.shape[1]}
    tb = t[prior.block - 1 :: prior.block][: len(sc.st)]
    j = sc.dead_zone_alarm
    return Detection(
        sc.source,
        i >= 0,
        float(t[i]) if i >= 0 else None,
        ev["property"] if i >= 0 else None,
        ev,
        float(t[j]) if j >= 0 else None,
        sc.h,
        tb,
        sc.st,
        sc.dead_zone,
        sc.dead_zone_h,
        t,
    )


#: log-likelihood-ratio lead (about a factor 10 in likelihood) the named property needs over every other
SEPARATION = 2.3


def attribute(
    eps: np.ndarray, S: np.ndarray, prior: YawPrior, upto: int, null_blocks: np.ndarray | None = None, start: int = 0
) -> dict:
    """Which candidate explains the residual from sample ``start`` up to ``upto``: per candidate, the
    GLR estimate ``theta_j = sum S_j eps / sum S_j^2`` (whitened) and its log-likelihood ratio
    ``(sum S_j eps)^2 / (2 s^2 sum S_j^2)``. A property is named only when its log-likelihood ratio
    leads every other's by ``SEPARATION``; otherwise ``property`` is ``"undecided"`` and
    ``undecided_between`` lists the candidates within it (at a turn onset more inertia and less
    actuator gain look alike). ``std`` is the estimate's standard deviation under no change: from
    the no-change records' block means ``null_blocks`` (blocks, runs) when given (noise and the
    prior's own parameter error), else from the noise alone."""
    return Whitened.of(eps, S, prior, null_blocks).attribute(upto, start)


@dataclass
class Whitened:
    """One recording's whitened 1 s block means (the prior's AR innovation filter along time): the
    signatures ``Sw`` (nb, k), the residual ``ew`` (nb,) and the no-change records ``nw`` (nb, runs)
    or None. The filter runs along time from the recording's start, so a window of these is the
    same as whitening the whole block array and then cutting the window, as :meth:`Whitened.onset` and
    :func:`attribute` do; made once per recording, the decision's many windows only slice."""

    prior: YawPrior
    Sw: np.ndarray
    ew: np.ndarray
    nw: np.ndarray | None

    @classmethod
    def of(
        cls, eps: np.ndarray, S: np.ndarray, prior: YawPrior, null_blocks: np.ndarray | None = None, band: RollBand | None = None
    ) -> Whitened:
        """Whitened with the prior's AR filter, and outside the roll ``band`` when given."""
        nw = None if null_blocks is None else decision_whiten(null_blocks, prior, band)
        Sw = decision_whiten(block_mean(S, prior.block), prior, band)
        return cls(prior, Sw, decision_whiten(block_mean(eps, prior.block), prior, band), nw)

    def onset(self, upto: int, k: int) -> tuple[int, int, int]:
        """Change point of a step change along signature ``k`` seen up to sample ``upto``: the block
        ``tau`` that maximises the GLR ``(sum_{t>=tau} S_k e)^2 / (2 s^2 sum_{t>=tau} S_k^2)`` (Basseville and
        Nikiforov 1993, section 2.2.3), and the blocks whose GLR is within 1.92 of it (a 95 % profile-
        likelihood interval). Returns (first sample of tau, of the interval's start, of its end)."""
        p = self.prior
        nb = max(upto // p.block, 2)
        Sw, ew = self.Sw[:nb, k], self.ew[:nb]
        z = np.cumsum((Sw * ew)[::-1])[::-1]
        d = np.maximum(np.cumsum((Sw * Sw)[::-1])[::-1], 1e-300)
        llr = z * z / (2 * p.sigma_w**2 * d)
        best = int(np.argmax(llr))
        inside = np.flatnonzero(llr >= llr[best] - 1.92)
        return best * p.block, int(inside[0]) * p.block, int(inside[-1] + 1) * p.block

    def attribute(self, upto: int, start: int = 0) -> dict:
        """:func:`attribute` on these arrays."""
        p = self.prior
        w = slice(start // p.block, max(upto // p.block, start // p.block + 2))
        Sw = self.Sw[w]
        s2 = p.sigma_w**2
        den = np.maximum(np.sum(Sw**2, axis=0), 1e-300)
        num = Sw.T @ self.ew[w]
        std = np.std(Sw.T @ self.nw[w], axis=1) / den if self.nw is not None else np.sqrt(s2 / den)
        std = np.sqrt(std**2 + p.structure**2)  # the structure's apparent change on a new manoeuvre
        llr = num**2 / (2 * s2 * den)
        order = np.argsort(-llr)
        close = [CANDIDATES[int(i)] for i in order if llr[order[0]] - llr[i] < SEPARATION]
        return {
            "property": close[0] if len(close) == 1 else "undecided",
            "undecided_between": close if len(close) > 1 else [],
            "candidates": {
                c: {"relative_change": float(num[i] / den[i]), "llr": float(llr[i]), "std": float(std[i])}
                for i, c in enumerate(CANDIDATES)
            },
            "llr_margin": float(llr[order[0]] - llr[order[1]]),
        }
