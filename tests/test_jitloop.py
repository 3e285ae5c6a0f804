"""The compiled time loop (primitives.jitloop) against the numpy loop it replaces, on the profiles
and environments the project simulates: the same bits where both use the same IEEE operations,
and within 1e-12 relative where numpy's own routines round differently (a rigid-body profile's
4x4 product by M^-1 in BLAS, pods' atan2 and hypot). The numpy loop runs whenever numba is
missing or SHIPTRIAL_KERNEL=numpy is set; these tests run it in the default suite."""

from __future__ import annotations

import importlib
import inspect
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from primitives import jitloop
from primitives.ship import load_profile
from primitives.simulate import Disturbances, VelocityStep, simulate
from primitives.terms import TermSet

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


@pytest.fixture(autouse=True)
def _compiled_for_every_size(monkeypatch):
    """The compiled loop for the small calls of these tests too (a process loads it from the
    first large call on, primitives.jitloop.use)."""
    monkeypatch.setattr(jitloop, "MIN_WORK", 0)


RIGID_RTOL = 1e-12  # the stated tolerance where the numpy loop's BLAS product or vectorised atan2/hypot round differently

WINDY = Disturbances(
    current_ne=(0.3, -0.2),
    current_sample_std=0.05,
    wind_ne=(3.0, 4.0),
    wind_sample_std=0.5,
    process_std=(1e-3, 1e-3, 1e-4),
    measurement_std=(0.01, 0.01, 0.001),
    heading_std=0.01,
    position_std=0.5,
)


def _inputs(profile, n: int) -> np.ndarray:
    """Slow sinusoids within each input's limits (a manoeuvre-like record)."""
    u = np.empty((n, len(profile.inputs)))
    for i, name in enumerate(profile.inputs):
        lo, hi = profile.input_limits.get(name, (-1.0, 1.0))
        u[:, i] = lo + (hi - lo) * (0.5 + 0.45 * np.sin(np.arange(n) / (37.0 + 11.0 * i)))
    return u


def _both(monkeypatch, profile, **kw):
    calls = []
    with monkeypatch.context() as m:  # the compiled loop must be the one that ran
        m.setattr(jitloop, "time_loop", lambda *a, f=jitloop.time_loop: calls.append(1) or f(*a))
        compiled = simulate(profile, **kw)
    assert calls == [1]
    with monkeypatch.context() as m:
        m.setattr(jitloop, "AVAILABLE", False)
        plain = simulate(profile, **kw)
    return compiled, plain


CASES = [  # (profile, disturbances, current_turning, per-member theta, positions)
    ("model-ship", None, False, False, True),
    ("model-ship", "profile", False, True, False),
    ("full-scale", WINDY, True, True, True),
    ("kvlcc2", WINDY, True, False, True),
    ("kvlcc2", None, False, False, False),
    ("naval-vessel", None, False, False, True),
    ("naval-vessel", WINDY, True, True, True),
]


@needs_numba
@pytest.mark.parametrize("name,dist,turning,per_member,positions", CASES)
def test_compiled_loop_matches_numpy_loop(monkeypatch, name, dist, turning, per_member, positions):
    prof = load_profile(name)
    batch = 1 if dist is None else 6
    theta = prof.params(None)
    if per_member:
        theta = theta * (1.0 + 0.01 * np.random.default_rng(2).standard_normal((batch, theta.size)))
    dist = Disturbances.from_profile(prof) if dist == "profile" else dist
    a, b = _both(
        monkeypatch,
        prof,
        inputs=_inputs(prof, 300),
        theta=theta,
        nu0=(prof.cruise_speed_mps, 0.0, 0.0),
        disturbances=dist,
        batch=batch,
        seed=5,
        current_turning=turning,
        positions=positions,
    )
    assert np.isfinite(b.nu).all()
    for field in ("nu", "eta", "y", "psi_meas", "pos_meas"):
        x, y = getattr(a, field), getattr(b, field)
        if prof.rigid_body is None:  # the same IEEE operations in the same order: the same bits
            assert np.array_equal(x, y, equal_nan=True), field
        else:
            np.testing.assert_allclose(x, y, rtol=RIGID_RTOL, atol=RIGID_RTOL * np.nanmax(np.abs(y)), err_msg=field)


@needs_numba
def test_open_loop_matches_stepping():
    """The diagnosis's open loop (caller-supplied signals, body-frame current and wind, input-only
    increments added first) gives the bits of VelocityStep called step by step."""
    rng = np.random.default_rng(0)
    terms = TermSet(
        [
            ["u_r", "v_r*r", "u_r*|u_r|", "tau_x", "wx"],
            ["v_r", "u_r*r", "tau_y", "psi", "u_q*|u_q|"],
            ["r", "u_r*v_r", "tau_n", "r*U^-1", "|v_r@-2.5|*r"],
        ]
    )
    batch, n = 5, 200
    step = VelocityStep(terms, rng.normal(0, 1e-3, (batch, terms.n_params)))
    exo = {k: rng.normal(0, 0.1, (n, batch)) for k in ("tau_x", "tau_y", "tau_n", "psi")}
    cur = (rng.normal(0.1, 0.01, (n, batch)), rng.normal(-0.1, 0.01, (n, batch)))
    wind = (rng.normal(2, 0.1, (n, batch)), rng.normal(1, 0.1, (n, batch)))
    forced = rng.normal(0, 1e-4, (n, batch, 3))
    nu0 = np.tile([1.0, 0.05, 0.01], (batch, 1))
    got = jitloop.open_loop(step, sorted(exo), exo, nu0, cur, wind, forced)
    nu, want = nu0, [nu0]
    for k in range(n):
        nu = step(nu, {m: exo[m][k] for m in exo}, (cur[0][k], cur[1][k]), (wind[0][k], wind[1][k]), forced[k])
        want.append(nu)
    assert np.array_equal(got, np.stack(want, axis=1))


def test_small_calls_do_not_load_the_compiler(monkeypatch):
    """A process that only steps single ships (plan-trial, the library build) keeps the numpy loop:
    loading numba would cost it more than it saves; a large call loads it for the rest."""
    monkeypatch.setattr(jitloop, "MIN_WORK", 20_000)
    monkeypatch.setattr(jitloop, "_LOADED", False)
    assert not jitloop.use(1000)
    assert jitloop.use(20_000) == jitloop.AVAILABLE
    monkeypatch.setattr(jitloop, "_LOADED", True)
    assert jitloop.use(1) == jitloop.AVAILABLE


def test_a_job_too_small_to_pay_for_the_load_keeps_the_numpy_loop(monkeypatch):
    """A job declared below JOB_MIN_WORK (detect on one recording) runs every call in numpy, a
    large call included; a large job loads the compiled code at its first call, a small one
    included, also when it is nested in a small job; outside a job, the call's own size decides as
    before; loaded code is used by all. (The load is replaced by a stand-in that only counts, so
    the decisions are tested with or without numba installed.)"""
    loads = []

    def fake_load():
        loads.append(jitloop._JOB.get())
        jitloop._LOADED = True

    monkeypatch.setattr(jitloop, "MIN_WORK", 20_000)
    monkeypatch.setattr(jitloop, "JOB_MIN_WORK", 1_000_000)
    monkeypatch.setattr(jitloop, "AVAILABLE", True)
    monkeypatch.setattr(jitloop, "_LOADED", False)
    monkeypatch.setattr(jitloop, "_load", fake_load)
    with jitloop.job(999_999):
        assert not jitloop.use(10**9) and loads == []
    assert jitloop._JOB.get() is None and not jitloop.use(19_999) and loads == []
    with jitloop.job(999_999):
        with jitloop.job(1_000_000):  # a job inside a job decides for its own block
            assert jitloop.use(1) and loads == [1_000_000]
        assert jitloop._JOB.get() == 999_999
        assert jitloop.use(1)  # loaded: used whatever the job
    assert loads == [1_000_000]
    with jitloop.job(0):
        assert jitloop.use(1)


def test_environment_selects_numpy_loop():
    """SHIPTRIAL_KERNEL=numpy (or no numba) runs the numpy loop, and a simulation still runs."""
    code = (
        "from primitives import jitloop; from primitives.ship import load_profile; from primitives.simulate import simulate; "
        "import numpy as np, sys; p = load_profile('model-ship'); r = simulate(p, np.ones((1000, len(p.inputs))), batch=25); "
        "print(jitloop.kernel_name(), bool(np.isfinite(r.nu).all()), 'numba' in sys.modules)"
    )
    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, SHIPTRIAL_KERNEL="numpy", PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["numpy", "True", "False"]  # a call past MIN_WORK, and numba never imported


@needs_numba
def test_sensitivity_recursion_compiled_matches_numpy(monkeypatch):
    """The output-error estimator's float32 recursion S(k+1) = (I + J(k)) S(k) + Phi(k): the
    compiled loop gives the numpy loop's bits, overflow (an unstable estimate) included."""
    from expdesign import sensloop

    rng = np.random.default_rng(4)
    n, b, p = 120, 7, 10
    sens = rng.normal(0, 1, (n + 1, b, 3, p)).astype(np.float32)
    sens[0] = 0.0
    jac = rng.normal(0, 0.3, (n, 3, b, 3)).astype(np.float32)
    jac[:, :, 3] *= 40.0  # one run's recursion blows up to inf / NaN
    a, c = sens.copy(), sens.copy()
    sensloop.recurse(a, jac)
    with monkeypatch.context() as m:
        m.setattr(jitloop, "AVAILABLE", False)
        sensloop.recurse(c, jac)
    assert not np.isfinite(c[:, 3]).all() and np.isfinite(c[:, 0]).all()
    assert np.array_equal(a, c, equal_nan=True)


def test_a_numba_that_cannot_load_falls_back_to_the_numpy_loop(tmp_path):
    """An installed numba that fails to import (built for another numpy, say) is said in one warning
    and the numpy loop runs: a large simulation still completes, no traceback."""
    stub = tmp_path / "numba"
    stub.mkdir()
    (stub / "__init__.py").write_text("raise ImportError('Numba needs NumPy 2.3 or less')\n")
    code = (
        "import warnings; warnings.simplefilter('always'); from primitives import jitloop; "
        "from primitives.ship import load_profile; from primitives.simulate import simulate; import numpy as np; "
        "p = load_profile('model-ship'); r = simulate(p, np.ones((1000, len(p.inputs))), batch=25); "
        "print(jitloop.AVAILABLE, bool(np.isfinite(r.nu).all()))"
    )
    root = Path(__file__).resolve().parent.parent
    env = {k: v for k, v in os.environ.items() if k != "SHIPTRIAL_KERNEL"}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), str(root)])
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "True"]
    assert "compiled simulation kernel unavailable" in out.stderr and "Traceback" not in out.stderr


@needs_numba
def test_a_changed_helper_file_recompiles_the_cached_functions_that_inline_it(tmp_path):
    """numba's disk cache checks a function's own file only; a helper inlined from another file
    (expdesign.oekernel's passes inline primitives.jitloop._increments) that changes must not leave
    the old machine code in use. Each call is a fresh process reading the cache the last one wrote."""
    helper, user = tmp_path / "helper_mod.py", tmp_path / "user_mod.py"
    helper.write_text("from primitives import jitloop\n\n\n@jitloop.inlined\ndef h(x):\n    return x + 1.0\n")
    user.write_text(
        "import helper_mod\nfrom primitives import jitloop\n\n\n@jitloop.compiled\ndef g(x):\n    return helper_mod.h(x)\n"
    )
    code = (
        f"from primitives import jitloop; jitloop.SHARED_HELPER_FILES = ({str(helper)!r},); import user_mod; "
        "jitloop.use(jitloop.MIN_WORK); print(user_mod.g(1.0), len(user_mod.g.jit.stats.cache_hits))"
    )
    root = Path(__file__).resolve().parent.parent
    env = {k: v for k, v in os.environ.items() if k not in ("SHIPTRIAL_KERNEL", "NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), str(root)])

    def run() -> list[str]:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root, timeout=120)
        assert out.returncode == 0, out.stderr
        return out.stdout.split()

    assert run() == ["2.0", "0"]  # compiled and written to the cache
    assert run() == ["2.0", "1"]  # loaded from it
    helper.write_text(helper.read_text().replace("x + 1.0", "x + 20.0"))
    assert run() == ["21.0", "0"]  # the helper's change seen: compiled again, not the cached 2.0


def _reference_open_loop(terms, coef, exo, nu0, forced):
    """open_loop in calm water (no current, no wind) in plain Python floats, member by member and
    term by term: each term ((c * f_1) * f_2) ..., a factor |s + station r|^power as
    primitives.powers.int_power forms it (products; the C library's pow for other powers), the
    terms of a DOF summed left to right, the input-only increment added first. (stop 44: integer
    powers as products)"""
    from primitives.powers import int_power
    from primitives.terms import parse_factor

    batch, n = nu0.shape[0], forced.shape[0]
    out = np.empty((batch, n + 1, 3))
    for b in range(batch):
        u, v, r = (float(x) for x in nu0[b])
        out[b, 0] = u, v, r
        for k in range(n):
            h = math.hypot(u, v)
            sig = {"u": u, "v": v, "r": r, "u_r": u, "v_r": v, "u_q": u, "v_q": v, "U": 1e-9 if h < 1e-9 else h}
            sig.update({name: float(x[k, b]) for name, x in exo.items()})
            nxt = []
            for i, dof in enumerate(terms.terms):
                acc = 0.0
                for j, term in enumerate(dof):
                    x_t = float(coef[b, terms.dof_slice(i)][j])
                    for f in (parse_factor(s) for s in term.split("*")):
                        x = sig[f.name] if f.station is None else sig[f.name] + f.station * r
                        x = abs(x) if f.modulus else x
                        x_t = x_t * int_power(x, f.power)
                    acc = x_t if j == 0 else acc + x_t
                nxt.append(acc)
            u, v, r = ((q + float(forced[k, b, i])) + nxt[i] for i, q in enumerate((u, v, r)))
            out[b, k + 1] = u, v, r
    return out


@needs_numba
def test_shared_factors_and_long_terms_give_the_term_by_term_bits():
    """The compiled loop evaluates each distinct factor once a step (jitfactors' factor table) and a
    term of up to three factors in one pass: the bits of forming every term factor by factor, on a
    program whose stations, moduli, squares, reciprocals and pow() powers repeat across terms and
    DOFs, with terms of one to five factors and a coefficient per member."""

    rng = np.random.default_rng(7)
    terms = TermSet(
        [
            ["u_r", "u_r*|u_r|", "v_r^3*U^-1", "|v_r@-2.5|*r*u_r*tau_x", "|v_r@-2.5|*r", "v_r^3*r*r*U^-1*tau_x"],
            ["v_r", "|v_r@-2.5|*r", "u_r*r", "v_r^3*U^-1", "U^-2*v_r", "|v_r@1.5|^2", "|v_r@1.5|*r"],
            ["r", "|v_r@-2.5|*r", "|v_r@-2.5|", "r^3", "U^-1*r", "u_r*v_r*r*tau_x*|u_r|"],
        ]
    )
    batch, n = 4, 60
    coef = rng.normal(0, 1e-3, (batch, terms.n_params))
    exo = {"tau_x": rng.normal(0, 0.1, (n, batch))}
    forced = rng.normal(0, 1e-4, (n, batch, 3))
    nu0 = np.column_stack([rng.normal(1.0, 0.1, batch), rng.normal(0.05, 0.02, batch), rng.normal(0.01, 0.005, batch)])
    got = jitloop.open_loop(VelocityStep(terms, coef), ["tau_x"], exo, nu0, None, None, forced)
    assert got is not None
    assert np.array_equal(got, _reference_open_loop(terms, coef, exo, nu0, forced))


@needs_numba
def test_factors_of_inputs_every_member_shares_give_the_term_by_term_bits():
    """Inputs the same for every member (one column): a factor of them alone (tau_x^3, |tau_y|^3,
    tau_x^2) is formed once a step and copied to the members, a factor with a station (it reads r)
    per member: the bits of forming every term factor by factor for each member."""
    rng = np.random.default_rng(11)
    terms = TermSet(
        [
            ["u_r", "tau_x^3*u_r", "|tau_x|*v_r^3*U^-1", "tau_x^2"],
            ["v_r", "tau_x^3*r", "|v_r@-2.5|*tau_x", "|tau_y|^3*v_r"],
            ["r", "tau_x^3", "|tau_x|*r", "tau_y^2"],
        ]
    )
    batch, n = 5, 60
    coef = rng.normal(0, 1e-3, (batch, terms.n_params))
    shared = {"tau_x": rng.normal(0, 0.3, (n, 1)), "tau_y": rng.uniform(2.0, 3.0, (n, 1))}
    forced = rng.normal(0, 1e-4, (n, batch, 3))
    nu0 = np.column_stack([rng.normal(1.0, 0.1, batch), rng.normal(0.05, 0.02, batch), rng.normal(0.01, 0.005, batch)])
    got = jitloop.open_loop(VelocityStep(terms, coef), ["tau_x", "tau_y"], shared, nu0, None, None, forced)
    assert got is not None
    each = {k: np.repeat(v, batch, axis=1) for k, v in shared.items()}
    assert np.array_equal(got, _reference_open_loop(terms, coef, each, nu0, forced))
    assert np.array_equal(got, jitloop.open_loop(VelocityStep(terms, coef), ["tau_x", "tau_y"], each, nu0, None, None, forced))


def _inlined_files_called(fn, helpers: dict, seen: set) -> set[str]:
    """The files of the :func:`jitloop.inlined` helpers ``fn`` calls (by name or as a module's
    attribute), and of the helpers they call in turn."""
    py = getattr(fn, "py_func", fn)
    names, files = py.__code__.co_names, set()
    for name in names:
        obj = py.__globals__.get(name)
        for cand in [obj] + ([getattr(obj, a, None) for a in names] if inspect.ismodule(obj) else []):
            if id(cand) in helpers and id(cand) not in seen:
                seen.add(id(cand))
                files.add(os.path.realpath(helpers[id(cand)]))
                files |= _inlined_files_called(cand, helpers, seen)
    return files


def test_every_helper_file_compiled_into_another_files_function_is_in_the_cache_stamp():
    """numba's disk cache checks a compiled function's own file only, so every file whose inlined
    helpers (or the constant N_STATE) another file's compiled function reads must be in
    SHARED_HELPER_FILES, or editing it leaves stale machine code in a warm process (the time loop
    inlines jitfactors' helpers and reads jitprogram's N_STATE since the loop left jitloop.py)."""
    import primitives.jitprogram

    for mod in ("expdesign.ivsolve", "expdesign.oekernel", "expdesign.robust", "expdesign.sensloop", "identify.steering.kalman"):
        importlib.import_module(mod)  # their compiled functions register in jitloop._COMPILED
    for mod in ("primitives.jitsens", "primitives.jittime", "primitives.regkernel"):
        importlib.import_module(mod)

    stamped = {os.path.realpath(f) for f in jitloop.SHARED_HELPER_FILES}
    helpers = {id(g[n]): g["__file__"] for g, n in jitloop._INLINED}
    for c in jitloop._COMPILED:
        own = os.path.realpath(c.fn.__globals__["__file__"])
        foreign = _inlined_files_called(c.fn, helpers, set()) - {own}
        assert foreign <= stamped, f"{c.__name__} inlines helpers of {sorted(foreign - stamped)}, not stamped"
    assert os.path.realpath(primitives.jitprogram.__file__) in stamped  # N_STATE, frozen into the loops
