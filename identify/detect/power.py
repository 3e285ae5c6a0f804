"""How large a change one recording could show: the smallest relative change of each candidate property
that the recording's own LR-CUSUM (:mod:`identify.detect.glr`) alarms on with ``POWER`` probability, at the
thresholds it was calibrated with, from the same no-change records (issue 25: a recording too short,
too calm or screened with too uncertain a prior is said to be blind, not to show no change).

Kept apart from the screening, as the verdict is (:mod:`identify.detect.verdict`): it reads a stored
:class:`~identify.detect.verdict.Screening` only and changes none of the detector's decisions."""

from __future__ import annotations

import numpy as np

from identify.detect.glr import structural_draws
from identify.detect.rollband import RollBand, decision_whiten
from identify.detect.verdict import Screening, physical_change
from identify.detect.yawmodel import CANDIDATES, YawPrior, block_mean

#: probability of an alarm that "detectable" stands for
POWER = 0.9
#: largest relative change searched (100 %): a recording that needs more is reported as blind to any
LARGEST = 1.0
#: smallest relative change searched (0.1 %)
SMALLEST = 1e-3
#: the search's steps from its first guess until the change is bracketed: small, as each step evaluates only
#: the records whose alarm changes within it (README's example: 2.5 evaluations of all records per candidate
#: with factors of 2, 2.0 with 1.25)
STEP = 1.25
#: the bisection stops when its bracket is this ratio wide (3 %)
RESOLUTION = 1.03
#: the figure's name per candidate, in the text report and the JSON
OF = {"yaw_inertia": "I_r", "yaw_damping": "damping", "pod_gain": "gain"}


def detectable_changes(
    prior: YawPrior,
    S: np.ndarray,
    null_blocks: np.ndarray,
    h: np.ndarray,
    theta1: np.ndarray,
    seed: int = 0,
    band: RollBand | None = None,
    power: float = POWER,
) -> np.ndarray:
    """(k,) smallest relative change ``theta_j`` of each candidate's property (I_r, damping, pod gain, as the
    signatures ``S`` (n, k) are per relative change) whose LR-CUSUM alarms (any candidate over its threshold
    ``h``, :meth:`SignatureCusum.alarms`) on at least ``power`` of the no-change records ``null_blocks`` (nb,
    runs) with ``theta_j * S_j`` added; NaN where even LARGEST does not.

    Assumes: the change is a step at the recording's start (a later change leaves fewer blocks: a larger
    change is needed); an increase (the two-sided CUSUM treats a decrease alike, to the null's asymmetry);
    the no-change records are the null, i.e. the prior's own bootstrap error, the nominal noise and the
    structural apparent change (candidate ``k``'s records carry ``prior.structure[k] * xi_k * S_k``, the
    very draws :func:`identify.detect.glr.null_peaks` calibrated ``h`` on, seed ``seed``); the LR-CUSUM
    stage alone: the verdict's --min-change and 2-sd tests only drop alarms; and that a record that alarms
    at some theta alarms at every larger one (true of its own candidate's upward CUSUM, whose increments
    grow with theta; the bisection then evaluates only the records whose alarm is not yet known).

    The statistic is linear in the record before the CUSUM (the whitening is a linear filter), so candidate
    ``k``'s increment on the changed record is ``A_k + theta_j B_jk`` (Basseville and Nikiforov 1993, 2.2:
    ``(+-m_k e - m_k^2 / 2) / sigma_w^2``, ``m_k = theta1_k S_k`` whitened), and its running sum is
    ``cumsum A_k + theta_j cumsum B_jk``: the records' sums are made once, each bisection step is a running
    minimum over the records it evaluates."""
    ew = decision_whiten(np.asarray(null_blocks, float), prior, band)
    nb, runs = ew.shape
    sw = decision_whiten(block_mean(S, prior.block), prior, band)[:nb]  # (nb, k)
    xi = structural_draws(prior, runs, seed)  # (k, runs)
    e = ew[:, :, None] + (prior.structure[:, None] * xi).T[None] * sw[:, None, :]  # (nb, runs, k): k's records
    m = np.asarray(theta1, float) * sw
    s2 = prior.sigma_w**2
    half = (0.5 * m * m)[:, None, :]
    a = np.stack([m[:, None, :] * e - half, -m[:, None, :] * e - half], axis=1) / s2  # (nb, 2, runs, k)
    # running sums from a leading 0 (the CUSUM's start), in single precision: the sums reach ~1e3 against
    # thresholds ~10, a rounding of 1e-4 at most, and half the memory each step reads
    ca = _running_sum(a).astype(np.float32)
    out = np.full(sw.shape[1], np.nan)
    for j in range(sw.shape[1]):
        cb = _running_sum(np.stack([m * sw[:, j : j + 1], -m * sw[:, j : j + 1]], axis=1)[:, :, None, :] / s2)
        # the search starts at 4 sd of the no-change records' GLR estimate from the start (a z of about 2.6 for the
        # alarm and 1.3 for the power): bracketing from there takes one or two steps, not ten from 0.1-100 %
        sd = np.std(sw[:, j] @ e[:, :, j]) / max(float(sw[:, j] @ sw[:, j]), 1e-300)
        out[j] = _smallest(ca, cb.astype(np.float32), np.asarray(h, np.float32), power, 4 * sd)
    return out


def _running_sum(x: np.ndarray) -> np.ndarray:
    """Cumulative sum along axis 0 after a leading row of zeros."""
    out = np.zeros((len(x) + 1, *x.shape[1:]))
    np.cumsum(x, axis=0, out=out[1:])
    return out


def _alarmed(ca: np.ndarray, cb: np.ndarray, theta: float, h: np.ndarray) -> np.ndarray:
    """(runs,) whether each record's CUSUM (up or down, any candidate) crosses its candidate's threshold ``h``
    (k,), from the running sums ``ca + theta cb`` of its increments ((nb + 1, 2, runs, k), from a leading 0).
    The peak of ``g_t = max(0, g_{t-1} + inc_t)`` is ``max_t (C_t - min_{s<=t} C_s)`` (Lindley's form, as
    :func:`identify.detect.cusum.cusum_path`'s closed form; the leading 0 is the ``min(0, ...)``)."""
    c = ca + np.float32(theta) * cb
    low = np.minimum.accumulate(c, axis=0)
    np.subtract(c, low, out=c)
    return (c.max(axis=0) > h).any(axis=(0, 2))


def _smallest(ca: np.ndarray, cb: np.ndarray, h: np.ndarray, power: float, guess: float) -> float:
    """Smallest theta in [SMALLEST, LARGEST] at which at least ``power`` of the records alarm, to a ratio of
    RESOLUTION: bracketed from ``guess`` by factors of STEP, then bisected on log(theta); NaN when LARGEST is not
    enough, SMALLEST when that is. A record that alarmed at a theta at or below the one tried, or stayed quiet
    at one at or above it, is not evaluated again (near the end, a few records are)."""
    runs = ca.shape[2]
    alarm_at = np.full(runs, np.inf)  # smallest theta tried at which the record alarmed
    quiet_at = np.zeros(runs)  # largest theta tried at which it did not

    def enough(theta: float) -> bool:
        todo = np.flatnonzero((alarm_at > theta) & (quiet_at < theta))
        if len(todo):
            hit = _alarmed(ca if len(todo) == runs else ca[:, :, todo], cb, theta, h)  # no copy of all
            alarm_at[todo[hit]] = theta
            quiet_at[todo[~hit]] = theta
        return bool(np.mean(alarm_at <= theta) >= power)

    # a non-finite guess (from a non-finite record or signature) starts from SMALLEST: min/max pass a NaN on,
    # and the bracket below never reached LARGEST
    hi = min(max(guess, SMALLEST), LARGEST) if np.isfinite(guess) else SMALLEST
    while not enough(hi):
        if not hi < LARGEST:
            return float("nan")
        hi = min(STEP * hi, LARGEST)
    lo = hi / STEP
    while lo >= SMALLEST and enough(lo):
        hi, lo = lo, lo / STEP
    if lo < SMALLEST:
        return SMALLEST
    while hi / lo > RESOLUTION:
        mid = float(np.sqrt(lo * hi))
        lo, hi = (lo, mid) if enough(mid) else (mid, hi)
    return hi


def detectable(
    sc: Screening,
    prior: YawPrior,
    theta1: np.ndarray,
    false_alarm: float,
    min_change: float,
    seed: int = 0,
    i_z: float | None = None,
    n_rdot: float | None = None,
) -> dict:
    """The report of :func:`detectable_changes` on a screened recording: per candidate the relative change
    (of I_z for yaw inertia when the hull's ``i_z`` and ``n_rdot`` are known, else of I_r; None: over
    LARGEST), what it is of, and whether ``min_change`` is below it (the recording cannot show a change of
    that size; ``blind_to_min_change`` lists those candidates). The figure is of the LR-CUSUM tuned to
    ``theta1`` (from ``min_change``): the same recording's figure is larger at a larger ``min_change``."""
    rel = detectable_changes(prior, sc.S, sc.null_blocks, sc.h, theta1, seed, sc.roll_band)
    known = i_z is not None and n_rdot is not None
    out: dict = {"power": POWER, "false_alarm": false_alarm, "min_change": min_change, "change_from": "start"}
    out["largest_searched"] = LARGEST
    for c, x in zip(CANDIDATES, rel):
        size, of = (float(x) if np.isfinite(x) else None), OF[c]
        if c == "yaw_inertia" and known:
            of = "I_z"
            size = None if size is None else physical_change(c, size, i_z - n_rdot, n_rdot)
        out[c] = {"relative_change": size, "of": of}
    blind = [c for c in CANDIDATES if out[c]["relative_change"] is None or out[c]["relative_change"] > min_change]
    out["blind_to_min_change"] = blind
    out["warning"] = {"name": BLIND, "message": blind_message(out, min_change)} if blind else None
    return out


#: the warning's name (text report and JSON) when --min-change is below what the recording can show
BLIND = "blind-to-min-change"


def sizes_text(d: dict, only: list[str] | None = None) -> str:
    """``yaw inertia >= 8.0 % of I_z, ...`` for the candidates ``only`` (default all) of :func:`detectable`."""
    parts = []
    for c in only or CANDIDATES:
        x, of = d[c]["relative_change"], d[c]["of"]
        size = f"over {100 * d['largest_searched']:.0f} %" if x is None else f">= {100 * x:.1f} %"
        parts.append(f"{c.replace('_', ' ')} {size}" + (f" of {of}" if c == "yaw_inertia" else ""))
    return ", ".join(parts)


def blind_message(d: dict, min_change: float) -> str:
    """What the recording cannot show and what would help (the candidates ``d["blind_to_min_change"]``)."""
    return (
        f"this recording cannot show a change of --min-change {100 * min_change:g} % in "
        f"{' or '.join(c.replace('_', ' ') for c in d['blind_to_min_change'])} (it needs "
        f"{sizes_text(d, d['blind_to_min_change'])} to alarm in {100 * d['power']:.0f} % of cases): "
        "a verdict of no change here is no evidence that no such change happened; to show smaller changes, "
        "record longer or manoeuvre more strongly (more turns, larger rudder or pod angles), or fit the prior "
        "on a longer nominal run"
    )
