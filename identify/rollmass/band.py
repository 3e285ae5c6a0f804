"""A band-limited objective for the output-error fit (stop 61, an experiment; not the default).

The fit (:mod:`identify.rollmass.output_error`, :mod:`identify.rollmass.oe_fit`) minimises the whitened, weighted
output error. With a :class:`Band` it minimises that error passed through one zero-phase linear filter ``F``: the
same ``F`` on every dataset's residual, its nuisance basis (bias, free response) and every Jacobian column, so the
fit minimises ``|w F(A e)|^2`` exactly (``A``: the channel's AR whitener) and the sandwich sees the same filtered
scores. Why: on the basin truth the wave-driven response at 0.8-1.7 Hz, near and above the roll resonance, sets the
scatter (docs/mass-accuracy.md, stop 39), and the rudder-driven response carries little there.

``F``: the forward-backward (zero-phase) response ``|H(e^{j 2 pi f T})|^2`` of the project's Butterworth design
(:func:`primitives.iir.butter`, what :func:`primitives.iir.filtfilt` applies in steady state, in closed form), applied by FFT to the
record extended by :data:`EDGE_PERIODS` periods of the band's lowest edge frequency at each end (odd extension about
the end samples, as ``filtfilt`` pads) and zero-padded against wrap-around; the extension is cut off again. All of
it is linear in the signal, so the filtered Jacobian is the filtered residual's exact Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

KINDS = ("lowpass", "bandpass", "bandstop")
# periods of the band's lowest edge frequency the record is extended by at each end (odd extension): the
# forward-backward 4th-order Butterworth's impulse response has decayed to about 1e-4 of its peak by then
EDGE_PERIODS = 4.0
ORDER = 4


@dataclass(frozen=True)
class Band:
    """A zero-phase Butterworth band: ``kind`` one of :data:`KINDS`, ``freqs`` its edge(s) in Hz."""

    kind: str
    freqs: tuple[float, ...]
    order: int = ORDER

    def label(self) -> str:
        """``kind:f`` or ``kind:lo-hi`` (the form :func:`parse_band` reads)."""
        return f"{self.kind}:{'-'.join(f'{f:g}' for f in self.freqs)}"

    def edge(self, n: int, T: float) -> int:
        """Samples of odd extension at each end of an ``n``-sample record at sample time ``T``."""
        return int(min(n - 1, np.ceil(EDGE_PERIODS / (min(self.freqs) * T))))

    def apply(self, x: np.ndarray, T: float) -> np.ndarray:
        """``x`` (n,) or (n, k) filtered along its first axis (a new array); a complex ``x`` (the free response's
        modal powers, :func:`sensitivity.dataset_jacobian`) its real and imaginary parts apart (the filter is real)."""
        if np.iscomplexobj(x):
            return self.apply(x.real, T) + 1j * self.apply(x.imag, T)
        n = x.shape[0]
        m = self.edge(n, T)
        ext = np.concatenate([2 * x[:1] - x[m:0:-1], x, 2 * x[-1:] - x[-2 : -m - 2 : -1]], axis=0)
        N = _fft_length(ext.shape[0] + m)  # the extension's length again of zeros: wrap-around stays below 1e-4
        H = _gain(self, N, T)
        X = np.fft.rfft(ext, N, axis=0)
        y = np.fft.irfft(X * (H if x.ndim == 1 else H[:, None]), N, axis=0)
        return y[m : m + n]


def _fft_length(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n."""
    best = 1 << int(np.ceil(np.log2(n)))
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p = p35
            while p < n:
                p *= 2
            best = min(best, p)
            p35 *= 3
        p5 *= 5
    return best


@lru_cache(maxsize=64)
def _gain(band: Band, N: int, T: float) -> np.ndarray:
    """``|H|^2`` of the band's Butterworth design (:func:`primitives.iir.butter`: the analog prototype through the
    pre-warped bilinear transform) on the rfft grid of ``N`` samples at sample time ``T``, in closed form: with the
    warped frequency ``W = tan(pi f T)`` and the prototype's ``L`` (``W / Wc``; band-pass ``(W^2 - W0^2) / (W B)``;
    band-stop its inverse, ``W0^2 = W_lo W_hi``, ``B = W_hi - W_lo``), ``|H|^2 = 1 / (1 + L^(2 order))`` (Oppenheim &
    Schafer 7.1.2). Why not ``|b(z) / a(z)|``: the direct-form polynomials of an 8-pole band at 1 % of the sample
    rate lose four digits (4e-4 of the gain at 0.3 Hz of a 0.2-0.5 Hz band at 50 Hz)."""
    W = np.tan(np.pi * np.minimum(np.fft.rfftfreq(N, T) * T, 0.5 - 1e-12))
    edges = np.tan(np.pi * np.asarray(band.freqs) * T)
    with np.errstate(divide="ignore"):
        if band.kind == "lowpass":
            L = W / edges[0]
        else:
            W0sq, B = edges[0] * edges[1], edges[1] - edges[0]
            L = (W * W - W0sq) / (W * B)  # W = 0: -inf, the pass band's gain 0 there
            if band.kind == "bandstop":
                L = 1.0 / L
    return 1.0 / (1.0 + L ** (2 * band.order))


def parse_band(text: str) -> Band:
    """``lowpass:F``, ``bandpass:LO-HI`` or ``bandstop:LO-HI`` (Hz) as a :class:`Band`; ValueError naming the fix."""
    kind, _, spec = text.partition(":")
    try:
        freqs = tuple(float(f) for f in spec.split("-"))
    except ValueError:
        freqs = ()
    want = 1 if kind == "lowpass" else 2
    if kind not in KINDS or len(freqs) != want or not all(f > 0 for f in freqs) or (want == 2 and not freqs[0] < freqs[1]):
        raise ValueError(f"band {text!r}: give lowpass:F, bandpass:LO-HI or bandstop:LO-HI in Hz (0 < LO < HI)")
    return Band(kind, freqs)
