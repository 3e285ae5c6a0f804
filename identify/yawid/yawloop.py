"""The yaw row's time loop without sensitivities: the explicit Euler step of (2.17)/(2.18) of
:func:`identify.yawid.estimate.simulate_yaw` over every step and batch member, compiled with numba
(:mod:`primitives.jitloop`; :func:`simulate`) for large batches, and in numpy without the generic loop's
per-term calls (:func:`simulate_numpy`) otherwise: both the generic loop's bits.

A change detector simulates 400 no-change records of a 500 s recording twice per recording
(:mod:`identify.detect.nullsim`); in numpy each of the 5,000 steps made about twenty array
operations on 400 members and the input forcing a dozen 16 MB temporaries, 0.2-0.3 s CPU a
simulation. The operations here are numpy's, in the same order, on the same IEEE doubles (no
fast-math, so no fused multiply-add): the input forcing ``tau_r`` plus each input term of the model
in its order (:data:`identify.yawid.model.INPUT_TERMS`), then each state term's value ``u r``,
``r |r|``, ``r |v|``, ``(phi u) |r|`` (:data:`identify.yawid.model.STATE_TERMS`) times its
parameter, divided by I_r, then ``r + Ts f`` -- the same bits (tests/test_yawloop.py).
"""

from __future__ import annotations

import numpy as np

from identify.yawid.model import YawModel
from primitives import jitloop

#: the input terms (:data:`identify.yawid.model.INPUT_TERMS`) and the r-dependent terms
#: (:data:`identify.yawid.model.STATE_TERMS`) of (2.17)/(2.18) by their code in the loop
INPUT_CODES = {"M_v": 0, "N_uv": 1, "N_phiuv": 2, "N_phiuu": 3, "N_p": 4}
STATE_CODES = {"A": 0, "N_rr": 1, "N_rv": 2, "N_phiur": 3}
#: the measured signals the loop reads, in its argument order
SIGNALS = ("tau_r", "u", "v", "v_dot", "phi", "p")
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


def simulate_numpy(
    model: YawModel,
    theta: np.ndarray,
    col: dict[str, int],
    forcing: np.ndarray,
    w: dict[str, np.ndarray],
    r0: float | np.ndarray,
    ts: float,
) -> np.ndarray:
    """:func:`simulate` in numpy: the explicit Euler step of (2.17)/(2.18) over the batch, one sample at a time.

    ``forcing`` (B, N) is the input terms plus tau_r (:func:`identify.yawid.estimate._input_forcing`).
    The operations are the generic loop's (:func:`identify.yawid.estimate.simulate_yaw`), element by
    element in the same order, so the same bits: ``f = forcing + th * term`` for each state term in the
    model's order, ``r + Ts (f / I_r)``. Only what does not depend on r is taken out of the loop and done
    once over all samples (``|v|``, ``phi u``: each element the same product), and every step writes
    into buffers: about 16 array operations a step without Python's per-term calls and dicts (stop 49,
    docs/detect-accuracy.md: 5,000 steps of 64 columns 0.085-0.150 -> 0.075-0.079 s CPU)."""
    b, n = forcing.shape
    theta = np.ascontiguousarray(theta, dtype=float)
    i_r = np.ascontiguousarray(theta[:, col["I_r"]])
    # each state term's parameters, how it multiplies r (STEPPED) and its factor, time-major: step k reads one row
    plan = [(np.ascontiguousarray(theta[:, col[t]]), STEPPED[t][0], _factor(t, w, b, n)) for t in model.state_terms]
    out = np.empty((n, b))
    if n == 0:
        return out.T
    out[0] = np.broadcast_to(np.asarray(r0, float), (b,))
    fk = np.ascontiguousarray(forcing.T)  # time-major: one contiguous row per step
    acc, tmp, ar = np.empty(b), np.empty(b), np.empty(b)
    mul, add, absolute = np.multiply, np.add, np.abs  # local names: no attribute lookups in the 5,000-step loop
    need_abs = any(code < 2 for _, code, _ in plan)
    for k in range(n - 1):
        r = out[k]
        if need_abs:
            absolute(r, out=ar)
        acc[:] = fk[k]
        for th, code, x in plan:
            if code == 0:
                mul(r, ar, out=tmp)
            elif code == 1:
                mul(x[k], ar, out=tmp)
            else:
                mul(x[k], r, out=tmp)
            mul(th, tmp, out=tmp)
            add(acc, tmp, out=acc)
        np.divide(acc, i_r, out=acc)
        mul(acc, ts, out=acc)
        add(r, acc, out=out[k + 1])
    return out.T


def _factor(term: str, w: dict[str, np.ndarray], b: int, n: int) -> np.ndarray | None:
    """Time-major (N, B) factor ``x`` of a state term (:data:`STEPPED`), formed once over all samples."""
    sig = {k: np.broadcast_to(w[k], (b, n)).T for k in STEPPED[term][1]}
    if term == "N_rv":
        return np.abs(sig["v"])
    if term == "N_phiur":
        return np.multiply(sig["phi"], sig["u"])
    return sig.get("u")  # A: u; N_rr: none
