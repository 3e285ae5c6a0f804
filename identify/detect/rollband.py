"""The roll band that the decision leaves out of the evidence.

A yaw row fitted on one nominal recording carries the misfit of its roll-yaw coupling at that
recording's roll level: the roll-coupling terms of (2.17) are linear in phi and p, while a real
ship's roll-yaw coupling is not (and the sensors' lags matter most at the roll frequency). On a
recording that rolls more or less than the nominal one the misfit shows in the roll band, where
the yaw response is inertia-dominated, as an apparent change of yaw inertia: on the podded truth
family's strong-roll variant (tests/physics/podded_truth.py) a +10 % I_z change (+5.4 % of I_r) on
the two runs rolling 2.1 and 2.3 times the nominal run's roll rms read +0.1 and -0.5 % of I_r over
the whole record, and +6.4 and +4.1 % with the roll band left out.

The decision therefore reads the residual and the change signatures through a band-stop filter
around the recording's roll frequency, after the prior's whitening filter: the same linear
time-invariant filter on both, so a change still moves the filtered residual along the filtered
signature, and the no-change records that set the thresholds go through it too. The filter is
causal (Butterworth, order 2 per edge), so the CUSUM stays an online statistic. What is lost is the
inertia information the roll band carries; what is gained is that the rest does not depend on how
much the recording rolls.

As a detector it trades delay and power for false alarms, so it is opt-in
(:func:`identify.detect.api.screen` ``leave_out_roll_band=True``; ``detect`` and the CLI leave it
off): re-deciding the podded truth family's stored screenings (2 ships x 5 + 5 runs on each of 5
variants; README, stop 39) with the band out took the pooled false alarms from 20 to 10 %, but the
misses from 38 to 48 % and the mean delay from 231 to 295 s (each rate's 95 % interval about +-12
points). BAND was chosen on those same runs (in-sample).

The peak is that of the roll angle's spectrum, which is the roll resonance only when the ship rolls
more at it than it heels in its turns: on the family's steering-lag runs (18 of 20) and on the
naval vessel's harbour manoeuvre the peak is the turns' heel at 0.05-0.07 Hz, and the band left out
there is the manoeuvre's, not the roll's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.detect.yawmodel import YawPrior, whiten
from primitives.iir import butter, lfilter  # scipy.signal's, without its 2 s import
from primitives.spectrum import welch

#: the band left out, relative to the roll's spectral peak: about half an octave around it (chosen on
#: the podded truth family's runs, in-sample: their roll peaks lie at 0.11-0.13 Hz)
BAND = (1 / 1.35, 1.6)
#: where a roll peak is looked for (Hz): ships' natural roll periods of 3-25 s
SEARCH_HZ = (0.04, 0.35)


@dataclass(frozen=True)
class RollBand:
    """The band-stop filter of one recording's roll band, at the 1 s block rate of the decision."""

    lo_hz: float
    hi_hz: float
    block_s: float

    def coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        return butter(2, [self.lo_hz, self.hi_hz], btype="bandstop", fs=1.0 / self.block_s)

    def apply(self, x: np.ndarray) -> np.ndarray:
        """``x`` (blocks along axis 0) through the band-stop filter, from rest."""
        b, a = self.coefficients()
        return lfilter(b, a, np.asarray(x, float), axis=0)


def roll_band(phi: np.ndarray, dt: float, block: int) -> RollBand | None:
    """The roll band of a recording: BAND around the spectral peak of its roll angle ``phi`` (Welch,
    about 100 s segments) within SEARCH_HZ; None when the band does not fit below the block rate's
    Nyquist frequency or the recording is too short for a spectrum."""
    phi = np.asarray(phi, float)
    nper = min(len(phi), int(round(102.4 / dt)))
    if nper < int(round(20 / dt)):
        return None
    f, p = welch(phi - np.mean(phi), fs=1.0 / dt, nperseg=nper)
    inside = (f >= SEARCH_HZ[0]) & (f <= SEARCH_HZ[1])
    if not inside.any() or not np.any(p[inside] > 0):
        return None
    peak = float(f[inside][np.argmax(p[inside])])
    block_s = block * dt
    lo, hi = BAND[0] * peak, BAND[1] * peak
    if hi >= 0.45 / block_s:
        return None
    return RollBand(lo, hi, block_s)


def decision_whiten(x: np.ndarray, prior: YawPrior, band: RollBand | None) -> np.ndarray:
    """Block means ``x`` (axis 0) as the decision reads them: the prior's AR innovation filter, then
    the roll band's band-stop filter when there is one (both linear and time-invariant: the order
    does not matter but for the first blocks)."""
    w = whiten(x, prior.ar)
    return w if band is None else band.apply(w)
