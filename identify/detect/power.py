"""How large a change one recording could show: the smallest relative change of each candidate property
that the recording's own LR-CUSUM (:mod:`identify.detect.glr`) alarms on with ``POWER`` probability, at the
thresholds it was calibrated with, from the same no-change records (issue 25: a recording too short,
too calm or screened with too uncertain a prior is said to be blind, not to show no change).

Kept apart from the screening, as the verdict is (:mod:`identify.detect.verdict`): it reads a stored
:class:`~identify.detect.verdict.Screening` only and changes none of the detector's decisions."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

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
#: the later onsets whose figure is also reported, as fractions of the recording's length (the start's is the
#: candidates' own): a change in the second half leaves the CUSUM half the blocks or fewer
LATER = (0.25, 0.5, 0.75)
#: the candidates reported at the later onsets: yaw inertia, the truth family's change (each further candidate
#: costs one search per onset)
LATER_OF = ("yaw_inertia",)
#: the figure's name per candidate, in the text report and the JSON
OF = {"yaw_inertia": "I_r", "yaw_damping": "damping", "pod_gain": "gain"}


@dataclass(frozen=True)
class NullSums:
    """The no-change records' running sums that every candidate's and onset's search shares
    (:func:`null_sums`): ``ca`` (nb + 1, 2, runs, k) of candidate ``k``'s up and down increments from a leading
    0, in single precision; ``e`` (nb, runs, k) candidate ``k``'s whitened records; ``m`` (nb, k) the
    LR-CUSUM's tuned signatures ``theta1_k S_k`` whitened, ``sw`` the signatures whitened; ``sb`` the
    signatures' block means before whitening (a later change's signature is masked there, as the record it is
    added to)."""

    ca: np.ndarray
    e: np.ndarray
    m: np.ndarray
    sw: np.ndarray
    sb: np.ndarray
    s2: float
    prior: YawPrior
    band: RollBand | None

    @property
    def blocks(self) -> int:
        """The records' length in blocks."""
        return self.e.shape[0]


def null_sums(
    prior: YawPrior,
    S: np.ndarray,
    null_blocks: np.ndarray,
    theta1: np.ndarray,
    seed: int = 0,
    band: RollBand | None = None,
) -> NullSums:
    """The running sums of :class:`NullSums` for the signatures ``S`` (n, k) and no-change records
    ``null_blocks`` (nb, runs) (the assumptions are :func:`detectable_changes`')."""
    ew = decision_whiten(np.asarray(null_blocks, float), prior, band)
    nb, runs = ew.shape
    sb = block_mean(S, prior.block)
    sw = decision_whiten(sb, prior, band)[:nb]  # (nb, k)
    xi = structural_draws(prior, runs, seed)  # (k, runs)
    e = ew[:, :, None] + (prior.structure[:, None] * xi).T[None] * sw[:, None, :]  # (nb, runs, k): k's records
    m = np.asarray(theta1, float) * sw
    s2 = prior.sigma_w**2
    # running sums from a leading 0 (the CUSUM's start), in single precision: the sums reach ~1e3 against
    # thresholds ~10, a rounding of 1e-4 at most, and half the memory each step reads
    return NullSums(_increment_sums(m, e, s2), e, m, sw, sb, s2, prior, band)


def _increment_sums(m: np.ndarray, e: np.ndarray, s2: float) -> np.ndarray:
    """(nb + 1, 2, runs, k) float32 running sums, from a leading 0, of the up and down LR-CUSUM increments
    ``(+-m_k e - m_k^2 / 2) / s2`` of the records ``e`` (nb, runs, k) (Basseville and Nikiforov 1993, 2.2), made
    a block row at a time: the same float64 operations per element as forming the (nb, 2, runs, k) increments
    whole, summing them along axis 0 and rounding to float32, without those float64 arrays' fresh pages (stop 60)."""
    nb, runs, k = e.shape
    out = np.zeros((nb + 1, 2, runs, k), np.float32)
    half = 0.5 * m * m
    acc, inc = np.empty((2, runs, k)), np.empty((2, runs, k))
    for t in range(nb):
        np.subtract(np.multiply(m[t], e[t], out=inc[0]), half[t], out=inc[0])
        np.subtract(np.multiply(-m[t], e[t], out=inc[1]), half[t], out=inc[1])
        np.divide(inc, s2, out=inc)
        if t == 0:
            acc[...] = inc  # a running sum's first term is the increment itself
        else:
            np.add(acc, inc, out=acc)
        out[t + 1] = acc
    return out


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

    Assumes: the change is a step at the recording's start (a later change: :func:`change_figure`); an
    increase (the two-sided CUSUM treats a decrease alike, to the null's asymmetry);
    the no-change records are the null, i.e. the prior's own bootstrap error, the nominal noise and the
    structural apparent change (candidate ``k``'s records carry ``prior.structure[k] * xi_k * S_k``, the
    very draws :func:`identify.detect.glr.null_peaks` calibrated ``h`` on, seed ``seed``); the LR-CUSUM
    stage alone: the verdict's --min-change and 2-sd tests only drop alarms; and that a record that alarms
    at some theta alarms at every larger one (true of its own candidate's upward CUSUM, whose increments
    grow with theta; the bisection then evaluates only the records whose alarm is not yet known).

    The statistic is linear in the record before the CUSUM (the whitening is a linear filter), so candidate
    ``k``'s increment on the changed record is ``A_k + theta_j B_jk`` (Basseville and Nikiforov 1993, 2.2:
    ``(+-m_k e - m_k^2 / 2) / sigma_w^2``, ``m_k = theta1_k S_k`` whitened), and its running sum is
    ``cumsum A_k + theta_j cumsum B_jk``: the records' sums are made once (:func:`null_sums`), each bisection
    step is a running minimum over the records it evaluates."""
    sums = null_sums(prior, S, null_blocks, theta1, seed, band)
    return np.array([change_figure(sums, j, 0, h, power) for j in range(sums.m.shape[1])])


def change_figure(sums: NullSums, j: int, onset: int, h: np.ndarray, power: float = POWER) -> float:
    """:func:`detectable_changes`' figure of candidate ``j`` for a step change at block ``onset`` (0: the
    recording's start), alarmed at or after it: a record whose CUSUM alarmed before (a false alarm, the
    detector's first alarm) counts as missed, as the truth bench counts it; the alarm comes before the
    recording ends, as the records end there.

    The change's signature is ``S_j`` with its blocks before ``onset`` zeroed, then whitened (the masked
    signature). A step of the parameter at ``t_k`` moves the prediction by the sensitivity of a simulation
    started from the prior's state at ``t_k``: zero there, reaching ``S_j(t)`` after the yaw motion's own time
    constant, while the masked one carries the state's deviation ``S_j(t_k)`` of a change since the start. The
    masked one is used as it is the change the LR-CUSUM itself tests for (its template ``theta1 S_k`` summed from
    any start) and needs no simulation; it overstates the first seconds after ``t_k`` only: on the tests' 300 s
    recording with a step at 150 s the true sensitivity's figures are 0.1, -0.02 and 0.2 % off the masked one's,
    within the search's 3 % (tests/test_detect_power.py). Before ``onset`` the records'
    sums are the null's: each record's CUSUM is carried to ``onset`` once, and the search evaluates the blocks
    from there (Lindley's form from ``g_onset``, :func:`_from_block`)."""
    sw = sums.sw[:, j] if onset == 0 else _masked(sums, onset)[:, j]
    m = sums.m
    cb = _running_sum(np.stack([m * sw[:, None], -m * sw[:, None]], axis=1)[:, :, None, :] / sums.s2)
    ca, cb, early = _from_block(sums.ca, cb.astype(np.float32), onset, np.asarray(h, np.float32))
    # the search starts at 4 sd of the no-change records' GLR estimate from the onset (a z of about 2.6 for the
    # alarm and 1.3 for the power): bracketing from there takes one or two steps, not ten from 0.1-100 %
    sd = np.std(sw @ sums.e[:, :, j]) / max(float(sw @ sw), 1e-300)
    return _smallest(ca, cb, np.asarray(h, np.float32), power, 4 * sd, early)


def _masked(sums: NullSums, onset: int) -> np.ndarray:
    """(nb, k) the signatures with their blocks before ``onset`` zeroed, then whitened."""
    sb = sums.sb.copy()
    sb[:onset] = 0.0
    return decision_whiten(sb, sums.prior, sums.band)[: sums.blocks]


def _from_block(ca: np.ndarray, cb: np.ndarray, i: int, h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The running sums ``ca``, ``cb`` (nb + 1, 2, runs, k) of a CUSUM whose ``cb`` is 0 to row ``i``, from row
    ``i`` on: ``D = ca[i:] - ca[i] + g_i`` after a leading 0 (``g_i = ca[i] - min ca[:i + 1]``, the CUSUM at
    ``i``) gives ``D_t - min_s D_s = g_t`` there, so the search reads ``nb + 1 - i`` rows; and (runs,) whether a
    record alarmed at or before ``i``. Row 0 (the start) returns the sums as they are."""
    runs = ca.shape[2]
    if i == 0:
        return ca, cb, np.zeros(runs, bool)
    peak, g_i = _peak(ca[: i + 1])
    early = (peak > h).any(axis=(0, 2))
    d = np.empty((len(ca) - i + 1, *ca.shape[1:]), np.float32)
    d[0] = 0.0
    np.subtract(ca[i:], ca[i] - g_i, out=d[1:])
    c = np.zeros_like(d[:, :, :1])
    np.subtract(cb[i:], cb[i], out=c[1:])
    return d, c, early


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
    return (_peak(ca, cb, np.float32(theta))[0] > h).any(axis=(0, 2))


#: records from which :func:`_peak` forms the CUSUM a block row at a time: numpy's running minimum along the
#: records' time axis (``np.minimum.accumulate``, axis 0) runs element by element, 5.1 ms for the README
#: example's (501, 2, 400, 3) sums against 1.0 ms in 500 row steps of three array calls (stop 60); below it the
#: row steps' fixed cost (about 2.6 us a row) is more than the accumulate's
ROWS_FROM = 96


def _records(ca: np.ndarray, todo: np.ndarray) -> np.ndarray:
    """The running sums of the records ``todo`` (axis 2): in C order from :data:`ROWS_FROM` records on (for
    :func:`_peak`'s rows), else as numpy's indexing lays them out (a record's sums together: its running minimum's
    fastest order)."""
    return np.take(ca, todo, axis=2) if len(todo) >= ROWS_FROM else ca[:, :, todo]


def _peak(ca: np.ndarray, cb: np.ndarray | None = None, theta: np.float32 = np.float32(0)) -> tuple[np.ndarray, np.ndarray]:
    """The CUSUM's peak ``max_t (C_t - min_{s<=t} C_s)`` over axis 0 of the running sums ``C = ca + theta cb``
    (``cb`` broadcast along the records; None: ``C = ca``), and its last term ``C_T - min_s C_s`` (the CUSUM at
    the last row): Lindley's form as :func:`_alarmed` reads it. The same float32 operations on every element in
    either order of evaluation (``theta cb`` then the sum, a running minimum, the difference, the largest), so
    the same numbers by rows as by numpy's whole-array running minimum (tests/test_detect_power.py); a NaN is
    carried to the peak either way (numpy's minimum and maximum pass it on)."""
    if ca.shape[2] < ROWS_FROM:
        c = ca + theta * cb if cb is not None else ca.copy()
        low = np.minimum.accumulate(c, axis=0)
        np.subtract(c, low, out=c)
        return c.max(axis=0), c[-1]
    row = np.empty(ca.shape[1:], np.float32)
    step = theta * cb if cb is not None else None  # (nb + 1, 2, 1, k): the records share it
    low = (ca[0] + step[0]) if cb is not None else ca[0].copy()
    peak = low - low  # row 0's term, 0 (a NaN stays one), as the accumulate's
    last = peak
    for t in range(1, len(ca)):
        x = ca[t] if cb is None else np.add(ca[t], step[t], out=row)
        np.minimum(low, x, out=low)
        last = np.subtract(x, low, out=row)
        np.maximum(peak, last, out=peak)
    return peak, last


def _smallest(
    ca: np.ndarray, cb: np.ndarray, h: np.ndarray, power: float, guess: float, never: np.ndarray | None = None
) -> float:
    """Smallest theta in [SMALLEST, LARGEST] at which at least ``power`` of the records alarm, to a ratio of
    RESOLUTION: bracketed from ``guess`` by factors of STEP, then bisected on log(theta); NaN when LARGEST is not
    enough, SMALLEST when that is. A record that alarmed at a theta at or below the one tried, or stayed quiet
    at one at or above it, is not evaluated again (near the end, a few records are). The records ``never``
    (runs,) count as quiet at every theta (alarmed before the change)."""
    runs = ca.shape[2]
    alarm_at = np.full(runs, np.inf)  # smallest theta tried at which the record alarmed
    quiet_at = np.zeros(runs)  # largest theta tried at which it did not
    if never is not None:
        quiet_at[never] = np.inf

    def enough(theta: float) -> bool:
        todo = np.flatnonzero((alarm_at > theta) & (quiet_at < theta))
        if len(todo):
            hit = _alarmed(ca if len(todo) == runs else _records(ca, todo), cb, theta, h)  # no copy of all
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
    later_s: Sequence[float] | None = None,
) -> dict:
    """The report of :func:`detectable_changes` on a screened recording: per candidate the relative change
    (of I_z for yaw inertia when the hull's ``i_z`` and ``n_rdot`` are known, else of I_r; None: over
    LARGEST), what it is of, and whether ``min_change`` is below it (the recording cannot show a change of
    that size; ``blind_to_min_change`` lists those candidates). The figure is of the LR-CUSUM tuned to
    ``theta1`` (from ``min_change``): the same recording's figure is larger at a larger ``min_change``.
    ``later``: the figures of the candidates LATER_OF for a change at ``later_s`` seconds after the
    recording's start (None: at the fractions LATER of its length; :func:`change_figure`), from the same sums."""
    sums = null_sums(prior, sc.S, sc.null_blocks, theta1, seed, sc.roll_band)
    known = i_z is not None and n_rdot is not None
    out: dict = {"power": POWER, "false_alarm": false_alarm, "min_change": min_change, "change_from": "start"}
    out["largest_searched"] = LARGEST
    for j, c in enumerate(CANDIDATES):
        out[c] = _figure(c, change_figure(sums, j, 0, sc.h), known, i_z, n_rdot)
    blind = [c for c in CANDIDATES if out[c]["relative_change"] is None or out[c]["relative_change"] > min_change]
    out["blind_to_min_change"] = blind
    out["warning"] = {"name": BLIND, "message": blind_message(out, min_change)} if blind else None
    block_s = prior.block * prior.dt
    if later_s is None:
        later_s = [f * sums.blocks * block_s for f in LATER]
    out["later"] = []
    for t in later_s:
        # the block nearest t: a change inside one is taken from its start
        i = min(max(int(round(t / block_s)), 0), sums.blocks - 1)
        one = {"onset_s": i * block_s}
        for c in LATER_OF:
            one[c] = _figure(c, change_figure(sums, CANDIDATES.index(c), i, sc.h), known, i_z, n_rdot)
        out["later"].append(one)
    return out


def _figure(c: str, x: float, known: bool, i_z: float | None, n_rdot: float | None) -> dict:
    """Candidate ``c``'s report of a relative change ``x`` (NaN: over LARGEST, None): of I_z for yaw inertia
    when the hull is ``known``, else of its own property (OF)."""
    size, of = (float(x) if np.isfinite(x) else None), OF[c]
    if c == "yaw_inertia" and known:
        of = "I_z"
        size = None if size is None else physical_change(c, size, i_z - n_rdot, n_rdot)
    return {"relative_change": size, "of": of}


def later_text(d: dict) -> str:
    """``yaw inertia from 125 s >= 9.0 %, 250 s >= 11.2 %, 375 s over 100 %`` (:func:`detectable`'s ``later``)."""
    parts = []
    for c in LATER_OF:
        sizes = []
        for one in d.get("later", []):
            sizes.append(f"{one['onset_s']:.0f} s {_size_text(d, one[c]['relative_change'])}")
        if sizes:
            parts.append(f"{c.replace('_', ' ')} from " + ", ".join(sizes))
    return "; ".join(parts)


#: the warning's name (text report and JSON) when --min-change is below what the recording can show
BLIND = "blind-to-min-change"


def sizes_text(d: dict, only: list[str] | None = None) -> str:
    """``yaw inertia >= 8.0 % of I_z, ...`` for the candidates ``only`` (default all) of :func:`detectable`."""
    parts = []
    for c in only or CANDIDATES:
        size, of = _size_text(d, d[c]["relative_change"]), d[c]["of"]
        parts.append(f"{c.replace('_', ' ')} {size}" + (f" of {of}" if c == "yaw_inertia" else ""))
    return ", ".join(parts)


def _size_text(d: dict, x: float | None) -> str:
    """``>= 8.1 %``, or ``over 100 %`` for a figure over the search (None)."""
    return f"over {100 * d['largest_searched']:.0f} %" if x is None else f">= {100 * x:.1f} %"


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
