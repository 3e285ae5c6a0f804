"""The compiled yaw-row loop (identify.yawid.yawloop) gives the numpy loop's bits: the change
detector's no-change records and predictions do not depend on whether numba is installed."""

from __future__ import annotations

import numpy as np
import pytest

from identify.detect.vessel import base_profile
from identify.yawid import yawloop
from identify.yawid.estimate import simulate_yaw
from identify.yawid.model import FULL_P, MODELS, YawModel, true_parameters
from identify.yawid.yawloop import INPUT_CODES, STATE_CODES
from primitives import jitloop

ALL = {**MODELS, FULL_P.name: FULL_P}  # (2.17), (2.18) and (2.17) with the roll-rate term N_p p
#: rows without N_rr r|r| and with or without an ``x |r|`` term: the stepped loop's other branches
PARTIAL = {
    "no-rr": YawModel("no-rr", ("I_r", "M_v", "A", "N_rv", "N_phiur", "N_uv")),
    "linear-in-r": YawModel("linear-in-r", ("I_r", "A", "N_rv", "N_uv")),
    "rr-only": YawModel("rr-only", ("I_r", "N_rr", "N_uv")),
}
needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _inputs(b: int, n: int, seed: int) -> dict[str, np.ndarray]:
    """(b, n) measured inputs of a turning podded ship, noisy, batch-first as simulate_yaw reads them."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    w = {
        "u": 5.0 + 0.3 * np.sin(0.02 * t) + 0.02 * rng.standard_normal((b, n)),
        "v": 0.4 * np.sin(0.05 * t) + 0.02 * rng.standard_normal((b, n)),
        "v_dot": 0.02 * np.cos(0.05 * t) + 0.003 * rng.standard_normal((b, n)),
        "phi": 0.05 * np.sin(0.8 * t) + 0.007 * rng.standard_normal((b, n)),
        "p": 0.04 * np.cos(0.8 * t) + 0.003 * rng.standard_normal((b, n)),
        "tau_r": 2e6 * np.sign(np.sin(0.03 * t)) + 6e3 * rng.standard_normal((b, n)),
    }
    return {k: np.ascontiguousarray(x.T).T for k, x in w.items()}  # time-major memory, as the detector's


def _laid_out(w: dict[str, np.ndarray], layout: str) -> dict[str, np.ndarray]:
    """The same (b, n) values in the memory layouts the detector hands the loop, which reads them where
    they lie: time-major (a transposed view), member-major (C), time-reversed rows of a wider buffer
    (the zero-phase filter's output), one member's row broadcast over the batch (stride 0)."""
    if layout == "time-major":
        return w
    if layout == "member-major":
        return {k: np.ascontiguousarray(x) for k, x in w.items()}
    if layout == "reversed":
        out = {}
        for k, x in w.items():
            buf = np.zeros((x.shape[0], x.shape[1] + 7))
            buf[:, 3:-4] = x[:, ::-1]
            out[k] = buf[:, ::-1][:, 4:-3]
        return out
    return {k: np.broadcast_to(x[:1], x.shape) for k, x in w.items()}


@needs_numba
@pytest.mark.parametrize("layout", ["time-major", "member-major", "reversed", "broadcast"])
@pytest.mark.parametrize("name", sorted(ALL))
def test_compiled_loop_gives_the_numpy_loops_bits(name: str, layout: str, monkeypatch) -> None:
    model = ALL[name]
    truth = true_parameters(base_profile())
    b, n = 40, 1200
    rng = np.random.default_rng(3)
    scale = np.array([truth.get(k, -1e6) for k in model.params])  # N_p: -1e6 N m s
    theta = scale * (1 + 0.1 * rng.standard_normal((b, len(model.params))))
    w = _laid_out(_inputs(b, n, 5), layout)
    assert all(np.array_equal(x, y) for x, y in zip(w.values(), _inputs(b, n, 5).values())) or layout == "broadcast"
    r0 = 0.01 * rng.standard_normal(b)
    assert yawloop.usable(model, w, b, n)  # every term of the model is one the loop knows
    fast, _ = simulate_yaw(model, theta, w, r0, 0.1, sensitivities=False)
    monkeypatch.setattr(yawloop, "usable", lambda *a: False)
    monkeypatch.setattr(yawloop, "stepped", lambda *a: False)  # against the generic loop, not simulate_numpy
    slow, _ = simulate_yaw(model, theta, w, r0, 0.1, sensitivities=False)
    assert np.abs(slow).max() > 1e-3  # the ship turns: a loop that returned r0 would not pass
    assert np.array_equal(fast, slow)


@needs_numba
@pytest.mark.parametrize("dtype", [np.float32, np.int64, ">f8"])
def test_inputs_other_than_float64_give_the_numpy_loops_bits(dtype, monkeypatch) -> None:
    """The compiled loop has one float64 signature: float32 or integer inputs would be converted to
    doubles there while the numpy loop multiplies them in their own type (float32 products rounded to
    float32), so they run the numpy loop, whatever the work; a simulation's bits do not depend on
    whether numba is installed."""
    model = FULL_P
    truth = true_parameters(base_profile())
    b, n = 30, 1000
    theta = np.array([truth.get(k, -1e6) for k in model.params]) * np.ones((b, 1))
    w = {k: (np.rint(x) if dtype is np.int64 else x).astype(dtype) for k, x in _inputs(b, n, 5).items()}
    assert jitloop.use(b * n) and not yawloop.usable(model, w, b, n)
    chosen, _ = simulate_yaw(model, theta, w, np.zeros(b), 0.1, sensitivities=False)
    monkeypatch.setattr(yawloop, "usable", lambda *a: False)
    slow, _ = simulate_yaw(model, theta, w, np.zeros(b), 0.1, sensitivities=False)
    assert np.abs(slow).max() > 1e-3 and chosen.tobytes() == slow.tobytes()


def _plain(model, theta: np.ndarray, w: dict[str, np.ndarray], r0: np.ndarray, ts: float) -> np.ndarray:
    """(2.17)/(2.18) stepped by explicit Euler, written out term by term for one member at a time on Python
    floats: the reference the loops are checked against, sharing none of their code."""
    b, n = w["u"].shape
    out = np.empty((b, n))
    for i in range(b):
        th = dict.fromkeys(("M_v", "A", "N_rr", "N_rv", "N_phiur", "N_uv", "N_phiuu", "N_phiuv", "N_p"), 0.0)
        th |= dict(zip(model.params, theta[i].tolist()))  # a term the model lacks: zero
        x = {k: np.broadcast_to(v, (b, n))[i].tolist() for k, v in w.items()}
        r = float(r0[i])
        for k in range(n):
            out[i, k] = r
            u, v, phi = x["u"][k], x["v"][k], x["phi"][k] if "phi" in x else 0.0
            vd, p = x["v_dot"][k] if "v_dot" in x else 0.0, x["p"][k] if "p" in x else 0.0
            f = x["tau_r"][k] + th["A"] * u * r + th["N_rr"] * r * abs(r) + th["N_rv"] * r * abs(v) + th["N_uv"] * abs(u) * v
            f += -th["M_v"] * vd + th["N_phiur"] * phi * u * abs(r)
            f += th["N_phiuv"] * phi * abs(u * v) + th["N_phiuu"] * phi * u * abs(u) + th["N_p"] * p
            r = r + ts * f / th["I_r"]
    return out


@pytest.mark.parametrize("b", [3, 17, 40])  # Python floats member by member (yawloop.FLOATS), array steps by blocks
@pytest.mark.parametrize("layout", ["time-major", "member-major", "reversed", "broadcast"])
@pytest.mark.parametrize("name", sorted(ALL) + sorted(PARTIAL))
def test_stepped_numpy_loop_agrees_with_a_plain_reference(name: str, layout: str, b: int, monkeypatch) -> None:
    """yawloop.simulate_numpy (stop 51: the step's terms grouped as r a + |r| (b + g r) + c, by blocks of
    samples) against the plain reference and the generic loop of simulate_yaw, on random parameters and
    inputs in every memory layout the detector hands it: equal to rounding (another order of the same sum),
    within 1e-13 of the yaw rate's scale over 900 steps; a change of one term's parameter by 1e-9 shows."""
    model = {**ALL, **PARTIAL}[name]
    truth = true_parameters(base_profile())
    n = 900
    rng = np.random.default_rng(4 + b)
    scale = np.array([truth.get(k, -1e6) for k in model.params])
    theta = scale * (1 + 0.1 * rng.standard_normal((b, len(model.params))))
    w = _laid_out(_inputs(b, n, 6 + b), layout)
    r0 = 0.01 * rng.standard_normal(b)
    monkeypatch.setattr(yawloop, "usable", lambda *a: False)  # numba's loop out of the way
    monkeypatch.setattr(yawloop, "BLOCK", 40 * 64)  # several blocks of 64 steps at 40 members
    assert yawloop.stepped(model, w)
    fast, _ = simulate_yaw(model, theta, w, r0, 0.1, sensitivities=False)
    bumped = theta.copy()
    bumped[:, -1] *= 1 + 1e-9  # the model's last term (an input term): a test too loose to see it would pass anything
    moved, _ = simulate_yaw(model, bumped, w, r0, 0.1, sensitivities=False)
    plain = _plain(model, theta, w, r0, 0.1)
    monkeypatch.setattr(yawloop, "stepped", lambda *a: False)
    slow, _ = simulate_yaw(model, theta, w, r0, 0.1, sensitivities=False)
    assert np.abs(plain).max() > 1e-3 and np.isfinite(plain).all()  # the ship turns, nothing diverged
    tol = 1e-13 * np.abs(plain).max()
    assert fast.shape == plain.shape and np.abs(fast - plain).max() < tol and np.abs(slow - plain).max() < tol
    assert np.abs(moved - fast).max() > tol


def test_the_stepped_loops_floats_give_its_array_steps_bits(monkeypatch) -> None:
    """A small batch stepped member by member on Python floats (yawloop.FLOATS) gives the bits of the same
    members stepped in array operations in a larger batch: the same IEEE operations in the same order."""
    model, truth = FULL_P, true_parameters(base_profile())
    b, n = 30, 700
    rng = np.random.default_rng(8)
    theta = np.array([truth.get(k, -1e6) for k in model.params]) * (1 + 0.1 * rng.standard_normal((b, len(model.params))))
    w, r0 = _inputs(b, n, 9), 0.01 * rng.standard_normal(b)
    monkeypatch.setattr(yawloop, "usable", lambda *a: False)
    monkeypatch.setattr(yawloop, "BLOCK", 30 * 100)
    arrays, _ = simulate_yaw(model, theta, w, r0, 0.1, sensitivities=False)
    assert b > yawloop.FLOATS
    for i in (0, 1, 17):  # one member: Python floats
        one, _ = simulate_yaw(
            model, theta[i : i + 1], {k: x[i : i + 1] for k, x in w.items()}, r0[i : i + 1], 0.1, sensitivities=False
        )
        assert one.tobytes() == np.ascontiguousarray(arrays[i : i + 1]).tobytes()
    assert np.abs(arrays).max() > 1e-3


def test_the_stepped_loop_takes_only_float64_signals() -> None:
    """Without numba too: float32 or integer signals run the generic loop in their own arithmetic."""
    w = _inputs(3, 50, 1)
    assert yawloop.stepped(FULL_P, w)
    for dtype in (np.float32, np.int64):
        assert not yawloop.stepped(FULL_P, {**w, "u": w["u"].astype(dtype)})


def test_the_loop_knows_every_term_of_the_yaw_models() -> None:
    for model in ALL.values():
        assert set(model.input_terms) <= set(INPUT_CODES)
        assert set(model.state_terms) <= set(STATE_CODES)


@needs_numba
def test_compiled_cusum_path_agrees_with_numpys(monkeypatch) -> None:
    """detect's CUSUM recursion (identify.detect.cusum.cusum_path) compiled (the recursion step by step) and
    in numpy (its closed form by blocks, stop 51): the same statistic to rounding, a NaN carried on in both
    from the same sample (a diverged record must not look like a quiet one)."""
    from identify.detect import cusum

    inc = np.random.default_rng(1).standard_normal((600, 50, 3)) - 0.3
    inc[100, 7, 1] = np.nan
    fast = cusum.cusum_path(inc)
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    slow = cusum.cusum_path(inc)
    assert np.isnan(slow[100:, 7, 1]).all() and np.nanmax(fast) > 1.0
    assert (np.isnan(fast) == np.isnan(slow)).all()
    ok = ~np.isnan(fast)
    assert np.abs(fast[ok] - slow[ok]).max() <= 1e-12 * np.abs(fast[ok]).max()
