"""The recording's own misfit in its no-change records, tried and not kept (issue 25, stop 49; docs/detect-accuracy.md):
settings of ``benchmarks/bench_detect_calibration.py --own-misfit`` that re-decide the truth bench's stored
screenings with the records' misfit term made from the run being tested.

The no-change records (:func:`identify.detect.nullsim.null_records`) carry the prior's misfit as
AR-coloured 1 s block offsets at the level the NOMINAL recording showed (``prior.model_error``). The
hypothesis: the structure the estimator leaves out misfits by how much each run excites it (roll, speed,
manoeuvre), so a run that excites it more scatters more than its records. Two ways of giving the records
the run's own misfit, each after the best single change-point fit along one candidate is taken out (a
changed run's own change must not raise its threshold):

* level (:func:`own_misfit`): the run's misfit level read with the estimator of
  :func:`identify.detect.priorfit.model_error` (robust sigma of the whitened 1 s block means; the
  records' own value of it the reference; the same two-standard-error gate), what the run has beyond
  its records added as a further independent AR-coloured term: the records' innovation sd becomes
  ``max(model_error, run's own)``. The offsets are constant over a 1 s block, so adding their block
  means to a stored screening's records gives the block means screening with them gives (to rounding).
* bootstrap (:func:`own_bootstrap`): the records' AR term (regenerated: :func:`stored_offsets`)
  replaced by a circular block bootstrap of the run's own post-fit block residual; ``bootpL`` (stop 49,
  continued): only its part orthogonal to the signatures and the fitted step (:func:`projected`). Neither
  wins the hold-out's power back (docs/detect-accuracy.md; ``benchmarks/detect_ownboot_diag.py``).

Stop 53 (calibrate without raising a changed run's thresholds; none qualifies, docs/detect-accuracy.md):
``lowbL`` (:func:`low_band_bootstrap`: only the part below the signatures' band from the run), ``scale``,
``scaleb``, ``scalei`` (:func:`scaled_term`: one bounded, shrunk scale of the AR term per run, read from
the run's unchanged part, above or inside the signatures' band), ``mixW`` (:func:`mixed_bootstrap`) and ``bootnL``
(``bootpL`` less the white noise its records carry already, :func:`own_bootstrap`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identify.detect.nullsim import misfit_offsets, normals
from identify.detect.verdict import Screening
from identify.detect.yawmodel import YawPrior, block_mean, whiten

#: the change-point fit leaves at least this many 1 s blocks after the change (a fit to the last few
#: blocks would take out the largest residuals rather than a change)
MIN_AFTER = 30


def change_fits(ew: np.ndarray, Sw: np.ndarray, min_after: int = MIN_AFTER) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each column's best single change-point fit along one whitened signature: for block residuals
    ``ew`` (nb, m) and signatures ``Sw`` (nb, k), over change blocks ``tau`` (at most ``nb - min_after``)
    and candidates ``k`` the fit ``theta = sum_{t>=tau} S_k e / sum_{t>=tau} S_k^2`` (the GLR estimate
    of a step change of ``theta`` from ``tau``, Basseville and Nikiforov 1993, section 2.2) that lowers
    the residual sum of squares most, ``(sum S_k e)^2 / sum S_k^2``: (tau, k, theta), each (m,)."""
    nb = len(ew)
    last = max(1, nb - min_after + 1)
    # suffix sums over t >= tau, (tau, m, k) and (tau, k): the fit from every change block at once
    num = np.cumsum((Sw[:, None, :] * ew[:, :, None])[::-1], axis=0)[::-1][:last]
    den = np.maximum(np.cumsum((Sw**2)[::-1], axis=0)[::-1][:last], 1e-300)
    m, k = ew.shape[1], Sw.shape[1]
    best = (num**2 / den[:, None, :]).transpose(1, 0, 2).reshape(m, last * k).argmax(axis=1)
    tau, cand = np.divmod(best, k)
    return tau, cand, num[tau, np.arange(m), cand] / den[tau, cand]


def change_removed(ew: np.ndarray, Sw: np.ndarray, min_after: int = MIN_AFTER) -> np.ndarray:
    """Block residuals ``ew`` (nb, m) less each column's best change-point fit (:func:`change_fits`)."""
    tau, cand, theta = change_fits(ew, Sw, min_after)
    step = (np.arange(len(ew))[:, None] >= tau[None, :]) * Sw[:, cand]  # (nb, m): candidate cand from tau
    return ew - theta[None, :] * step


def robust_sigmas(x: np.ndarray) -> np.ndarray:
    """1.4826 median absolute deviation of each column of ``x`` (nb, m) (``yawmodel.robust_sigma`` per column)."""
    return 1.4826 * np.median(np.abs(x - np.median(x, axis=0)), axis=0)


def levels(prior: YawPrior, eps: np.ndarray, S: np.ndarray, null_blocks: np.ndarray, level=robust_sigmas) -> tuple[float, float]:
    """``s_run``, the robust sigma (or ``level``) of the recording's whitened 1 s block residual (``eps``
    (n,)), and ``s_null``, the root mean square of the same over its records' block means ``null_blocks``
    (nb, runs), each after its best change-point fit (:func:`change_removed`, signatures ``S`` (n, k))."""
    Sw = whiten(block_mean(S, prior.block), prior.ar)
    nb = min(len(Sw), len(null_blocks))
    e = np.column_stack([block_mean(eps, prior.block)[:nb], null_blocks[:nb]])
    s = level(change_removed(whiten(e, prior.ar), Sw[:nb]))
    return float(s[0]), float(np.sqrt(np.mean(s[1:] ** 2)))


def own_misfit(
    prior: YawPrior, eps: np.ndarray, S: np.ndarray, null_blocks: np.ndarray, gate: float = 2.0, level=robust_sigmas
) -> float:
    """Innovation sd of the recording's misfit beyond its no-change records: ``sqrt(s_run^2 - s_null^2)``
    (:func:`levels`); 0 when ``s_run`` is within ``gate`` standard errors of ``s_null`` (as
    :func:`identify.detect.priorfit.model_error`: the robust sigma's efficiency 0.37). The records
    already carry ``prior.model_error``, so adding this much more makes their level the larger of the
    nominal's and the run's. ``level``: the scale estimate per column (:data:`OWN`)."""
    s_run, s_null = levels(prior, eps, S, null_blocks, level)
    nb = min(len(eps) // prior.block, len(null_blocks))
    if not np.isfinite(s_run) or s_run <= s_null * (1 + gate / np.sqrt(0.74 * nb)):
        return 0.0
    return float(np.sqrt(s_run**2 - s_null**2))


def extra_offsets(prior: YawPrior, extra: float, n: int, runs: int, seed: int = 0) -> np.ndarray:
    """(n, runs) AR-coloured 1 s block offsets of innovation sd ``extra`` (:func:`identify.detect.nullsim.misfit_offsets`),
    independent of the records' own (innovations seeded ``[seed, 11]``); zeros for ``extra`` 0."""
    return misfit_offsets(replace(prior, model_error=max(extra, 0.0)), n, runs, np.random.default_rng([seed, 11]))


#: --own-misfit settings: the run's own misfit level (:func:`own_misfit`) added to a stored
#: screening's records at block level (its offsets are constant over a block: the same block means as
#: screening with it, to rounding), as (gate in standard errors, scale estimate); "stored": as screened
OWN = {
    "robust": (2.0, robust_sigmas),
    "robust-gate0": (0.0, robust_sigmas),
    "rms": (2.0, lambda x: np.sqrt(np.mean(x**2, axis=0))),
}


_INNOVATIONS: dict = {}


def stored_offsets(prior: YawPrior, n: int, runs: int) -> np.ndarray:
    """Block means (nb, runs) of the misfit offsets ``nullsim.null_records`` added to a stored screening's
    records (seed 0: the generator's draws regenerated, the prior's signals one yaw-rate noise each)."""
    nb = n // prior.block
    if prior.model_error <= 0:
        return np.zeros((nb, runs))
    k = (n, runs, len(prior.noise) - 1)
    if k not in _INNOVATIONS:
        _INNOVATIONS.clear()
        _INNOVATIONS[k] = normals(0, runs, n, len(prior.noise) - 1, nb)[-1]
    return block_mean(misfit_offsets(prior, n, runs, None, _INNOVATIONS[k]), prior.block)


def projected(res: np.ndarray, Sb: np.ndarray, step: np.ndarray | None = None) -> np.ndarray:
    """Block residual ``res`` (nb,) less its least-squares fit on a constant, the signatures ``Sb`` (nb, k)
    and, if given, the change-point fit's step column ``step`` (nb,): ``(I - X (X'X)^+ X') res``, the
    part orthogonal to every column of ``X`` (stop 49, continued: a change's own signal, whole-record
    or from ``tau``, cannot then enter the records and raise its own threshold)."""
    cols = [np.ones(len(res)), *np.asarray(Sb, float).T] + ([] if step is None else [step])
    X = np.column_stack(cols)
    coef = np.linalg.lstsq(X, res, rcond=None)[0]
    return res - X @ coef


def post_fit_residual(sc: Screening, prior: YawPrior, project: bool = False) -> np.ndarray:
    """The run's block residual (nb,) after its best change-point fit (:func:`change_fits` on the whitened
    series), or with ``project`` its part orthogonal to the signatures and that fit's step (:func:`projected`)."""
    nb = sc.null_blocks.shape[0]
    Sb, eb = block_mean(sc.S, prior.block)[:nb], block_mean(sc.eps, prior.block)[:nb]
    tau, k, theta = (x[0] for x in change_fits(whiten(eb, prior.ar)[:, None], whiten(Sb, prior.ar)))
    step = np.where(np.arange(nb) >= tau, Sb[:, k], 0.0)
    return projected(eb, Sb, step) if project else eb - theta * step


def own_bootstrap(
    sc: Screening, prior: YawPrior, length: int, seed: int = 0, project: bool = False, denoise: bool = False
) -> Screening:
    """``sc`` with its records' AR misfit term (:func:`stored_offsets`) replaced by a circular block
    bootstrap (blocks of ``length`` 1 s blocks) of the run's own block residual, centred, after its best
    change-point fit (:func:`change_fits`): the run's own misfit, in its own spectrum. ``project``: only
    the part orthogonal to the signatures and the fitted step is resampled (:func:`projected`). ``denoise``
    (stop 53): scaled in sd by ``sqrt(1 - noise / var)``, the records' own white noise (the stored records less
    the term) not counted twice."""
    nb, runs = sc.null_blocks.shape
    base = sc.null_blocks - stored_offsets(prior, len(sc.eps), runs)[:nb]
    res = post_fit_residual(sc, prior, project)
    v = np.var(res)
    keep = np.sqrt(max(1 - np.mean(np.var(base, axis=0)) / v, 0.0)) if denoise and v > 0 else 1.0
    return replace(sc, null_blocks=base + keep * circular_blocks(res - res.mean(), runs, length, seed))


#: stop 53: the fraction of the signatures' block-mean power below the band edge of :func:`signature_edge`
EDGE_POWER = 0.05
#: stop 53: the scale of the records' AR term (``scale``): shrunk toward 1 with this many 1 s blocks' weight,
#: and bounded, so a run's unchanged part can move its thresholds only so far
SCALE_PRIOR_BLOCKS = 100
SCALE_BOUNDS = (0.67, 1.5)
#: stop 53: the fitted change leaves at least this many 1 s blocks before it for ``scale`` to read only them
MIN_BEFORE = 60


def band_split(x: np.ndarray, edge: float) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (nb, ...) split along axis 0 at ``edge`` cycles a block (Hz for 1 s blocks) by a zero-phase
    brick-wall mask of its discrete Fourier transform: (below, at and above), summing to ``x``."""
    f = np.fft.rfftfreq(len(x))
    X = np.fft.rfft(x, axis=0)
    low = np.fft.irfft(np.where((f < edge).reshape(-1, *[1] * (x.ndim - 1)), X, 0), n=len(x), axis=0)
    return low, x - low


def signature_edge(Sb: np.ndarray, power: float = EDGE_POWER) -> float:
    """The lower edge of the signatures' band: the frequency (cycles a block) below which a fraction
    ``power`` of the block-mean signatures' power lies (each column centred and scaled to unit power,
    the periodograms summed; the zero frequency left out)."""
    S = np.asarray(Sb, float) - np.mean(Sb, axis=0)
    P = np.abs(np.fft.rfft(S / np.maximum(S.std(axis=0), 1e-300), axis=0)) ** 2
    c = np.cumsum(P[1:].sum(axis=1))
    f = np.fft.rfftfreq(len(S))[1:]
    return float(f[np.searchsorted(c, power * c[-1])])


def circular_blocks(x: np.ndarray, runs: int, length: int, seed: int = 0) -> np.ndarray:
    """(nb, runs) circular block bootstrap of ``x`` (nb,): blocks of ``length`` (Politis and Romano 1992)."""
    nb = len(x)
    starts = np.random.default_rng([seed, 13]).integers(0, nb, size=(runs, -(-nb // length)))
    return x[((starts[:, :, None] + np.arange(length)).reshape(runs, -1)[:, :nb] % nb)].T


def low_band_bootstrap(sc: Screening, prior: YawPrior, length: int, seed: int = 0) -> Screening:
    """Stop 53 (a): ``sc`` with the records' AR term below the signatures' band (:func:`signature_edge`)
    replaced by a block bootstrap of the run's projected residual's part there (:func:`projected`), less
    the share of it the records' own white noise already gives (its variance times ``2 edge``); the
    term's part in and above the band stays the nominal's. The change's own signal is in the band (and
    projected out): only the run's slow misfit can move its thresholds."""
    nb, runs = sc.null_blocks.shape
    so = stored_offsets(prior, len(sc.eps), runs)[:nb]
    base = sc.null_blocks - so
    edge = signature_edge(block_mean(sc.S, prior.block)[:nb])
    low = band_split(post_fit_residual(sc, prior, project=True), edge)[0]
    v = np.var(low)
    keep = np.sqrt(max(v - 2 * edge * np.mean(np.var(base, axis=0)), 0.0) / v) if v > 0 else 0.0
    return replace(sc, null_blocks=base + band_split(so, edge)[1] + keep * circular_blocks(low - low.mean(), runs, length, seed))


def term_scale(sc: Screening, prior: YawPrior, band: str = "all") -> float:
    """Stop 53 (b): the records' AR term's variance scale from the run's unchanged part: the projected
    residual (:func:`projected`) before the fitted change block (the whole when that leaves fewer than
    :data:`MIN_BEFORE` blocks), less the records' own white noise, over the term's variance; shrunk
    toward 1 with the weight of :data:`SCALE_PRIOR_BLOCKS` blocks and bounded (:data:`SCALE_BOUNDS`).
    ``band`` "above": both read only above the signatures' band (above the frequency below which
    ``1 - EDGE_POWER`` of their power lies, :func:`signature_edge`), where a change has no signal, the
    noise's share there ``1 - 2 edge`` of its variance; "in": only in it (from the edge of ``EDGE_POWER``
    to that one), where the CUSUM looks; the whole residual then, not the part before the fit."""
    nb, runs = sc.null_blocks.shape
    so = stored_offsets(prior, len(sc.eps), runs)[:nb]
    if not np.any(so):
        return 1.0
    Sb, eb = block_mean(sc.S, prior.block)[:nb], block_mean(sc.eps, prior.block)[:nb]
    tau, k, _ = (x[0] for x in change_fits(whiten(eb, prior.ar)[:, None], whiten(Sb, prior.ar)))
    res = projected(eb, Sb, np.where(np.arange(nb) >= tau, Sb[:, k], 0.0))
    noise = np.mean(np.var(sc.null_blocks - so, axis=0))
    if band != "all":
        lo, hi = signature_edge(Sb, EDGE_POWER), signature_edge(Sb, 1 - EDGE_POWER)
        keep = (lambda x: band_split(x, hi)[1]) if band == "above" else (lambda x: band_split(band_split(x, hi)[0], lo)[1])
        share = 1 - 2 * hi if band == "above" else 2 * (hi - lo)
        part, so, noise = keep(res), keep(so), noise * share
    else:
        part = res[:tau] if tau >= MIN_BEFORE else res
    raw = max(np.var(part) - noise, 0.0) / np.var(so)
    w = len(part) / (len(part) + SCALE_PRIOR_BLOCKS)
    return float(np.clip(1 + w * (raw - 1), *SCALE_BOUNDS))


def scaled_term(sc: Screening, prior: YawPrior, band: str = "all") -> tuple[Screening, float]:
    """``sc`` with its records' AR term scaled in sd by ``sqrt(term_scale)`` (:func:`term_scale`), and that scale."""
    c = term_scale(sc, prior, band)
    so = stored_offsets(prior, len(sc.eps), sc.null_blocks.shape[1])[: len(sc.null_blocks)]
    return replace(sc, null_blocks=sc.null_blocks + (np.sqrt(c) - 1) * so), c


def mixed_bootstrap(sc: Screening, prior: YawPrior, weight: float, length: int = 30, seed: int = 0) -> Screening:
    """Stop 53 (c): the records' AR term (:func:`stored_offsets`) and the projected own-residual bootstrap
    (``bootp30``, :func:`own_bootstrap`) mixed in variance, ``sqrt(1 - weight)`` of the one plus
    ``sqrt(weight)`` of the other (independent): between main (``weight`` 0) and ``bootp30`` (1), the
    trade of calibration against the changed runs' thresholds."""
    nb, runs = sc.null_blocks.shape
    so = stored_offsets(prior, len(sc.eps), runs)[:nb]
    boot = own_bootstrap(sc, prior, length, seed, project=True).null_blocks - (sc.null_blocks - so)
    return replace(sc, null_blocks=sc.null_blocks + (np.sqrt(1 - weight) - 1) * so + np.sqrt(weight) * boot)


#: stop 53 --own-misfit settings of the records' AR term scaled (:func:`term_scale`), and the band read
SCALE_BANDS = {"scale": "all", "scaleb": "above", "scalei": "in"}


def with_own(sc: Screening, prior: YawPrior, setting: str = "stored") -> tuple[Screening, float]:
    """The stored screening ``sc`` with its records' misfit as ``setting`` says (:data:`OWN`, or
    ``bootL``: :func:`own_bootstrap` with blocks of L s; ``bootpL``: the same of the part orthogonal to
    the signatures, :func:`projected`), and the innovation sd a level setting added
    (0 else); the dead-zone CUSUM's threshold stays as stored (it only drops alarms)."""
    if setting == "stored":
        return sc, 0.0
    if setting in SCALE_BANDS:
        return scaled_term(sc, prior, SCALE_BANDS[setting])[0], 0.0
    if setting.startswith("mix"):
        return mixed_bootstrap(sc, prior, int(setting[3:]) / 100), 0.0
    if setting.startswith("lowb"):
        return low_band_bootstrap(sc, prior, int(setting[4:])), 0.0
    if setting.startswith("bootn"):
        return own_bootstrap(sc, prior, int(setting[5:]), project=True, denoise=True), 0.0
    if setting.startswith("bootp"):
        return own_bootstrap(sc, prior, int(setting[5:]), project=True), 0.0
    if setting.startswith("boot"):
        return own_bootstrap(sc, prior, int(setting[4:])), 0.0
    gate, level = OWN[setting]
    extra = own_misfit(prior, sc.eps, sc.S, sc.null_blocks, gate=gate, level=level)
    if extra <= 0:
        return sc, 0.0
    nb, runs = sc.null_blocks.shape
    off = block_mean(extra_offsets(prior, extra, nb * prior.block, runs, 0), prior.block)
    return replace(sc, null_blocks=sc.null_blocks + off), extra
