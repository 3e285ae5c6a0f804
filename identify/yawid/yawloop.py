"""The yaw row's time loop without sensitivities: the explicit Euler step of (2.17)/(2.18) of
:func:`identify.yawid.estimate.simulate_yaw` over every step and batch member, compiled with numba
(:mod:`primitives.jitloop`; :func:`simulate`: the generic loop's bits) for large batches, and in numpy
without the generic loop's per-term calls (:func:`simulate_numpy`: the generic loop's sum in another
order, equal to rounding) otherwise.

A change detector simulates 400 no-change records of a 500 s recording twice per recording
(:mod:`identify.detect.nullsim`); in numpy each of the 5,000 steps made about twenty array
operations on 400 members and the input forcing a dozen 16 MB temporaries, 0.2-0.3 s CPU a
simulation. The compiled loop's operations are numpy's generic loop's, in the same order, on the same
IEEE doubles (no fast-math, so no fused multiply-add): the input forcing ``tau_r`` plus each input term
of the model in its order (:data:`identify.yawid.model.INPUT_TERMS`), then each state term's value
``u r``, ``r |r|``, ``r |v|``, ``(phi u) |r|`` (:data:`identify.yawid.model.STATE_TERMS`) times its
parameter, divided by I_r, then ``r + Ts f`` -- the same bits (tests/test_yawloop.py). The numpy loop
(stop 51) groups the step's terms by how they hold r, ``r a + |r| (b + g r) + c``, so that a step is 7
array operations: a last-bit difference per step, within 1e-13 of the yaw rate over 900 steps
(tests/test_yawloop.py against a plain reference), 1e-13 relative in ``detect``'s thresholds and statistics.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from identify.yawid.model import YawModel
from primitives import jitloop

#: the input terms (:data:`identify.yawid.model.INPUT_TERMS`) and the r-dependent terms
#: (:data:`identify.yawid.model.STATE_TERMS`) of (2.17)/(2.18) by their code in the loop
INPUT_CODES = {"M_v": 0, "N_uv": 1, "N_phiuv": 2, "N_phiuu": 3, "N_p": 4}
STATE_CODES = {"A": 0, "N_rr": 1, "N_rv": 2, "N_phiur": 3}
#: the measured signals the loop reads, in its argument order
SIGNALS = ("tau_r", "u", "v", "v_dot", "phi", "p")
#: elements (members x samples) of one block of :func:`simulate_numpy`'s coefficients: 256 KB an array, in the cache
BLOCK = 2**15
#: batches of up to this many members are stepped member by member on Python floats (about 1.3 ms a member
#: for 5,000 steps, against 25-40 ms for any batch of under 20 in array operations)
FLOATS = 16
#: :func:`simulate_numpy`'s state terms: how each multiplies the yaw rate (0 ``r |r|``, 1 ``x |r|``, 2 ``x r``)
#: and the signals its factor ``x`` is made of (``u``; none; ``|v|``; ``phi u``)
STEPPED = {"A": (2, ("u",)), "N_rr": (0, ()), "N_rv": (2, ("v",)), "N_phiur": (1, ("phi", "u"))}


_R = "Array(float64, 2, 'A', readonly=True)"  # any strides: transposed, time-reversed or broadcast views, no copies
_V, _I = "Array(float64, 1, 'A', readonly=True)", "Array(int64, 1, 'A', readonly=True)"  # writable or not
_SIGNATURE = f"void({', '.join([_R] * 6)}, {_I}, {_R}, {_I}, {_R}, {_V}, {_V}, float64, float64[:, :])"


@jitloop.typed(_SIGNATURE)
def _loop(tau, u, v, vd, phi, p, in_codes, th_in, st_codes, th_st, i_r, r0, ts, out):  # pragma: no cover - compiled
    # member by member along time: the inputs are (B, N) views of time-contiguous rows (the zero-phase
    # filter's output), read along their rows; each member's steps are the same operations in the same order
    b, n = tau.shape
    for i in range(b):
        ri = r0[i]
        for k in range(n):
            out[i, k] = ri
            f = tau[i, k]
            for t in range(in_codes.shape[0]):
                c = in_codes[t]
                if c == 0:
                    x = -vd[i, k]
                elif c == 1:
                    x = abs(u[i, k]) * v[i, k]
                elif c == 2:
                    x = phi[i, k] * abs(u[i, k] * v[i, k])
                elif c == 3:
                    x = phi[i, k] * u[i, k] * abs(u[i, k])
                else:
                    x = p[i, k]
                f = f + th_in[t, i] * x
            for t in range(st_codes.shape[0]):
                c = st_codes[t]
                if c == 0:
                    x = u[i, k] * ri
                elif c == 1:
                    x = ri * abs(ri)
                elif c == 2:
                    x = ri * abs(v[i, k])
                else:
                    x = phi[i, k] * u[i, k] * abs(ri)
                f = f + th_st[t, i] * x
            f = f / i_r[i]
            ri = ri + ts * f


def usable(model: YawModel, w: dict[str, np.ndarray], b: int, n: int) -> bool:
    """Whether :func:`simulate` runs ``b`` members of ``n`` steps compiled: numba there and the
    work worth loading it (:func:`primitives.jitloop.use`), every term of the model known to the loop
    and every signal it reads given (the compiled loop does not check its indices: a missing signal
    must fail in the numpy loop with its KeyError, not read out of bounds). The loop's one signature
    reads native float64: other inputs (float32, integers, another byte order) run the numpy loop, whose
    arithmetic in their own type the float64 loop would not repeat bit for bit."""
    known = all(t in INPUT_CODES for t in model.input_terms) and all(t in STATE_CODES for t in model.state_terms)
    given = set(model.signals) <= set(w) and "tau_r" in w
    doubles = given and all(np.asarray(w[k]).dtype == np.float64 for k in SIGNALS if k in w)
    return known and doubles and jitloop.use(b * n)


def simulate(model: YawModel, theta: np.ndarray, col: dict[str, int], w: dict[str, np.ndarray], r0, ts: float) -> np.ndarray:
    """Predicted yaw rate (B, N), a view of time-major memory, from the measured inputs ``w`` (B, N) each (any strides:
    read where they lie, not copied), ``theta`` (B, p) in ``col``'s order and ``r0`` (B,)."""
    b, n = w["u"].shape
    theta = np.broadcast_to(theta, (b, theta.shape[1]))  # the loop reads one parameter set per member
    dummy = np.zeros((1, 1))
    sig = [np.broadcast_to(w[k], (b, n)) if k in w else dummy for k in SIGNALS]  # float64 (usable)

    def coded(names: tuple[str, ...], codes: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
        th = np.stack([theta[:, col[t]] for t in names]) if names else np.zeros((0, b))
        return np.array([codes[t] for t in names], np.int64), np.asarray(th, float)

    ins, sts = coded(model.input_terms, INPUT_CODES), coded(model.state_terms, STATE_CODES)
    r0 = np.array(np.broadcast_to(np.asarray(r0, float), (b,)))
    out = np.empty((n, b)).T  # written time-major: the (N, B) layout the detector's callers read (no copy there)
    _loop(*sig, *ins, *sts, np.asarray(theta[:, col["I_r"]], float), r0, float(ts), out)
    return out


def stepped(model: YawModel, w: dict[str, np.ndarray]) -> bool:
    """Whether :func:`simulate_numpy` runs this model on ``w``: every state term known to it and the
    signals those terms read native float64 (other types run the generic loop, in their own arithmetic)."""
    if not all(t in STEPPED for t in model.state_terms):
        return False
    read = {k for t in model.state_terms for k in STEPPED[t][1]}
    return all(k in w and np.asarray(w[k]).dtype == np.float64 for k in read)


def added(w: dict[str, np.ndarray], extra: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``w``'s signals with ``extra``'s added where it has one (``x + e`` elementwise, the records' inputs of
    :func:`identify.detect.nullsim.null_records`): whole before a simulation, or a block of samples at a time
    inside :func:`simulate_numpy`; IEEE addition per element, so the same bits either way."""
    return {k: x + extra[k] if k in extra else x for k, x in w.items()}


def simulate_numpy(
    model: YawModel,
    theta: np.ndarray,
    col: dict[str, int],
    forcing: Callable[[dict[str, np.ndarray]], np.ndarray],
    w: dict[str, np.ndarray],
    r0: float | np.ndarray,
    ts: float,
    extra: dict[str, np.ndarray] | None = None,
) -> np.ndarray:
    """:func:`simulate` in numpy: the explicit Euler step of (2.17)/(2.18) over the batch, one sample at a time,
    with the step's terms grouped by how they hold r (stop 51):

        r[k+1] = r[k] a[k] + |r[k]| (b[k] + g r[k]) + c[k]

    ``a = 1 + (Ts / I_r) sum th x`` over the ``x r`` terms (``A u r``, ``N_rv |v| r``), ``b = (Ts / I_r) sum th x``
    over the ``x |r|`` terms (``N_phiur phi u |r|``), ``g = (Ts / I_r) N_rr`` and ``c = (Ts / I_r) f``, ``f`` the
    input terms plus tau_r, (B, len) from ``forcing`` of the inputs of a block of samples
    (:func:`identify.yawid.estimate._input_forcing`). Everything but r is formed outside the step, a block of samples
    at a time (:func:`_coefficients`: its arrays stay in the cache, not 16 MB temporaries; an input the same for
    every member, a broadcast row, is read as one row), so a step is 7 array operations, not the generic loop's 17
    (the Python call per operation, not the arithmetic, is the cost at 400 members). The generic loop's sum
    (:func:`identify.yawid.estimate.simulate_yaw`) in another order: equal to rounding, not to the bit
    (tests/test_yawloop.py: within 1e-13 of the yaw rate's scale on random inputs). Up to :data:`FLOATS` members
    are stepped on Python floats (:func:`_one`), the same IEEE operations in the same order: this loop's bits.
    ``extra`` (B or 1, N) per signal is added to ``w``'s a block of samples at a time: the same bits as adding it
    first, without the whole (B, N) sums in memory (a detector's no-change records: 16 MB of fresh pages each)."""
    b, n = w["u"].shape
    theta = np.ascontiguousarray(theta, dtype=float)
    out = np.empty((n, b))
    if n == 0:
        return out.T
    out[0] = np.broadcast_to(np.asarray(r0, float), (b,))
    scale = ts / theta[:, col["I_r"]]  # (B,): Ts / I_r once per member
    g = theta[:, col["N_rr"]] * scale if "N_rr" in model.state_terms else None
    step = n if b <= FLOATS else max(16, BLOCK // b)
    bufs = (np.empty(b), np.empty(b), np.empty(b))
    w = {k: x[:1] if x.shape[0] > 1 and x.strides[0] == 0 else x for k, x in w.items()}  # a broadcast row: one row
    extra = {k: x[:1] if x.shape[0] > 1 and x.strides[0] == 0 else x for k, x in (extra or {}).items()}
    for k0 in range(0, n - 1, step):
        sl = slice(k0, min(k0 + step, n - 1))
        part = added({k: x[:, sl] for k, x in w.items()}, {k: e[:, sl] for k, e in extra.items()})
        a, bk, c = _coefficients(model, theta, col, forcing(part), part, scale)
        if b <= FLOATS:
            for i in range(b):
                coef = (a[:, i], None if bk is None else bk[:, i], None if g is None else float(g[i]), c[:, i])
                out[sl.start + 1 : sl.stop + 1, i] = _one(float(out[sl.start, i]), *coef)
        else:
            _steps(out[sl.start : sl.stop + 1], a, bk, g, c, bufs)
    return out.T


def _steps(out: np.ndarray, a: np.ndarray, bk: np.ndarray | None, g: np.ndarray | None, c: np.ndarray, bufs) -> None:
    """``out[j + 1]`` from ``out[j]`` for each row j of the block's (len, B) coefficients (:func:`simulate_numpy`)."""
    ar, t, s = bufs
    mul, add, absolute = np.multiply, np.add, np.abs  # local names: no attribute lookups in the steps' loop
    for k in range(len(a)):
        r = out[k]
        mul(r, a[k], out=s)
        if g is not None or bk is not None:
            absolute(r, out=ar)
            if g is None:
                mul(bk[k], ar, out=t)
            else:
                mul(g, r, out=t)
                if bk is not None:
                    add(t, bk[k], out=t)
                mul(t, ar, out=t)
            add(s, t, out=s)
        add(s, c[k], out=out[k + 1])


def _coefficients(
    model: YawModel, theta: np.ndarray, col: dict[str, int], f: np.ndarray, w: dict[str, np.ndarray], scale: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`simulate_numpy`'s ``a``, ``b`` (None without an ``x |r|`` term) and ``c`` of a block of samples,
    time-major (len, B): step k reads one contiguous row of each. ``f`` is the block's forcing (B, len), ``w`` its
    inputs (B or 1, len); formed member-major, as the inputs lie, and transposed once at the end."""
    th = theta[:, None, :]
    sc = scale[:, None]
    lin, absr = None, None
    for term in model.state_terms:
        code, names = STEPPED[term]
        if code == 0:  # r |r|: its g is a member's constant
            continue
        x = w[names[0]]
        x = np.abs(x) if term == "N_rv" else x * w[names[1]] if len(names) == 2 else x  # the factor: once per row
        x = th[:, :, col[term]] * x
        if code == 2:
            lin = x if lin is None else np.add(lin, x, out=lin)
        else:
            absr = x if absr is None else np.add(absr, x, out=absr)
    b, m = f.shape
    lin = np.zeros((b, m)) if lin is None else np.broadcast_to(lin, (b, m))
    a = np.multiply(lin.T, sc.T, out=np.empty((m, b)))
    a += 1.0
    bk = None if absr is None else np.multiply(np.broadcast_to(absr, (b, m)).T, sc.T, out=np.empty((m, b)))
    return a, bk, np.multiply(f.T, sc.T, out=np.empty((m, b)))


def _one(r: float, a: np.ndarray, bk: np.ndarray | None, g: float | None, c: np.ndarray) -> list[float]:
    """:func:`_steps` for one member on Python floats (no array call per operation): the same IEEE double
    operations in the same order, so its bits. The yaw rates after ``r``, one per coefficient."""
    av, cv = a.tolist(), c.tolist()
    bv = None if bk is None else bk.tolist()
    rs = []
    for k in range(len(av)):
        if g is not None:
            t = g * r
            if bv is not None:
                t = t + bv[k]
            r = r * av[k] + t * abs(r) + cv[k]
        elif bv is not None:
            r = r * av[k] + bv[k] * abs(r) + cv[k]
        else:
            r = r * av[k] + cv[k]
        rs.append(r)
    return rs
